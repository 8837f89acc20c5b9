"""Timed windows and the record of one measured configuration."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from smac_hard_gym.bench.machine import machine_info


def timed_repeats(step: Callable[[], int], seconds: float, repeats: int) -> list[float]:
    """Env-steps/s of ``repeats`` windows; each calls ``step()`` (which returns the env steps it made) until
    ``seconds`` have passed, at least once."""
    runs = []
    for _ in range(repeats):
        count, t0 = 0, time.perf_counter()
        while True:
            count += step()
            elapsed = time.perf_counter() - t0
            if elapsed >= seconds:
                break
        runs.append(count / elapsed)
    return runs


@dataclass
class Measurement:
    """One configuration's throughput (median env-steps/s over ``runs``) and what else was measured with it."""

    section: str  # native | engine | subproc | starcraft2 | opponents | smax
    map: str
    num_envs: int  # battles stepped together (workers x battles per worker for subproc)
    steps_per_second: float
    runs: list[float] = field(default_factory=list)
    opponent: str = ""
    workers: int = 0  # subproc only
    mode: str = ""  # smax: "scan" (batched, jit + scan) or "loop" (Python loop over single steps)
    setup_seconds: float = 0.0  # build + reset + two warm-up steps (memory tracing on when it was measured)
    episodes_per_second: float = 0.0
    peak_bytes_per_env: float | None = None  # tracemalloc peak over build, reset and the warm-up steps, / battles
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def spread(self) -> tuple[float, float]:
        return (min(self.runs), max(self.runs)) if self.runs else (self.steps_per_second, self.steps_per_second)


def write_json(path: str | os.PathLike, kind: str, results: list) -> None:
    """A results document ``{benchmark, machine, results}``; ``results`` are dataclasses."""
    doc = {"benchmark": kind, "machine": machine_info(), "results": [asdict(r) for r in results]}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(doc, indent=1))
