"""Soak every step API with malformed and legal actions on every map, and count what happened.

    python benchmarks/soak.py                          # >= 200k malformed and >= 1M legal steps over the 23 maps
    python benchmarks/soak.py --maps 3m,MMM --malformed 2000 --legal 20000 --out soak.json

Each malformed step must raise TypeError or ValueError and leave the env exactly as it was (the fuzz harness of the
test suite, tests/fuzz_harness.py, snapshots everything a step changes); after each, a legal step must work. Legal
steps are also run in bulk (random available actions, native batches of 64 battles); one battle stepping once is
one legal step. The report counts, per API: malformed steps, clean rejections, silent accepts, state changes after
a rejection and crashes (any other exception), and legal steps; it exits 1 unless the last three are all 0.

APIs: StarCraft2Env (script and self-play), the gymnasium env, NativeVectorEnv, PettingZoo (one team and both),
SubprocVectorEnv and RayVectorEnv (the last two in lock-step with a native batch, whose state they must keep).
Not part of the test suite: the default run takes tens of minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fuzz_harness import (  # noqa: E402 - the harness lives beside the tests that use it
    SEED,
    GymApi,
    PettingZooApi,
    Sc2Api,
    VectorApi,
    fuzz_remote,
    fuzz_round,
    legal_actions,
)

from smac_hard_gym.envs.vector import NativeVectorEnv  # noqa: E402
from smac_hard_gym.files import atomic_write  # noqa: E402
from smac_hard_gym.maps import list_maps  # noqa: E402

LOCAL_APIS = {
    "StarCraft2Env-script": lambda m: Sc2Api(m, "script"),
    "StarCraft2Env-self-play": lambda m: Sc2Api(m, "self-play"),
    "SMACHardEnv": GymApi,
    "NativeVectorEnv": VectorApi,
    "PettingZoo-red": lambda m: PettingZooApi(m, "red"),
    "PettingZoo-both": lambda m: PettingZooApi(m, "both"),
}
REMOTE_APIS = ("SubprocVectorEnv", "RayVectorEnv")
REMOTE_SHARE = 0.02  # remote envs pay a round trip per step: they get this share of each map's malformed steps
BULK_BATCH = 64


class Tally:
    """Counts per API, and the first few problems in full."""

    def __init__(self) -> None:
        self.counts: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
        self.examples: list[str] = []

    def malformed(self, api: str, outcome: str) -> None:
        counts = self.counts[api]
        counts["malformed"] += 1
        counts["legal_steps"] += outcome == "rejected"
        key = ("rejected" if outcome == "rejected" else "silent_accepts" if outcome.startswith("silent") else
               "crashes" if outcome.startswith("crash") else "state_changes")
        counts[key] += 1
        if key != "rejected" and len(self.examples) < 20:
            self.examples.append(f"{api}: {outcome[:500]}")

    def problems(self) -> int:
        return sum(c["silent_accepts"] + c["crashes"] + c["state_changes"] for c in self.counts.values())


def soak_local(map_name: str, rounds: int, rng: np.random.Generator, tally: Tally) -> None:
    for name, make in LOCAL_APIS.items():
        api = make(map_name)
        try:
            for _ in range(rounds):
                tally.malformed(name, fuzz_round(api, rng))
        finally:
            api.close()


def soak_remote(map_name: str, rounds: int, rng: np.random.Generator, tally: Tally) -> None:
    from smac_hard_gym.envs.subproc import make_subproc_env

    makers = {"SubprocVectorEnv": make_subproc_env}
    try:
        from smac_hard_gym.wrappers.ray_vec import make_ray_vec

        makers["RayVectorEnv"] = make_ray_vec
    except ImportError:
        print("ray is not installed: RayVectorEnv skipped", file=sys.stderr)
    for name, make in makers.items():
        native = VectorApi(map_name, opponent="default")
        env = make(map_name, 2, 1, invalid_action="raise", autoreset_mode="SameStep", opponent="default")
        try:
            fuzz_remote(env, native, rng, rounds=rounds)  # raises on the first problem: counted as a crash
            tally.counts[name].update(malformed=rounds, rejected=rounds, legal_steps=rounds * env.num_envs)
        except AssertionError as err:
            tally.malformed(name, f"crash: {err}")
        finally:
            env.close()
            native.close()


def soak_legal(map_name: str, steps: int, rng: np.random.Generator, tally: Tally) -> None:
    env = NativeVectorEnv(map_name, BULK_BATCH, autoreset_mode="SameStep", invalid_action="raise")
    env.reset(seed=SEED)
    n_agents = env.view.n_agents
    try:
        for _ in range(-(-steps // BULK_BATCH)):
            masks = env.action_masks().reshape(BULK_BATCH, n_agents, -1)
            env.step(legal_actions(rng, masks))
            tally.counts["NativeVectorEnv (bulk legal)"]["legal_steps"] += BULK_BATCH
    except Exception as err:  # noqa: BLE001 - a legal step must never fail
        tally.malformed("NativeVectorEnv (bulk legal)", f"crash: {type(err).__name__}: {err}")
    finally:
        env.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--maps", default=",".join(list_maps()), help="comma-separated maps (default: all 23)")
    parser.add_argument("--malformed", type=int, default=200_000, help="malformed steps in all (default 200,000)")
    parser.add_argument("--legal", type=int, default=1_000_000, help="bulk legal steps in all (default 1,000,000)")
    parser.add_argument("--no-remote", action="store_true", help="skip SubprocVectorEnv and RayVectorEnv")
    parser.add_argument("--out", default="benchmarks/results/soak.json", help="where the JSON report goes")
    args = parser.parse_args(argv)
    maps = [m for m in args.maps.split(",") if m]
    unknown = sorted(set(maps) - set(list_maps()))
    if unknown:
        parser.error(f"unknown map(s) {unknown}; the maps are {list_maps()}")
    if args.malformed < 0 or args.legal < 0:
        parser.error("--malformed and --legal must be non-negative")
    remote_rounds = 0 if args.no_remote else int(args.malformed * REMOTE_SHARE / (len(maps) * len(REMOTE_APIS)))
    local_rounds = -(-(args.malformed - remote_rounds * len(maps) * len(REMOTE_APIS)) // (len(maps) * len(LOCAL_APIS)))
    tally = Tally()
    ray = None
    if remote_rounds:
        try:
            import ray

            ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)  # one local Ray for every map
        except ImportError:
            ray = None
    started = time.perf_counter()
    for k, map_name in enumerate(maps):
        rng = np.random.default_rng([SEED, k])
        soak_local(map_name, local_rounds, rng, tally)
        if remote_rounds:
            soak_remote(map_name, remote_rounds, rng, tally)
        soak_legal(map_name, -(-args.legal // len(maps)), rng, tally)
        print(f"{map_name:>16}: done at {time.perf_counter() - started:.0f} s", flush=True)
    if ray is not None:
        ray.shutdown()
    totals = collections.Counter()
    for counts in tally.counts.values():
        totals.update(counts)
    columns = ("malformed", "rejected", "silent_accepts", "state_changes", "crashes", "legal_steps")
    print(f"\n{'API':<30}" + "".join(f"{c:>16}" for c in columns))
    for name, counts in [*sorted(tally.counts.items()), ("total", totals)]:
        print(f"{name:<30}" + "".join(f"{counts[c]:>16,}" for c in columns))
    for example in tally.examples:
        print("problem:", example)
    report = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version()},
              "maps": maps, "seconds": round(time.perf_counter() - started, 1),
              "per_api": {k: dict(v) for k, v in tally.counts.items()}, "total": dict(totals),
              "problems": tally.examples}
    with atomic_write(args.out) as f:
        json.dump(report, f, indent=1)
    print(f"{totals['malformed']:,} malformed and {totals['legal_steps']:,} legal steps in "
          f"{report['seconds']:.0f} s; problems: {tally.problems()}; report: {args.out}")
    return 1 if tally.problems() else 0


if __name__ == "__main__":
    raise SystemExit(main())
