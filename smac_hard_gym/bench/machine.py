"""The machine a figure was measured on, and how busy it was: hardware and versions, the code's identity, a CPU
probe, a meter of the cores in use, and /proc readers for child processes."""

from __future__ import annotations

import os
import platform
import subprocess
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

REPO_ROOT = Path(__file__).resolve().parents[2]


def machine_info() -> dict[str, Any]:
    """What the figures were measured on: CPU, cores, threads, versions and date."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import gymnasium
    import numba

    try:
        from importlib.metadata import version

        ours = version("smac-hard-gym")
    except Exception:  # not installed, only on the path
        ours = "unknown"
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "memory_gib": _memory_gib(),
        "numba_threads": numba.get_num_threads(),
        "numba_threading_layer": _threading_layer(),
        "python": platform.python_version(),
        "smac_hard_gym": ours,
        "numpy": np.__version__,
        "numba": numba.__version__,
        "gymnasium": gymnasium.__version__,
        "platform": platform.platform(),
        "load_average": list(os.getloadavg()) if hasattr(os, "getloadavg") else None,
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
    }


def source_version() -> dict[str, Any]:
    """The code measured: the git commit (when run from a checkout), whether tracked files differ from it, and a
    digest of every source file of the simulator and env layers (so a run can tell if they changed under it)."""
    import hashlib

    digest, files = hashlib.sha1(), {}
    for folder in ("smac_hard_gym", "maps", "opponents"):
        for path in sorted((REPO_ROOT / folder).rglob("*.py")):
            if not _is_benchmark_code(path):
                data = path.read_bytes()
                digest.update(data)
                files[str(path.relative_to(REPO_ROOT))] = hashlib.sha1(data).hexdigest()[:12]
    out: dict[str, Any] = {"source_digest": digest.hexdigest()[:12], "files": files}
    try:
        def git(*args: str) -> str:
            return subprocess.run(["git", "-C", str(REPO_ROOT), *args], capture_output=True, text=True,
                                  timeout=10, check=True).stdout

        out["git_commit"] = git("rev-parse", "--short", "HEAD").strip()
        status = git("status", "--porcelain", "--untracked-files=no").splitlines()
        out["git_modified"] = [line[3:] for line in status if line.strip()]
    except (OSError, subprocess.SubprocessError):
        pass
    return out


def _is_benchmark_code(path: Path) -> bool:
    """The CLI commands and this package: they measure the simulator, so they stay out of its digest."""
    parts = path.relative_to(REPO_ROOT).parts
    return "commands" in parts or parts[:2] == ("smac_hard_gym", "bench")


def _memory_gib() -> float | None:
    try:
        return round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30, 1)
    except (ValueError, OSError, AttributeError):
        return None


def _threading_layer() -> str:
    import numba

    try:
        return numba.threading_layer()
    except ValueError:  # no parallel kernel has run yet in this process
        return "not yet chosen"


def cpu_probe() -> float:
    """Seconds for a fixed single-thread workload (a Python loop and a numpy reduction). On a quiet machine it is
    steady; larger values mean other processes were taking the cores while the next figures were measured."""
    t = time.perf_counter()
    total = 0
    for i in range(300_000):
        total += i * i
    a = np.arange(1_000_000, dtype=np.float64)
    for _ in range(20):
        total += float(np.sqrt(a).sum())
    return time.perf_counter() - t


def _system_cpu_seconds() -> tuple[float, float]:
    """(busy, stolen) CPU seconds of the whole machine since boot, from /proc/stat; (0, 0) where it is missing."""
    try:
        with open("/proc/stat") as f:
            fields = [int(v) for v in f.readline().split()[1:]]
    except (OSError, ValueError):
        return 0.0, 0.0
    tick = os.sysconf("SC_CLK_TCK")
    user, nice, system, _idle, _iowait, irq, softirq, steal = (fields + [0] * 8)[:8]
    return (user + nice + system + irq + softirq) / tick, steal / tick


def _process_cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of another live process (all its threads); 0 when it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class CpuMeter:
    """Cores in use over a timed window: on the whole machine (``busy``), by this benchmark (``ours``: this process
    and the ``pids`` it watches), by everything else (``others`` = busy - ours), and stolen by the hypervisor.

    ``others`` is the load that competed with a figure while it was measured: on 2 cores, 1.0 means another process
    held a whole core."""

    def __init__(self, pids: Sequence[int] = ()) -> None:
        self.pids = list(pids)
        self.result: dict[str, float] = {}

    def _read(self) -> tuple[float, float, float, float]:
        busy, steal = _system_cpu_seconds()
        ours = time.process_time() + sum(_process_cpu_seconds(p) for p in self.pids)
        return time.perf_counter(), busy, steal, ours

    def __enter__(self) -> CpuMeter:
        self._start = self._read()
        return self

    def __exit__(self, *exc: Any) -> None:
        t1, busy1, steal1, ours1 = self._read()
        t0, busy0, steal0, ours0 = self._start
        wall = max(t1 - t0, 1e-9)
        busy, ours = (busy1 - busy0) / wall, (ours1 - ours0) / wall
        steal = (steal1 - steal0) / wall
        self.result = {"busy_cores": round(busy, 2), "our_cores": round(ours, 2),
                       "other_cores": round(max(0.0, busy - ours), 2), "stolen_cores": round(steal, 2)}


def peak_rss_of(pid: int) -> int | None:
    """Peak resident set (VmHWM) of a process, bytes; None where /proc is missing."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        return None
    return None
