"""What every benchmark shares: machine facts, a load note, the peak memory of this process, the
best of repeated timings."""

from __future__ import annotations

import datetime as dt
import os
import platform
import sys
import time
from pathlib import Path

QUIET_CPU_PERCENT = 20.0  # CPU use (all cores) under which the machine counts as quiet

# Measure as a user's Python runs: it writes the bytecode caches of the (editable) toolbox once and
# reads them afterwards. The engineers' shells set PYTHONDONTWRITEBYTECODE, which made every
# whole-process run of a fresh checkout compile the toolbox's modules from source (0.1-0.45 CPU s)
# while the peers' pip installs had their bytecode. Every benchmark imports this module first, so
# its own imports and every process it starts write and read bytecode.
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
sys.dont_write_bytecode = False


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine()


def machine_facts(*versions: str) -> str:
    """``date, N cores (CPU), Python x, numpy y`` plus the given ``"name version"`` strings."""
    import numpy as np

    parts = [f"{dt.date.today().isoformat()}, {os.cpu_count()} cores ({cpu_model()}), Python "
             f"{platform.python_version()}, numpy {np.__version__}", *versions]
    return ", ".join(parts)


def load_note() -> str:
    """How busy the CPUs were in the second before the benchmark (other processes' work makes
    timings noisy; the load average would still count the previous benchmark)."""
    from toolbox.extras import require

    psutil = require("psutil", "bench", "the benchmarks")
    busy = psutil.cpu_percent(interval=1.0)
    state = "quiet machine" if busy < QUIET_CPU_PERCENT else \
        "the machine was busy with other work: timings are noisy"
    return f"CPU {busy:.0f}% busy in the second before the start: {state}"


def peak_rss_mb() -> float:
    """Peak resident memory of this process (``VmHWM``), MB.

    Not ``ru_maxrss``: Linux carries the parent's high-water mark across fork/exec into it, so a
    child started by a big parent would report the parent's peak.
    """
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM"):
            return int(line.split()[1]) / 1024.0
    import resource  # pragma: no cover - not Linux

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_measured(cmd: list[str], poll: float = 0.02, timeout: float | None = None
                 ) -> tuple[float, float, int, str]:
    """Run a command; return (seconds, peak resident MB, exit code, stderr).

    The peak is the child's own ``VmHWM``, read while it runs (it only grows, so the last
    reading before exit is the peak up to the polling interval). With ``timeout`` the child is
    killed after that many seconds (exit code -9, stderr says so). Its stderr goes to a
    temporary file, not a pipe, so a talkative long run cannot block on a full pipe.
    """
    import subprocess
    import tempfile
    import time

    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as log:
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=log)
        status = Path(f"/proc/{proc.pid}/status")
        peak_kb = 0
        while proc.poll() is None:
            try:
                for line in status.read_text().splitlines():
                    if line.startswith("VmHWM"):
                        peak_kb = max(peak_kb, int(line.split()[1]))
            except (OSError, ValueError):
                pass
            if timeout is not None and time.perf_counter() - t0 > timeout:
                proc.kill()
                proc.wait()
                return time.perf_counter() - t0, peak_kb / 1024.0, -9, \
                    f"killed after {timeout:.0f} s (deadline)"
            time.sleep(poll)
        seconds = time.perf_counter() - t0
        log.seek(0)
        stderr = log.read().decode(errors="replace")
    return seconds, peak_kb / 1024.0, proc.returncode, stderr


def best_of(func, repeat: int) -> float:
    """Best wall time of ``repeat`` calls of ``func``, seconds, after one warm-up call
    (compilation, caches)."""
    func()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        func()
        times.append(time.perf_counter() - t0)
    return min(times)


def write_results(path, lines: list[str]) -> str:
    """Join ``lines``, write them to ``path`` (its folder made), print and return the text."""
    text = "\n".join(lines)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    print(text)
    return text


def generated_markers(tag: str, name: str) -> tuple[str, str]:
    """The two lines (HTML comments: a Markdown viewer shows neither) around the part ``name``
    a benchmark ``tag`` generates in its results file (:func:`rewrite_generated`)."""
    return (f"<!-- {tag}: {name} (generated: each run rewrites it down to the end marker) -->",
            f"<!-- /{tag}: {name} (end; notes below are kept) -->")


def rewrite_generated(old: str, tag: str, parts: dict[str, list[str]]) -> str:
    """The results file ``old`` with each generated part (``{name: lines}``) put between its
    markers (:func:`generated_markers`), replacing what was there; the text outside the markers
    (notes written after a sitting, under a table) is kept as it is. A part whose markers
    ``old`` lacks is appended at the end (a file of an older layout keeps all its text: its old
    tables go by hand); markers out of order are a ValueError, the file left to be mended."""
    text = old
    for name, lines in parts.items():
        start, end = generated_markers(tag, name)
        while lines and not lines[0].strip():
            lines = lines[1:]
        while lines and not lines[-1].strip():
            lines = lines[:-1]
        block = "\n".join([start, "", *lines, "", end])
        i, j = text.find(start), text.find(end)
        if (i < 0) != (j < 0) or j < i or text.count(start) > 1 or text.count(end) > 1:
            raise ValueError(f"the results file's markers of {name!r} are broken: expected "
                             f"one {start!r} then one {end!r}; mend it by hand")
        if i < 0:
            text = text.rstrip("\n") + "\n\n" + block + "\n"
        else:
            text = text[:i] + block + text[j + len(end):]
    return text


def case_arguments(description: str, extra=None):
    """The arguments of a bench that runs its cases in child processes: --case, --work,
    --points (1,000,000) and --small; ``extra(parser)`` adds its own."""
    import argparse
    from pathlib import Path

    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--case")
    parser.add_argument("--work", type=Path)
    parser.add_argument("--points", type=int, default=1_000_000)
    parser.add_argument("--small", action="store_true")
    if extra is not None:
        extra(parser)
    return parser.parse_args()


def measure_case(script: str, name: str, work, n_points: int, cwd, width: int = 26) -> dict:
    """Run ``script --case name`` in a fresh process (see :func:`case_arguments`); its last
    stdout line is the JSON result (with seconds and peak_mb), printed as one row."""
    import json
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, script, "--case", name, "--work", str(work),
                           "--points", str(n_points)], capture_output=True, text=True, cwd=cwd)
    if proc.returncode != 0:
        raise RuntimeError(f"case {name} failed:\n{proc.stderr[-3000:]}")
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    print(f"  {name:<{width}} {result['seconds']:8.2f} s  {result['peak_mb']:8.0f} MB", flush=True)
    return result
