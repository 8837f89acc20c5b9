"""Throughput benchmarks. Each prints env-steps/s with the machine and batch size named and can write JSON.

An env step is one SMAC step (``step_mul`` = 8 game loops) of one battle; a batch of B battles stepped once counts
B env steps. Compile time is measured and reported apart from the timed runs; figures are medians over repeats.
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np


def machine_info() -> dict:
    """What the figures were measured on."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import numba

    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "numba_threads": numba.get_num_threads(),
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
        "date": time.strftime("%Y-%m-%d %H:%M:%S"),
    }


@dataclass
class EngineBenchResult:
    map: str
    batch: int
    steps_per_second: float  # median over repeats
    runs: list[float] = field(default_factory=list)
    startup_seconds: float = 0.0  # engine construction + first (compiling or cache-loading) step
    resets_per_second: float = 0.0
    bytes_per_battle: float = 0.0


def _random_command_pool(engine, rng: np.random.Generator, size: int):
    """A pool of random command sets (move to a nearby point, or attack a random unit) to cycle through."""
    from smac_hard_gym.engine.state import CMD_ATTACK, CMD_MOVE, Commands

    b, u = engine.batch_size, engine.n_units
    pool = []
    for _ in range(size):
        c = Commands.empty(b, u)
        attack = rng.random((b, u)) < 0.5
        c.kind[:] = np.where(attack, CMD_ATTACK, CMD_MOVE)
        c.target[:] = rng.integers(0, u, size=(b, u))
        c.x[:] = engine.layout.x + rng.uniform(-6, 6, size=(b, u))
        c.y[:] = engine.layout.y + rng.uniform(-6, 6, size=(b, u))
        pool.append(c)
    return pool


def bench_engine(map_name: str, batch: int, steps: int = 200, repeats: int = 3, seed: int = 0) -> EngineBenchResult:
    """Engine alone: random commands every step, battles reset when one side is dead or the limit is reached."""
    from smac_hard_gym.engine import BattleEngine
    from smac_hard_gym.engine.state import state_nbytes

    t0 = time.perf_counter()
    engine = BattleEngine(map_name, batch_size=batch)
    engine.step()
    startup = time.perf_counter() - t0
    engine.reset()
    rng = np.random.default_rng(seed)
    pool = _random_command_pool(engine, rng, 16)
    limit = engine.spec.episode_limit * engine.step_mul
    runs, resets = [], []
    for _ in range(repeats):
        n_resets = 0
        t = time.perf_counter()
        for k in range(steps):
            engine.step(pool[k % len(pool)])
            red, blue = engine.alive_counts()
            done = (red == 0) | (blue == 0) | (engine.state.loop >= limit)
            if done.any():
                n_resets += int(done.sum())
                engine.reset(done)
        dt = time.perf_counter() - t
        runs.append(steps * batch / dt)
        resets.append(n_resets / dt)
    return EngineBenchResult(
        map=map_name, batch=batch, steps_per_second=float(np.median(runs)), runs=[float(r) for r in runs],
        startup_seconds=startup, resets_per_second=float(np.median(resets)),
        bytes_per_battle=state_nbytes(engine.state) / batch,
    )


def write_json(path: str | os.PathLike, kind: str, results: list) -> None:
    doc = {"benchmark": kind, "machine": machine_info(), "results": [asdict(r) for r in results]}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(doc, indent=1))
