"""Speed of two versions of smac-hard-gym, interleaved on the same machine: is a change within N% of before?

Each version (a git revision, or ``WORKTREE`` for the working tree as it is) is installed, not editable, into its
own folder (``pip install --no-deps --target``) and imported from there through ``PYTHONPATH``, with its own numba
cache, so the two never share code or compiled kernels; a folder that already holds such an install can be given
instead of a revision (on a machine without the repository's history). Then ``--rounds`` rounds run each version
once per measurement, alternating which goes first, in fresh processes:

- ``gym``: ``gymnasium.make("SMACHard-<map>-v0", opponent="base")``, one battle: ``action_masks()`` and ``step`` with
  random legal actions, resets included (the loop MaskablePPO runs around the env);
- ``vector<N>``: ``NativeVectorEnv(<map>, num_envs=N, opponent="base")``: ``action_masks()`` and ``step``;
- ``engine<N>``: ``BattleEngine(<map>, N)`` alone, its own command buffer filled with random move and attack orders.

A measurement times ``--windows`` windows of ``--steps`` steps after a warm-up and reports the best window (noise
on a shared machine only adds time, so the best is the most stable figure) and the median; the summary gives, per
measurement, the median over rounds of each version's best and the ratio after/before. Steps/s count battle-steps
(N battles stepped once = N).

    python benchmarks/ab_speed.py --before 0810aea --after WORKTREE --measure gym,vector1,vector64,engine4096 \\
        --rounds 4 --json benchmarks/results/house_speed.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
WORKTREE = "WORKTREE"

# Run in a fresh interpreter of the version under test: only public APIs that every version has.
CHILD = r'''
import json, sys, time
import numpy as np
measure, map_name, windows, steps = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
rng = np.random.default_rng(0)
if measure == "gym":
    import gymnasium as gym
    import smac_hard_gym  # noqa: F401
    env = gym.make(f"SMACHard-{map_name}-v0", opponent="base").unwrapped
    env.reset(seed=0)
    n_agents, battles = env.action_space.nvec.size, 1
    noise = rng.random((4096, n_agents, int(env.action_space.nvec[0])))
    def run(k, i0):
        for i in range(i0, i0 + k):
            mask = env.action_masks().reshape(n_agents, -1)
            _, _, term, trunc, _ = env.step(np.argmax(mask * noise[i % 4096], axis=1))
            if term or trunc:
                env.reset()
elif measure.startswith("vector"):
    from smac_hard_gym.envs.vector import NativeVectorEnv
    battles = int(measure[len("vector"):])
    env = NativeVectorEnv(map_name, num_envs=battles, opponent="base")
    env.reset(seed=0)
    n_agents, n_actions = env.single_action_space.nvec.size, int(env.single_action_space.nvec[0])
    noise = rng.random((64, battles, n_agents, n_actions))
    def run(k, i0):
        for i in range(i0, i0 + k):
            mask = env.action_masks().reshape(battles, n_agents, n_actions)
            env.step(np.argmax(mask * noise[i % 64], axis=2))
elif measure.startswith("engine"):
    from smac_hard_gym.engine import CMD_ATTACK, CMD_MOVE, BattleEngine
    battles = int(measure[len("engine"):])
    engine = BattleEngine(map_name, batch_size=battles)
    n = engine.n_units
    limit = engine.spec.episode_limit * engine.step_mul
    kinds = rng.integers(0, 2, size=(16, battles, n))
    targets = rng.integers(0, n, size=(16, battles, n))
    offsets = rng.uniform(-6, 6, size=(16, 2, battles, n))
    def run(k, i0):
        cmd, st = engine.commands, engine.state
        for i in range(i0, i0 + k):
            j = i % 16
            cmd.kind[:] = np.where(kinds[j] == 0, CMD_ATTACK, CMD_MOVE)
            cmd.target[:] = targets[j]
            cmd.x[:] = st.x + offsets[j, 0]
            cmd.y[:] = st.y + offsets[j, 1]
            engine.step()
            red, blue = engine.alive_counts()
            done = (red == 0) | (blue == 0) | (st.loop >= limit)
            if done.any():
                engine.reset(done)
else:
    raise SystemExit(f"unknown measurement {measure!r}")
run(max(50, steps), 0)
times = []
for w in range(windows):
    t = time.perf_counter()
    run(steps, (w + 1) * steps)
    times.append(time.perf_counter() - t)
times.sort()
print(json.dumps({"best": steps * battles / times[0], "median": steps * battles / times[len(times) // 2]}))
'''


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def install(rev: str, root: Path) -> Path:
    """A non-editable install of ``rev`` (or the working tree) in its own folder; returns the folder. A folder that
    already holds an install (a ``smac_hard_gym`` package in it, as ``pip install --no-deps --target DIR`` leaves it)
    is used as it is: that is how versions travel to a machine without the repository's history."""
    if Path(rev).is_dir() and (Path(rev) / "smac_hard_gym" / "__init__.py").is_file():
        return Path(rev).resolve()
    target = root / ("worktree" if rev == WORKTREE else rev)
    if rev == WORKTREE:
        source = REPO
    else:
        source = root / f"src-{rev}"
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", str(source), rev], check=True,
                       capture_output=True)
    try:
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                        "--target", str(target), str(source)], check=True)
    finally:
        if rev != WORKTREE:
            subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(source)], check=False)
    return target


def measure_once(site: Path, cache: Path, what: str, map_name: str, windows: int, steps: int, threads: int = 1) -> dict:
    env = {**os.environ, "PYTHONPATH": str(site), "NUMBA_CACHE_DIR": str(cache), "NUMBA_NUM_THREADS": str(threads)}
    out = subprocess.run([sys.executable, "-c", CHILD, what, map_name, str(windows), str(steps)], env=env,
                         cwd=tempfile.gettempdir(), capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--before", required=True,
                   help="git revision, WORKTREE, or a folder holding an install (pip install --no-deps --target)")
    p.add_argument("--after", default=WORKTREE,
                   help="git revision, WORKTREE (the default: the working tree), or a folder holding an install")
    p.add_argument("--map", default="3m")
    p.add_argument("--measure", default="gym,vector1,vector64,engine4096",
                   help="comma list of gym, vector<N>, engine<N> (default gym,vector1,vector64,engine4096)")
    p.add_argument("--rounds", type=int, default=4, help="rounds, each running both versions (default 4)")
    p.add_argument("--windows", type=int, default=60, help="timed windows per measurement (default 60)")
    p.add_argument("--steps", type=int, default=0,
                   help="steps per window (default: 50 for one battle, 10 for 64+, 2 for 1024+)")
    p.add_argument("--threads", type=int, default=1,
                   help="numba threads of each measured process (default 1; `bench engine` uses every core)")
    p.add_argument("--json", type=Path, help="write the rounds and the summary here")
    args = p.parse_args(argv)
    measures = args.measure.split(",")
    for what in measures:
        if what != "gym" and not (what.startswith(("vector", "engine")) and what[6:].isdigit() and int(what[6:])):
            p.error(f"--measure: {what!r} is not gym, vector<N> or engine<N> (N a positive int)")
    if args.rounds < 1 or args.windows < 1 or args.steps < 0 or args.threads < 1:
        p.error("--rounds, --windows and --threads must be >= 1, --steps >= 0")

    def steps_for(what: str) -> int:
        battles = 1 if what == "gym" else int(what[6:])
        return args.steps or (50 if battles < 64 else 10 if battles < 1024 else 2)

    with tempfile.TemporaryDirectory(prefix="ab_speed-") as tmp:
        root = Path(tmp)
        versions = {"before": args.before, "after": args.after}
        sites = {tag: install(rev, root) for tag, rev in versions.items()}
        caches = {tag: root / f"numba-{tag}" for tag in versions}
        for tag in versions:  # compile each version's kernels once, untimed
            for what in measures:
                measure_once(sites[tag], caches[tag], what, args.map, 1, 1, args.threads)
        rounds = []
        for r in range(args.rounds):
            order = ["before", "after"] if r % 2 == 0 else ["after", "before"]
            row = {}
            for what in measures:
                for tag in order:
                    row[f"{what}/{tag}"] = measure_once(sites[tag], caches[tag], what, args.map, args.windows,
                                                        steps_for(what), args.threads)
            load = os.getloadavg()
            rounds.append({"round": r, "order": order, "load_average": load, "results": row})
            print(f"round {r + 1}/{args.rounds} done (load {load[0]:.1f})", file=sys.stderr)

    summary = {}
    print(f"{args.map}: steps/s, median over {args.rounds} rounds of each version's best window "
          f"({args.windows} windows, {args.threads} numba thread(s))")
    print(f"{'measurement':<14}{'before':>12}{'after':>12}{'after/before':>14}")
    for what in measures:
        best = {tag: statistics.median(r["results"][f"{what}/{tag}"]["best"] for r in rounds) for tag in versions}
        ratio = best["after"] / best["before"]
        summary[what] = {"before": best["before"], "after": best["after"], "after_over_before": ratio}
        print(f"{what:<14}{best['before']:>12,.0f}{best['after']:>12,.0f}{ratio:>14.3f}")
    if args.json:
        doc = {"benchmark": "ab_speed", "before": args.before, "after": args.after, "map": args.map,
               "machine": {"cpu": _cpu_name(), "cores": os.cpu_count(), "python": platform.python_version()},
               "command": " ".join([Path(sys.argv[0]).name, *(argv if argv is not None else sys.argv[1:])]),
               "windows": args.windows, "threads": args.threads, "rounds": rounds, "summary": summary}
        args.json.write_text(json.dumps(doc, indent=1) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
