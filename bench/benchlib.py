"""What every benchmark shares: machine facts, a load note, the peak memory of this process."""

from __future__ import annotations

import datetime as dt
import os
import platform
from pathlib import Path

QUIET_LOAD = 1.2  # 1-minute load average under which the machine counts as quiet (2 cores)


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


def load_note(load: tuple[float, float, float] | None = None) -> str:
    """The load average at the start and whether timings are to be trusted."""
    one, five, _ = load or os.getloadavg()
    state = ("quiet machine" if one < QUIET_LOAD else
             "the machine was busy with other work: timings are noisy")
    return f"load average at start {one:.1f} (1 min), {five:.1f} (5 min): {state}"


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


def run_measured(cmd: list[str], poll: float = 0.02) -> tuple[float, float, int, str]:
    """Run a command; return (seconds, peak resident MB, exit code, stderr).

    The peak is the child's own ``VmHWM``, read while it runs (it only grows, so the last
    reading before exit is the peak up to the polling interval).
    """
    import subprocess
    import time

    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    status = Path(f"/proc/{proc.pid}/status")
    peak_kb = 0
    while proc.poll() is None:
        try:
            for line in status.read_text().splitlines():
                if line.startswith("VmHWM"):
                    peak_kb = max(peak_kb, int(line.split()[1]))
        except (OSError, ValueError):
            pass
        time.sleep(poll)
    seconds = time.perf_counter() - t0
    stderr = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    return seconds, peak_kb / 1024.0, proc.returncode, stderr
