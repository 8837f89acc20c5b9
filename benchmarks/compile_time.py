"""Where a first run's numba compile time goes: each scenario runs in a fresh interpreter on its own empty
``NUMBA_CACHE_DIR``, with a listener on numba's ``numba:compile`` event that times every dispatcher's compilation in
CPU seconds (``time.process_time``, the whole process: numba compiles on the calling thread) and wall seconds,
exclusive of the kernels it compiled on the way (a driver's compile triggers its callees').

Scenarios (``--scenarios``, comma-separated; default all):

- ``train``: ``smac-hard-gym train --map 3m`` (64 envs, its 16-env evaluation; one rollout) on an empty cache;
- ``second-map``: ``train --map 8m`` on the cache ``train`` left (what a first run on another map adds);
- ``warm``: ``train --map 3m`` again on that cache (a second process: should compile nothing);
- ``bench-engine``: ``smac-hard-gym bench engine --map 3m --batch 1024`` (a few steps) on an empty cache.

Prints a table (kernel, compile CPU s, wall s) per scenario with its totals, and writes them as JSON (``--json``).

    python benchmarks/compile_time.py --json compile_time.json
    python benchmarks/compile_time.py --scenarios bench-engine --batch 4096
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# Runs inside the measured interpreter: a CPU-timing listener on numba's compile event, then the command, then one
# JSON line with the compiled kernels and the process's totals.
_CHILD = r"""
import json, os, sys, time
_t0_wall, _t0_cpu = time.perf_counter(), time.process_time()
from numba.core import event

class _Timer(event.Listener):
    def __init__(self):
        self.stack, self.rows = [], []
    def on_start(self, ev):
        now = (time.process_time(), time.perf_counter())
        self.stack.append([ev.data["dispatcher"], ev.data.get("args"), *now, 0.0, 0.0])
    def on_end(self, ev):
        disp, args, cpu0, wall0, child_cpu, child_wall = self.stack.pop()
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        if self.stack:
            self.stack[-1][4] += cpu
            self.stack[-1][5] += wall
        func = disp.py_func
        name = f"{func.__module__}.{func.__qualname__}".replace(".<locals>", "")
        closure = func.__closure__
        if closure:
            name += "[" + ",".join(repr(c.cell_contents) for c in closure if isinstance(c.cell_contents, (int, float)))
            name += "]"
        self.rows.append({"kernel": name, "cpu_s": cpu - child_cpu, "wall_s": wall - child_wall,
                          "args": str(args)[:300]})

_timer = _Timer()
event.register("numba:compile", _timer)
from smac_hard_gym.cli import main
from smac_hard_gym.engine import BattleEngine

# When the first engine step has run (train: its first rollout step, where the progress bar starts moving).
_first_step = {}
_engine_step = BattleEngine.step

def _timed_step(self, *args, **kwargs):
    _engine_step(self, *args, **kwargs)
    if not _first_step:
        _first_step.update(cpu_s=time.process_time() - _t0_cpu, wall_s=time.perf_counter() - _t0_wall)

BattleEngine.step = _timed_step
os.chdir(sys.argv[1])
code = main(sys.argv[2:])
print("\n" + json.dumps({"rc": code, "kernels": _timer.rows, "first_step": _first_step,
                         "process_cpu_s": time.process_time() - _t0_cpu,
                         "process_wall_s": time.perf_counter() - _t0_wall}))
"""


def _train_argv(map_name: str, num_envs: int) -> list[str]:
    # One rollout (64 x 32 = 2048 steps) and its evaluation: every kernel a long run calls, little training.
    return ["train", "--map", map_name, "--timesteps", str(num_envs * 32), "--num-envs", str(num_envs),
            "--eval-episodes", "16", "--no-progress", "--out", "run-" + map_name]


def _run(argv: list[str], cache: Path, work: Path) -> dict:
    work.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    cmd = [sys.executable, "-c", _CHILD, str(work), *argv]
    t0 = time.perf_counter()
    usage0 = os.times()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    usage1 = os.times()
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}):\n{proc.stderr[-4000:]}")
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    result["argv"] = argv
    result["child_cpu_s"] = (usage1.children_user - usage0.children_user) + (usage1.children_system
                                                                               - usage0.children_system)
    result["child_wall_s"] = time.perf_counter() - t0
    result["compile_cpu_s"] = sum(row["cpu_s"] for row in result["kernels"])
    result["compile_wall_s"] = sum(row["wall_s"] for row in result["kernels"])
    result["load_average"] = os.getloadavg()
    return result


def _table(name: str, result: dict) -> str:
    lines = [f"== {name}: {' '.join(result['argv'])}",
             f"{'kernel':<72} {'CPU s':>7} {'wall s':>7}"]
    for row in sorted(result["kernels"], key=lambda r: -r["cpu_s"]):
        lines.append(f"{row['kernel'][:72]:<72} {row['cpu_s']:7.1f} {row['wall_s']:7.1f}")
    lines.append(f"{'total compile':<72} {result['compile_cpu_s']:7.1f} {result['compile_wall_s']:7.1f}")
    lines.append(f"{'whole process (CPU incl. all threads / wall)':<72} {result['child_cpu_s']:7.1f} "
                 f"{result['child_wall_s']:7.1f}")
    first = result.get("first_step") or {}
    if first:
        lines.append(f"{'first engine step done at (process CPU / wall since start)':<72} {first['cpu_s']:7.1f} "
                     f"{first['wall_s']:7.1f}")
    lines.append(f"load average after: {' '.join(f'{v:.2f}' for v in result['load_average'])}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenarios", default="train,second-map,warm,bench-engine")
    parser.add_argument("--map", default="3m")
    parser.add_argument("--second-map", default="8m")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--batch", type=int, default=1024, help="bench-engine's batch (default 1024)")
    parser.add_argument("--json", default=None, metavar="PATH", help="write the results as JSON")
    args = parser.parse_args(argv)
    scenarios = args.scenarios.split(",")
    unknown = set(scenarios) - {"train", "second-map", "warm", "bench-engine"}
    if unknown:
        parser.error(f"unknown scenarios {sorted(unknown)}")
    results: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="compile-time-") as tmp:
        root = Path(tmp)
        train_cache = root / "cache-train"
        if {"train", "second-map", "warm"} & set(scenarios):
            # second-map and warm need the cache train leaves behind, so train runs first whenever they are asked.
            results["train"] = _run(_train_argv(args.map, args.num_envs), train_cache, root / "work")
            if "train" in scenarios:
                print(_table("train", results["train"]), flush=True)
            else:
                del results["train"]
        if "second-map" in scenarios:
            results["second-map"] = _run(_train_argv(args.second_map, args.num_envs), train_cache, root / "work")
            print(_table("second-map", results["second-map"]), flush=True)
        if "warm" in scenarios:
            results["warm"] = _run(_train_argv(args.map, args.num_envs), train_cache, root / "work")
            print(_table("warm", results["warm"]), flush=True)
        if "bench-engine" in scenarios:
            results["bench-engine"] = _run(["bench", "engine", "--map", args.map, "--batch", str(args.batch),
                                            "--steps", "5", "--repeats", "1"], root / "cache-bench", root / "work")
            print(_table("bench-engine", results["bench-engine"]), flush=True)
    if args.json:
        path = Path(args.json)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, temp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
        try:
            with os.fdopen(fd, "w") as handle:
                json.dump({"scenarios": results, "cores": os.cpu_count(), "python": sys.version.split()[0]},
                          handle, indent=2)
            os.replace(temp, path)
        except BaseException:
            os.unlink(temp)
            raise
    return 0


if __name__ == "__main__":
    sys.exit(main())
