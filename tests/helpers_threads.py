"""Run test callables on threads at once."""

from __future__ import annotations

import threading
from collections.abc import Callable


def run_in_threads(*targets: Callable[[], object]) -> None:
    """Start one thread per callable of ``targets``, wait for all, and raise the first
    exception a thread raised (a plain ``threading.Thread`` only prints it, and the test
    passed on whatever the thread left)."""
    errors: list[BaseException] = []

    def guarded(target: Callable[[], object]) -> None:
        try:
            target()
        except BaseException as exc:  # noqa: BLE001 - re-raised on the test's thread
            errors.append(exc)

    threads = [threading.Thread(target=guarded, args=(target,)) for target in targets]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    if errors:
        raise errors[0]
