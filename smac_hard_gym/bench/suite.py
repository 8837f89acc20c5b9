"""The suite behind ``smac-hard-gym bench vector``: its configuration, the checks on it, and the run of every
section into one results document."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from smac_hard_gym.bench.fresh_process import cold_start
from smac_hard_gym.bench.machine import cpu_probe, machine_info, source_version
from smac_hard_gym.bench.measure import bench_engine, bench_native, bench_starcraft2, bench_subproc
from smac_hard_gym.bench.profiles import profile_native, profile_starcraft2
from smac_hard_gym.bench.smax import SMAX_MAPS, run_smax, smax_python
from smac_hard_gym.bench.targets import must_reach
from smac_hard_gym.bench.timing import Measurement

DEFAULT_MAPS = ("3m", "8m", "2s3z", "MMM2", "27m_vs_30m", "corridor", "2c_vs_64zg")
DEFAULT_NUM_ENVS = (1, 16, 256, 1024, 4096)
DEFAULT_WORKERS = (1, 2, 4)
DEFAULT_ENVS_PER_WORKER = (16, 256)
DEFAULT_SUBPROC_MAPS = ("3m", "27m_vs_30m")
SECTIONS = ("native", "engine", "subproc", "starcraft2", "opponents", "memory", "profile", "ray")
DEFAULT_SECTIONS = tuple(s for s in SECTIONS if s != "ray")  # ray: only when asked for (needs the [ray] extra)
DEFAULT_RAY_MAPS = ("27m_vs_30m",)
DEFAULT_RAY_ACTORS = (1, 2)
OPPONENTS = ("base", "default")


@dataclass
class SuiteConfig:
    """What ``smac-hard-gym bench vector`` measures; every field has a CLI flag of the same name."""

    maps: Sequence[str] = DEFAULT_MAPS
    num_envs: Sequence[int] = DEFAULT_NUM_ENVS
    opponent: str = "base"
    workers: Sequence[int] = DEFAULT_WORKERS
    envs_per_worker: Sequence[int] = DEFAULT_ENVS_PER_WORKER
    subproc_maps: Sequence[str] = DEFAULT_SUBPROC_MAPS
    opponent_num_envs: int = 256
    memory: Sequence[tuple[str, int]] = (("3m", 4096),)
    profile: Sequence[tuple[str, int]] = ()  # empty: each SMAX map at its best native batch, and StarCraft2Env 3m
    sections: Sequence[str] = DEFAULT_SECTIONS
    ray_maps: Sequence[str] = DEFAULT_RAY_MAPS
    ray_actors: Sequence[int] = DEFAULT_RAY_ACTORS
    ray_envs_per_actor: int = 256
    ray_address: str | None = None  # a Ray cluster to run the ray section on (None: a local Ray started for it)
    seconds: float = 1.0
    repeats: int = 3
    seed: int = 0
    peer: str | None = None
    peer_python: str | None = None
    numba_threads: int | None = None  # threads of the engine's parallel kernels in this process (None: numba's)


def _check_config(config: SuiteConfig) -> None:
    from smac_hard_gym.maps import load_map

    for name in (*config.maps, *config.subproc_maps, *config.ray_maps, *(m for m, _ in config.memory),
                 *(m for m, _ in config.profile)):
        load_map(name)  # a clear error for an unknown map before any timing
    bad = [s for s in config.sections if s not in SECTIONS]
    if bad:
        raise ValueError(f"unknown sections {bad}; choose from {list(SECTIONS)}")
    if config.opponent not in OPPONENTS:
        raise ValueError(f"opponent must be one of {OPPONENTS}, got {config.opponent!r}")
    if config.peer not in (None, "smax"):
        raise ValueError(f"peer must be 'smax' or None, got {config.peer!r}")
    if config.numba_threads is not None:
        import numba

        if not 1 <= config.numba_threads <= numba.config.NUMBA_NUM_THREADS:
            raise ValueError(f"numba_threads must lie in 1..{numba.config.NUMBA_NUM_THREADS} (NUMBA_NUM_THREADS), "
                             f"got {config.numba_threads!r}")
    if "ray" in config.sections:
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ValueError("the ray section needs Ray: pip install 'smac-hard-gym[ray]'") from None
    if not config.seconds > 0 or config.repeats < 1:
        raise ValueError(f"seconds must be > 0 and repeats >= 1, got {config.seconds!r} and {config.repeats!r}")


def _best(results: list[Measurement], section: str, map_name: str, **match: Any) -> Measurement | None:
    rows = [r for r in results if r.section == section and r.map == map_name
            and all(getattr(r, k) == v for k, v in match.items())]
    return max(rows, key=lambda r: r.steps_per_second, default=None)


def run_suite(config: SuiteConfig, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every section of ``config``; returns the results document (what :func:`markdown_report` renders)."""
    _check_config(config)
    peer_python = smax_python(config.peer_python) if config.peer == "smax" else None
    sections = set(config.sections)
    results: list[Measurement] = []
    probes: list[dict[str, Any]] = []
    doc: dict[str, Any] = {"benchmark": "vector", "config": {k: v for k, v in asdict(config).items()},
                           "results": results, "cpu_probes": probes, "memory": [], "profiles": [], "peer": None,
                           "ray_payload": []}
    timing = {"seconds": config.seconds, "repeats": config.repeats, "seed": config.seed}
    started = time.perf_counter()
    doc["started"] = time.strftime("%Y-%m-%d %H:%M:%S %Z")
    doc["source"] = source_version()
    if config.numba_threads is not None:
        import numba

        numba.set_num_threads(config.numba_threads)
    doc["load_average_start"] = list(os.getloadavg()) if hasattr(os, "getloadavg") else None

    def probe(label: str) -> None:
        probes.append({"before": label, "seconds": cpu_probe()})

    def record(m: Measurement) -> None:
        results.append(m)
        lo, hi = m.spread
        mem = "" if m.peak_bytes_per_env is None else f"  peak {m.peak_bytes_per_env / 1024:,.1f} KB/battle"
        if "compile_seconds" in m.extra:
            mem = f"  compile {m.extra['compile_seconds']:.1f} s"
        who = (f"{m.workers}x{m.extra.get('envs_per_worker')}" if m.section in ("subproc", "ray")
               else f"N={m.num_envs}")
        who_else = f"SMAX {m.mode}" if m.section == "smax" else f"{m.mode} {m.opponent}" if m.section == "ray" \
            else m.opponent
        log(f"  {m.section:<10} {m.map:<12} {who:<9} {who_else:<10} {m.steps_per_second:>12,.0f} "
            f"steps/s  ({lo:,.0f}-{hi:,.0f}){mem}")

    if sections & {"memory", "profile", "native"}:
        log("cold start (fresh process): ...")
        first = cold_start(*(config.memory[0] if config.memory else ("3m", 1)), opponent=config.opponent)
        doc["memory"].append(first)
        log(f"  import {first['import_seconds']:.1f} s, first step {first['cold_start_seconds']:.1f} s; "
            f"{first['map']} x {first['num_envs']}: {first['rss_bytes_per_env'] / 1024:,.1f} KB/battle peak RSS")
    if peer_python:
        doc["peer"] = {"name": "smax", "python": peer_python}

    if "native" in sections:
        for name in config.maps:
            probe(f"native {name}")
            log(f"native vector env, {name} (opponent {config.opponent}):")
            for n in config.num_envs:
                record(bench_native(name, n, opponent=config.opponent, **timing))
            if peer_python and name in SMAX_MAPS:
                probe(f"smax {name}")
                log(f"SMAX, {name}:")
                # The single-env loops are compared on 3m only (the StarCraft2Env target).
                modes = ("scan", "loop", "pymarl") if name == "3m" else ("scan",)
                smax, machine = run_smax(peer_python, [name], config.num_envs, modes=modes, seconds=config.seconds,
                                         repeats=config.repeats, seed=config.seed)
                doc["peer"]["machine"] = machine
                for m in smax:
                    record(m)
    if "engine" in sections:
        probe("engine")
        log("engine alone (random commands):")
        for name in config.maps:
            for n in config.num_envs:
                record(bench_engine(name, n, seconds=config.seconds, repeats=config.repeats, seed=config.seed))
    if "subproc" in sections:
        probe("subproc")
        log("subprocess vector env (workers x battles each):")
        for name in config.subproc_maps:
            for k in config.envs_per_worker:
                for w in config.workers:
                    record(bench_subproc(name, w, k, opponent=config.opponent, **timing))
    if "ray" in sections:
        from smac_hard_gym.bench.ray_section import bench_ray

        probe("ray")
        log(f"Ray actors vs subprocess workers (x {config.ray_envs_per_actor} battles each), interleaved rounds:")
        for name in config.ray_maps:
            measured, payload = bench_ray(name, config.ray_actors, config.ray_envs_per_actor,
                                          opponent=config.opponent, address=config.ray_address, log=log, **timing)
            for m in measured:
                record(m)
            doc["ray_payload"].append(payload)
            log("  bytes per step per actor: " + ", ".join(
                f"{k} {v:,.0f}" for k, v in payload["bytes_per_step_per_actor"].items()))
    if "starcraft2" in sections:
        probe("starcraft2")
        log("StarCraft2Env, one battle, pymarl loop:")
        for opponent in OPPONENTS:
            record(bench_starcraft2("3m", opponent=opponent, **timing))
        if peer_python and not any(r.section == "smax" and r.mode == "loop" and r.map == "3m" for r in results):
            smax, machine = run_smax(peer_python, ["3m"], [1], modes=("loop", "pymarl"), seconds=config.seconds,
                                     repeats=config.repeats, seed=config.seed)
            doc["peer"]["machine"] = machine
            for m in smax:
                record(m)
    if "opponents" in sections:
        probe("opponents")
        log(f"opponents at N={config.opponent_num_envs}:")
        for name in config.maps:
            for opponent in OPPONENTS:
                record(bench_native(name, config.opponent_num_envs, opponent=opponent, trace_memory=False,
                                    section="opponents", **timing))
    if "memory" in sections:
        for name, n in config.memory[1:]:
            log(f"memory, fresh process: {name} x {n} ...")
            doc["memory"].append(cold_start(name, n, opponent=config.opponent))
    if "profile" in sections:
        log("profiles (wall-time split of a step):")
        targets = list(config.profile)
        if not targets:
            for name in SMAX_MAPS:
                best = _best(results, "native", name)
                if best is not None:
                    targets.append((name, best.num_envs))
        for name, n in targets:
            doc["profiles"].append(profile_native(name, n, opponent=config.opponent, seconds=2 * config.seconds))
            log(f"  native {name} N={n}: " + _profile_line(doc["profiles"][-1]))
        if "starcraft2" in sections:
            doc["profiles"].append(profile_starcraft2("3m", opponent="base", seconds=2 * config.seconds))
            log("  StarCraft2Env 3m: " + _profile_line(doc["profiles"][-1]))
    probe("end")
    doc["machine"] = machine_info()  # after the engine ran here, so numba's threading layer is known
    now, then = source_version()["files"], doc["source"]["files"]
    changed = sorted(f for f in now.keys() | then.keys() if now.get(f) != then.get(f))
    if changed:
        doc["warnings"] = [f"source files changed during the run ({', '.join(changed)}): this process kept the "
                           "versions it had imported; processes started later (workers, probes) got the new ones"]
        log("WARNING: " + doc["warnings"][0])
    doc["elapsed_seconds"] = time.perf_counter() - started
    doc["results"] = [asdict(r) for r in results]
    doc["must_reach"] = must_reach(doc)
    return doc


def _profile_line(p: dict[str, Any]) -> str:
    top = sorted(p["share"].items(), key=lambda kv: -kv[1])[:4]
    return ", ".join(f"{k} {v:.0%}" for k, v in top)
