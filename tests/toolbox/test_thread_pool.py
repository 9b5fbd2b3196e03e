"""The local executor's thread pools (:func:`toolbox.executor.thread_pool`): reused across calls
(a thread's first GDAL open pays for its PROJ context, about 10 ms with the GIL held), another
pool for a nested call, and every task finished when a call returns."""

from __future__ import annotations

import threading
import time

from toolbox.executor import Executor, map_tiles

TWO = Executor("local", 2)


_SEEN = threading.local()  # what a thread keeps between tasks (as GDAL's per-thread state)


def _thread_id(_: int) -> int:
    time.sleep(0.01)  # both threads take tasks
    return threading.get_ident()


def _seen_before(_: int) -> bool:
    time.sleep(0.01)
    seen = getattr(_SEEN, "seen", False)
    _SEEN.seen = True
    return seen


def test_threads_are_reused_by_the_next_call():
    list(map_tiles(_seen_before, range(8), executor=TWO))
    assert all(map_tiles(_seen_before, range(8), executor=TWO))  # new threads for every call before


def _inner_sum(n: int) -> tuple[int, int]:
    inner = list(map_tiles(_thread_id, range(n), executor=TWO))
    return sum(range(n)), threading.get_ident() in inner


def test_a_nested_call_takes_another_pool():
    results = list(map_tiles(_inner_sum, [3, 4, 5, 6], executor=TWO))
    assert [total for total, _ in results] == [3, 6, 10, 15]
    assert not any(own_thread for _, own_thread in results)  # never its caller's thread


def test_every_task_has_finished_when_the_consumer_stops_early():
    finished: list[int] = []

    def slow(i: int) -> int:
        time.sleep(0.05)
        finished.append(i)
        return i

    results = map_tiles(slow, range(20), executor=TWO, prefetch=4)
    assert next(results) == 0
    results.close()  # the consumer stops: pending tasks cancelled, running ones awaited
    done = len(finished)
    time.sleep(0.2)
    assert len(finished) == done < 20  # nothing ran after the call returned


def test_a_thread_reused_after_close_opens_its_raster_again(tmp_path):
    """ThreadDatasets keeps a dataset per thread; a pool thread reused by a later call after
    ``close()`` must not be handed the closed dataset."""
    import numpy as np
    from affine import Affine

    from toolbox.raster.datasets import ThreadDatasets
    from toolbox.raster.writer import write_raster

    path = write_raster(tmp_path / "a.tif", np.arange(16, dtype="float32").reshape(4, 4),
                        Affine(1, 0, 0, 0, -1, 4), None)
    datasets = ThreadDatasets()

    def read(_: int) -> float:
        time.sleep(0.01)
        return float(datasets.get(path).read(1).sum())

    assert list(map_tiles(read, range(4), executor=TWO)) == [120.0] * 4
    datasets.close()
    assert list(map_tiles(read, range(4), executor=TWO)) == [120.0] * 4
