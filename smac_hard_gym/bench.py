"""Throughput benchmarks: env-steps/s through the public APIs, with the machine, versions and date named.

Units and rules (every figure this module produces follows them):

- An **env step** is one SMAC step (``step_mul`` = 8 game loops) of one battle. A vector env of N battles stepped
  once counts N env steps. Resets are included: the vector envs run in ``SameStep`` autoreset mode, so every step
  of every battle is a real transition and finished battles restart inside the step that ended them.
- The **policy** is uniform over each agent's legal actions (:class:`RandomLegalPolicy`): one uniform draw per
  (battle, agent) picks a rank among the legal actions, in a compiled loop, so it never picks an illegal action and
  costs little next to the env. (SMAX's side draws the same distribution inside its jitted step.)
- **Compile time apart.** Every configuration is built and stepped twice before timing; the cold start of a fresh
  process (import, numba cache load or compile, first step) is measured on its own (:func:`cold_start`).
- **Medians of repeats.** Each configuration runs ``repeats`` timed windows of at least ``seconds`` seconds (and at
  least one step); the figure is their median and ``runs`` keeps them all.
- **Noise.** The machine may be shared: :func:`cpu_probe` times a fixed workload before each group of runs so a
  reader can see how contended the machine was.

Sections of :func:`run_suite` (``smac-hard-gym bench vector``): ``native`` (NativeVectorEnv, maps x num_envs),
``engine`` (the engine alone, random commands), ``subproc`` (SubprocVectorEnv, workers x K battles each),
``starcraft2`` (StarCraft2Env, one battle, pymarl's loop), ``opponents`` (``base`` vs the ``default`` mixture),
``memory`` (peak RSS of a fresh process per battle), ``profile`` (where a step's time goes) and, with a peer, ``smax``
(SMAX run by ``benchmarks/smax_bench.py`` in its own Python). :func:`markdown_report`, :func:`plot_report` and
:func:`must_reach` turn the resulting document into the published table, figure and target checks.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

__all__ = [
    "DEFAULT_MAPS", "DEFAULT_NUM_ENVS", "SECTIONS", "SMAX_MAPS", "Measurement", "RandomLegalPolicy", "SuiteConfig",
    "CpuMeter", "bench_engine", "bench_native", "bench_starcraft2", "bench_subproc", "cold_start", "cpu_probe",
    "machine_info", "markdown_report", "must_reach", "plot_report", "profile_native", "profile_starcraft2",
    "run_smax", "run_suite", "smax_python", "source_version", "timed_repeats", "write_json",
]

DEFAULT_MAPS = ("3m", "8m", "2s3z", "MMM2", "27m_vs_30m", "corridor", "2c_vs_64zg")
DEFAULT_NUM_ENVS = (1, 16, 256, 1024, 4096)
DEFAULT_WORKERS = (1, 2, 4)
DEFAULT_ENVS_PER_WORKER = (16, 256)
DEFAULT_SUBPROC_MAPS = ("3m", "27m_vs_30m")
SMAX_MAPS = ("3m", "8m", "2s3z", "27m_vs_30m")  # the maps of ours that SMAX also has
SECTIONS = ("native", "engine", "subproc", "starcraft2", "opponents", "memory", "profile")
OPPONENTS = ("base", "default")
REPO_ROOT = Path(__file__).resolve().parents[1]
SMAX_SCRIPT = REPO_ROOT / "benchmarks" / "smax_bench.py"


# ---------------------------------------------------------------------------------------------------------------
# Machine, noise and timing.


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
            if "commands" not in path.parts and path.name != "bench.py":
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


# ---------------------------------------------------------------------------------------------------------------
# The policy.


@njit(cache=True)
def _pick_legal(masks, draws, out):
    """out[b, i] = the legal action of rank int(draws[b, i] * legal count) among agent i's legal actions."""
    for b in range(masks.shape[0]):
        for i in range(masks.shape[1]):
            count = 0
            for a in range(masks.shape[2]):
                count += masks[b, i, a] != 0
            rank = int(draws[b, i] * count)
            for a in range(masks.shape[2]):
                if masks[b, i, a] != 0:
                    if rank == 0:
                        out[b, i] = a
                        break
                    rank -= 1


class RandomLegalPolicy:
    """Uniform over each agent's legal actions: one uniform draw per (battle, agent) picks a rank among the legal
    actions (a compiled loop, so that the policy costs little next to the env). Every agent always has a legal action
    (no-op when dead, stop when alive), so the result is always legal.
    """

    def __init__(self, num_envs: int, n_agents: int, n_actions: int, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)
        self.shape = (num_envs, n_agents, n_actions)
        self._draws = np.empty((num_envs, n_agents), dtype=np.float64)

    def __call__(self, masks: np.ndarray) -> np.ndarray:
        """``masks``: bool or int ``(N, n_agents * n_actions)`` or ``(N, n_agents, n_actions)``; int64 (N, n_agents)."""
        self.rng.random(out=self._draws)
        out = np.empty(self.shape[:2], dtype=np.int64)
        _pick_legal(np.ascontiguousarray(masks).reshape(self.shape), self._draws, out)
        return out


class _VectorLoop:
    """Steps a gymnasium vector env with the random legal policy; ``step()`` returns the env steps made."""

    def __init__(self, env: Any, n_agents: int, n_actions: int, seed: int) -> None:
        self.env = env
        self.policy = RandomLegalPolicy(env.num_envs, n_agents, n_actions, seed)
        self.episodes = 0

    def step(self) -> int:
        env = self.env
        _, _, terminated, truncated, _ = env.step(self.policy(env.action_masks()))
        self.episodes += int(np.count_nonzero(terminated | truncated))
        return env.num_envs


def _warm_up(loop: _VectorLoop) -> None:
    loop.step()
    loop.step()


def _measure_loop(make: Callable[[], tuple[Any, _VectorLoop]], seconds: float, repeats: int,
                  trace_memory: bool) -> tuple[Any, _VectorLoop, list[float], float, float | None, float, dict]:
    """Build (traced when asked), warm up, time. Returns env, loop, runs, setup s, peak bytes, episodes/s and the
    :class:`CpuMeter` reading of the timed windows."""
    if trace_memory:
        tracemalloc.start()
    t0 = time.perf_counter()
    try:
        env, loop = make()
        _warm_up(loop)
        peak = tracemalloc.get_traced_memory()[1] if trace_memory else None
    finally:
        if trace_memory:
            tracemalloc.stop()
    setup = time.perf_counter() - t0
    loop.episodes = 0
    t1 = time.perf_counter()
    with CpuMeter([p.pid for p in getattr(env, "processes", [])]) as meter:
        runs = timed_repeats(loop.step, seconds, repeats)
    episodes_per_second = loop.episodes / (time.perf_counter() - t1)
    return env, loop, runs, setup, peak, episodes_per_second, meter.result


# ---------------------------------------------------------------------------------------------------------------
# Our environments.


def bench_native(map_name: str, num_envs: int, *, opponent: str = "base", seconds: float = 1.0, repeats: int = 3,
                 seed: int = 0, trace_memory: bool = True, section: str = "native") -> Measurement:
    """``NativeVectorEnv`` through the gymnasium vector API: random legal actions, SameStep autoreset."""
    from smac_hard_gym.vector import NativeVectorEnv

    def make(n: int = num_envs) -> tuple[Any, _VectorLoop]:
        env = NativeVectorEnv(map_name, n, opponent=opponent, autoreset_mode="SameStep")
        env.reset(seed=seed)
        return env, _VectorLoop(env, env.view.n_agents, env.view.n_actions, seed)

    if trace_memory:  # one-time costs (lazy imports, kernel loads, map caches) must not count as this config's
        primer, loop = make(1)
        _warm_up(loop)
        primer.close()
    env, _, runs, setup, peak, eps, cpu = _measure_loop(make, seconds, repeats, trace_memory)
    env.close()
    return Measurement(section, map_name, num_envs, float(np.median(runs)), runs, opponent=opponent,
                       setup_seconds=setup, episodes_per_second=eps,
                       peak_bytes_per_env=None if peak is None else peak / num_envs, extra={"cpu": cpu})


def bench_subproc(map_name: str, workers: int, envs_per_worker: int, *, opponent: str = "base",
                  seconds: float = 1.0, repeats: int = 3, seed: int = 0) -> Measurement:
    """``SubprocVectorEnv``: ``workers`` processes of ``envs_per_worker`` battles each, one numba thread each."""
    from smac_hard_gym.subproc import make_subproc_env

    def make() -> tuple[Any, _VectorLoop]:
        env = make_subproc_env(map_name, num_workers=workers, envs_per_worker=envs_per_worker,
                               autoreset_mode="SameStep", opponent=opponent)
        env.reset(seed=seed)
        n_agents = len(env.single_action_space.nvec)
        return env, _VectorLoop(env, n_agents, int(env.single_action_space.nvec[0]), seed)

    env, _, runs, setup, _, eps, cpu = _measure_loop(make, seconds, repeats, trace_memory=False)
    worker_rss = [_peak_rss_of(p.pid) for p in env.processes]
    env.close()
    rss = [r for r in worker_rss if r is not None]
    return Measurement("subproc", map_name, workers * envs_per_worker, float(np.median(runs)), runs,
                       opponent=opponent, workers=workers, setup_seconds=setup, episodes_per_second=eps,
                       extra={"envs_per_worker": envs_per_worker, "cpu": cpu,
                              "worker_peak_rss_mib": [round(r / 2**20, 1) for r in rss]})


def bench_starcraft2(map_name: str = "3m", *, opponent: str = "base", seconds: float = 1.0, repeats: int = 3,
                     seed: int = 0) -> Measurement:
    """``StarCraft2Env``, one battle, in pymarl's episode-runner loop: each step reads ``get_state()``,
    ``get_avail_actions()`` and ``get_obs()``, picks random legal actions, calls ``step``; resets on episode end."""
    from smac_hard_gym.starcraft2 import StarCraft2Env

    env = StarCraft2Env(map_name=map_name, opponent=opponent, seed=seed)
    info = env.get_env_info()
    policy = RandomLegalPolicy(1, info["n_agents"], info["n_actions"], seed)
    episodes = [0]

    def step() -> int:
        env.get_state()
        avail = np.asarray(env.get_avail_actions())
        env.get_obs()
        _, terminated, _ = env.step(policy(avail[None])[0])
        if terminated:
            episodes[0] += 1
            env.reset()
        return 1

    t0 = time.perf_counter()
    env.reset()
    step()
    step()
    setup = time.perf_counter() - t0
    episodes[0] = 0
    t1 = time.perf_counter()
    with CpuMeter() as meter:
        runs = timed_repeats(step, seconds, repeats)
    eps = episodes[0] / (time.perf_counter() - t1)
    env.close()
    return Measurement("starcraft2", map_name, 1, float(np.median(runs)), runs, opponent=opponent,
                       setup_seconds=setup, episodes_per_second=eps, extra={"cpu": meter.result})


def _random_command_pool(engine: Any, rng: np.random.Generator, size: int) -> list:
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


def bench_engine(map_name: str, batch: int, steps: int | None = None, repeats: int = 3, seed: int = 0,
                 seconds: float = 1.0) -> Measurement:
    """The engine alone: random commands every step, battles reset when one side is dead or at the limit.

    ``steps`` fixes the steps per timed repeat; None runs each repeat for ``seconds``. ``extra`` holds
    ``resets_per_second`` and ``state_bytes_per_battle`` (the engine state arrays).
    """
    from smac_hard_gym.engine import BattleEngine
    from smac_hard_gym.engine.state import state_nbytes

    t0 = time.perf_counter()
    engine = BattleEngine(map_name, batch_size=batch)
    engine.step()
    setup = time.perf_counter() - t0
    engine.reset()
    pool = _random_command_pool(engine, np.random.default_rng(seed), 16)
    limit = engine.spec.episode_limit * engine.step_mul
    counter = {"k": 0, "resets": 0}

    def step() -> int:
        engine.step(pool[counter["k"] % len(pool)])
        counter["k"] += 1
        red, blue = engine.alive_counts()
        done = (red == 0) | (blue == 0) | (engine.state.loop >= limit)
        if done.any():
            counter["resets"] += int(done.sum())
            engine.reset(done)
        return batch

    step()
    t1 = time.perf_counter()
    with CpuMeter() as meter:
        if steps is None:
            runs = timed_repeats(step, seconds, repeats)
        else:
            runs = []
            for _ in range(repeats):
                t = time.perf_counter()
                for _ in range(steps):
                    step()
                runs.append(steps * batch / (time.perf_counter() - t))
    resets = counter["resets"] / (time.perf_counter() - t1)
    extra = {"resets_per_second": resets, "state_bytes_per_battle": state_nbytes(engine.state) / batch,
             "cpu": meter.result}
    return Measurement("engine", map_name, batch, float(np.median(runs)), runs, setup_seconds=setup,
                       episodes_per_second=resets, extra=extra)


# ---------------------------------------------------------------------------------------------------------------
# Memory and cold start in a fresh process.


def _die_with_parent() -> None:
    """In a child before exec (Linux): the kernel kills it if this process dies first, so no probe outlives us."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, 9)  # PR_SET_PDEATHSIG, SIGKILL
        except (OSError, AttributeError):
            pass


def _peak_rss_of(pid: int) -> int | None:
    """Peak resident set (VmHWM) of a process, bytes; None where /proc is missing."""
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        return None
    return None


def _rss_now() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise OSError("no VmRSS in /proc/self/status")


def _probe_main(map_name: str, num_envs: int, opponent: str) -> None:
    """Runs in a fresh process (``python -c``): cold start, then peak RSS growth of a NativeVectorEnv of
    ``num_envs`` battles over the same process with a warmed one-battle env; prints JSON."""
    t0 = time.perf_counter()
    from smac_hard_gym.vector import NativeVectorEnv

    t_import = time.perf_counter() - t0
    small = NativeVectorEnv(map_name, 1, opponent=opponent, autoreset_mode="SameStep")
    small.reset(seed=0)
    loop = _VectorLoop(small, small.view.n_agents, small.view.n_actions, 0)
    loop.step()
    t_first = time.perf_counter() - t0
    for _ in range(3):
        loop.step()
    small.close()
    baseline = _rss_now()
    reset_peak = True
    try:  # clear_refs "5" resets VmHWM to the current RSS (Linux >= 4.0), so the peak starts from here
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        reset_peak = False
    env = NativeVectorEnv(map_name, num_envs, opponent=opponent, autoreset_mode="SameStep")
    env.reset(seed=0)
    loop = _VectorLoop(env, env.view.n_agents, env.view.n_actions, 0)
    for _ in range(5):
        loop.step()
    peak = _peak_rss_of(os.getpid()) or _rss_now()
    print(json.dumps({"import_seconds": t_import, "cold_start_seconds": t_first, "baseline_rss": baseline,
                      "peak_rss": peak, "peak_reset": reset_peak,
                      "rss_bytes_per_env": (peak - baseline) / num_envs}))


def cold_start(map_name: str = "3m", num_envs: int = 4096, opponent: str = "base",
               timeout: float = 600.0) -> dict[str, Any]:
    """A fresh process: seconds to import and to make the first step (numba's disk cache load, or its compile on
    a cold cache), and peak RSS growth per battle of ``num_envs`` battles (``rss_bytes_per_env``)."""
    code = f"from smac_hard_gym.bench import _probe_main; _probe_main({map_name!r}, {int(num_envs)}, {opponent!r})"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                         preexec_fn=_die_with_parent)
    if out.returncode != 0:
        raise RuntimeError(f"memory probe for {map_name} x {num_envs} failed:\n{out.stderr[-2000:]}")
    result = json.loads(out.stdout.strip().splitlines()[-1])
    result.update(map=map_name, num_envs=int(num_envs), opponent=opponent)
    return result


# ---------------------------------------------------------------------------------------------------------------
# Where the time goes.


class _Splits:
    """Wall time accumulated per component by wrapping callables in place (restored by ``restore``)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._undo: list[tuple[Any, str, Any]] = []

    def wrap(self, owner: Any, attr: str, label: str) -> None:
        original = getattr(owner, attr)
        seconds = self.seconds
        seconds.setdefault(label, 0.0)

        def timed(*args: Any, **kwargs: Any) -> Any:
            t = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                seconds[label] += time.perf_counter() - t

        self._undo.append((owner, attr, original))
        setattr(owner, attr, timed)

    def restore(self) -> None:
        for owner, attr, original in reversed(self._undo):
            setattr(owner, attr, original)
        self._undo.clear()


# (owner path, attribute, label): the core's collaborators, wrapped where the core looks them up.
_CORE_PARTS = (
    ("backend", "step", "engine step"),
    ("opponent", "act", "opponent script"),
    ("features.0", "observations", "observations"),
    ("features.0", "global_state", "global state"),
    ("core_module", "available_actions", "action masks"),
    ("core_module", "check_actions", "action checks + decoding"),
    ("core_module", "decode_actions", "action checks + decoding"),
    ("core_module", "finish_step", "outcome, rewards, counters"),
)


def _wrap_core(splits: _Splits, core: Any) -> None:
    import smac_hard_gym.core as core_module

    owners = {"backend": core.backend, "opponent": core.opponent, "features.0": core.features[0],
              "core_module": core_module, "core": core}
    for owner, attr, label in _CORE_PARTS:
        if owners[owner] is not None:
            splits.wrap(owners[owner], attr, label)


def _split_table(splits: _Splits, total: float, steps: int, policy_seconds: float) -> dict[str, Any]:
    parts = dict(splits.seconds)
    parts["random policy"] = policy_seconds
    parts["Python overhead (env, core, infos)"] = max(0.0, total - sum(parts.values()))
    return {"total_seconds": total, "steps": steps,
            "us_per_step": {k: 1e6 * v / steps for k, v in parts.items()},
            "share": {k: v / total for k, v in parts.items()}}


def profile_native(map_name: str, num_envs: int, *, opponent: str = "base", seconds: float = 2.0,
                   seed: int = 0) -> dict[str, Any]:
    """Wall-time split of NativeVectorEnv steps (random legal policy, SameStep) between the engine, opponent,
    observations, masks, rewards, action handling, the policy, and the rest (Python overhead)."""
    from smac_hard_gym.vector import NativeVectorEnv

    env = NativeVectorEnv(map_name, num_envs, opponent=opponent, autoreset_mode="SameStep")
    env.reset(seed=seed)
    loop = _VectorLoop(env, env.view.n_agents, env.view.n_actions, seed)
    _warm_up(loop)
    splits = _Splits()
    _wrap_core(splits, env.core)
    policy, policy_time = loop.policy, [0.0]

    def timed_policy(masks: np.ndarray) -> np.ndarray:
        t = time.perf_counter()
        out = policy(masks)
        policy_time[0] += time.perf_counter() - t
        return out

    loop.policy = timed_policy
    steps, t0 = 0, time.perf_counter()
    try:
        while time.perf_counter() - t0 < seconds or steps < 2:
            loop.step()
            steps += 1
    finally:
        total = time.perf_counter() - t0
        splits.restore()
        env.close()
    table = _split_table(splits, total, steps, policy_time[0])
    table.update(what="native", map=map_name, num_envs=num_envs, opponent=opponent,
                 steps_per_second=steps * num_envs / total)
    return table


def profile_starcraft2(map_name: str = "3m", *, opponent: str = "base", seconds: float = 2.0,
                       seed: int = 0) -> dict[str, Any]:
    """The same split for StarCraft2Env's pymarl loop on one battle."""
    from smac_hard_gym.starcraft2 import StarCraft2Env

    env = StarCraft2Env(map_name=map_name, opponent=opponent, seed=seed)
    info = env.get_env_info()
    policy = RandomLegalPolicy(1, info["n_agents"], info["n_actions"], seed)
    env.reset()
    splits = _Splits()
    _wrap_core(splits, env._core)
    policy_time, steps, t0 = 0.0, 0, time.perf_counter()
    try:
        while time.perf_counter() - t0 < seconds or steps < 2:
            env.get_state()
            avail = np.asarray(env.get_avail_actions())
            env.get_obs()
            t = time.perf_counter()
            actions = policy(avail[None])[0]
            policy_time += time.perf_counter() - t
            _, terminated, _ = env.step(actions)
            if terminated:
                env.reset()
            steps += 1
    finally:
        total = time.perf_counter() - t0
        splits.restore()
        env.close()
    table = _split_table(splits, total, steps, policy_time)
    table.update(what="starcraft2", map=map_name, num_envs=1, opponent=opponent, steps_per_second=steps / total)
    return table


# ---------------------------------------------------------------------------------------------------------------
# The SMAX peer, in its own Python.


def smax_python(explicit: str | None = None) -> str:
    """The Python that has ``jaxmarl``: ``explicit``, else ``$SMAX_PYTHON``, else ``smax-venv/bin/python`` beside
    the repository (``benchmarks/README.md`` sets that one up). Raises with the setup command when none imports it."""
    candidates = [explicit] if explicit else [os.environ.get("SMAX_PYTHON"),
                                              str(REPO_ROOT.parent / "smax-venv" / "bin" / "python")]
    tried = []
    for path in [c for c in candidates if c]:
        tried.append(path)
        if not Path(path).exists():
            continue
        check = subprocess.run([path, "-c", "import jaxmarl.environments.smax"], capture_output=True, text=True,
                               timeout=300)
        if check.returncode == 0:
            return path
    raise RuntimeError(
        f"--peer smax needs a Python with jaxmarl; tried {tried or ['(none)']}. Set one up with "
        f"`python3 -m venv {REPO_ROOT.parent / 'smax-venv'} && {REPO_ROOT.parent / 'smax-venv'}/bin/pip install "
        "jaxmarl` (see benchmarks/README.md), or pass --peer-python PATH / set SMAX_PYTHON.")


def run_smax(python: str, maps: Sequence[str], num_envs: Sequence[int], *, seconds: float = 1.0, repeats: int = 3,
             modes: Sequence[str] = ("scan", "loop"), seed: int = 0, script: Path = SMAX_SCRIPT,
             timeout: float = 1800.0) -> tuple[list[Measurement], dict]:
    """Run ``benchmarks/smax_bench.py`` under ``python``; its results as Measurements (section ``smax``) and its
    machine record (jax and jaxmarl versions)."""
    if not Path(script).exists():
        raise RuntimeError(f"the SMAX script {script} is missing (it lives in the repository's benchmarks/)")
    with tempfile.TemporaryDirectory() as tmp:
        out_path = Path(tmp) / "smax.json"
        cmd = [python, str(script), "--maps", ",".join(maps), "--num-envs", ",".join(map(str, num_envs)),
               "--modes", ",".join(modes), "--seconds", str(seconds), "--repeats", str(repeats),
               "--seed", str(seed), "--json", str(out_path)]
        try:  # run() kills the child on timeout, so it never outlives this call
            proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, timeout=timeout,
                                  preexec_fn=_die_with_parent)
        except subprocess.TimeoutExpired:
            raise RuntimeError(f"SMAX benchmark ran past {timeout:.0f} s: {' '.join(cmd)}") from None
        if proc.returncode != 0:
            raise RuntimeError(f"SMAX benchmark failed ({' '.join(cmd)}):\n{proc.stderr[-3000:]}")
        doc = json.loads(out_path.read_text())
    results = []
    for r in doc["results"]:
        extra = {k: r[k] for k in ("compile_seconds", "chunk", "episodes", "state_bytes_per_env", "cpu") if k in r}
        results.append(Measurement("smax", r["map"], r["num_envs"], r["steps_per_second"], r["runs"],
                                   opponent="HeuristicEnemySMAX", mode=r["mode"], extra=extra))
    return results, doc["machine"]


# ---------------------------------------------------------------------------------------------------------------
# The suite.


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
    sections: Sequence[str] = SECTIONS
    seconds: float = 1.0
    repeats: int = 3
    seed: int = 0
    peer: str | None = None
    peer_python: str | None = None
    numba_threads: int | None = None  # threads of the engine's parallel kernels in this process (None: numba's)


def _check_config(config: SuiteConfig) -> None:
    from smac_hard_gym.maps import load_map

    for name in (*config.maps, *config.subproc_maps, *(m for m, _ in config.memory), *(m for m, _ in config.profile)):
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
                           "results": results, "cpu_probes": probes, "memory": [], "profiles": [], "peer": None}
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
        who = f"{m.workers}x{m.extra.get('envs_per_worker')}" if m.section == "subproc" else f"N={m.num_envs}"
        who_else = f"SMAX {m.mode}" if m.section == "smax" else m.opponent
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


# ---------------------------------------------------------------------------------------------------------------
# Targets, tables and the figure.


def _rows(doc: dict[str, Any], section: str, **match: Any) -> list[dict[str, Any]]:
    return [r for r in doc["results"] if r["section"] == section and all(r.get(k) == v for k, v in match.items())]


def _best_row(doc: dict[str, Any], section: str, **match: Any) -> dict[str, Any] | None:
    return max(_rows(doc, section, **match), key=lambda r: r["steps_per_second"], default=None)


def must_reach(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """The issue's targets against this document: measured value, threshold, hit, and the configurations used."""
    targets = []
    for name in ("3m", "8m", "27m_vs_30m"):
        ours, smax = _best_row(doc, "native", map=name), _best_row(doc, "smax", map=name, mode="scan")
        if ours and smax:
            a, b = _per_cpu(ours), _per_cpu(smax)
            per_cpu = f"; per CPU-second {a / b:.2f}×" if a and b else ""
            targets.append(_target(f"native best batch >= 5x SMAX best batch, {name}", ours["steps_per_second"]
                                   / smax["steps_per_second"], 5.0, f"ours N={ours['num_envs']} "
                                   f"{ours['steps_per_second']:,.0f} vs SMAX N={smax['num_envs']} "
                                   f"{smax['steps_per_second']:,.0f} steps/s{per_cpu}"))
    sc2, loop = _best_row(doc, "starcraft2", map="3m", opponent="base"), _best_row(doc, "smax", map="3m", mode="loop")
    if sc2 and loop:
        a, b = _per_cpu(sc2), _per_cpu(loop)
        per_cpu = f"; per CPU-second {a / b:.2f}×" if a and b else ""
        targets.append(_target("StarCraft2Env 3m B=1 >= 2x SMAX single-env Python loop", sc2["steps_per_second"]
                               / loop["steps_per_second"], 2.0, f"{sc2['steps_per_second']:,.0f} vs "
                               f"{loop['steps_per_second']:,.0f} steps/s{per_cpu}"))
    scaling = [s for s in _subproc_scaling(doc) if "ratio_2" in s]
    if scaling:
        # "Where the environment dominates": the configuration whose one-worker step takes longest.
        heavy = max(scaling, key=lambda s: s["seconds_per_step_1"])
        rows = {r["workers"]: r for r in _rows(doc, "subproc", map=heavy["map"])
                if r["extra"]["envs_per_worker"] == heavy["k"]}
        targets.append(_target("subprocess 2 workers >= 1.7x 1 worker (env-dominated)", heavy["ratio_2"], 1.7,
                               f"{heavy['map']} K={heavy['k']}: {heavy['sps_1']:,.0f} -> {heavy['sps_2']:,.0f} "
                               f"steps/s; cores lost to others meanwhile {_others(rows.get(1))} / "
                               f"{_others(rows.get(2))}"))
    for probe in doc.get("memory", []):
        if probe["map"] == "3m" and probe["num_envs"] == 4096:
            traced = next((r["peak_bytes_per_env"] for r in _rows(doc, "native", map="3m", num_envs=4096)
                           if r["peak_bytes_per_env"] is not None), None)
            worst = max(probe["rss_bytes_per_env"], traced or 0.0)
            targets.append(_target("peak memory, 3m x 4096 <= 100 KB per battle", worst / 1024, 100.0,
                                   f"RSS growth {probe['rss_bytes_per_env'] / 1024:,.1f} KB, traced peak "
                                   f"{(traced or 0) / 1024:,.1f} KB per battle", lower_is_better=True))
    return targets


def _target(name: str, value: float, threshold: float, detail: str, lower_is_better: bool = False) -> dict:
    hit = value <= threshold if lower_is_better else value >= threshold
    return {"target": name, "value": value, "threshold": threshold, "hit": bool(hit),
            "margin": (threshold / value if lower_is_better else value / threshold) if value else 0.0,
            "detail": detail}


def _subproc_scaling(doc: dict[str, Any]) -> list[dict[str, Any]]:
    out = []
    groups = {(r["map"], r["extra"]["envs_per_worker"]) for r in _rows(doc, "subproc")}
    for name, k in sorted(groups):
        by_w = {r["workers"]: r for r in _rows(doc, "subproc", map=name) if r["extra"]["envs_per_worker"] == k}
        if 1 not in by_w:
            continue
        one = by_w[1]["steps_per_second"]
        row = {"map": name, "k": k, "sps_1": one, "seconds_per_step_1": k / one}
        for w, r in by_w.items():
            row[f"sps_{w}"] = r["steps_per_second"]
            row[f"ratio_{w}"] = r["steps_per_second"] / one
        out.append(row)
    return out


def _fmt(x: float | None) -> str:
    if x is None:
        return "–"
    return f"{x / 1000:,.1f}k" if x >= 10_000 else f"{x:,.0f}"


def _spread(row: dict[str, Any]) -> str:
    runs = row["runs"]
    if len(runs) < 2:
        return ""
    return f" ({_fmt(min(runs))}–{_fmt(max(runs))})"


def _lost(cpu: dict[str, float]) -> float:
    """Cores this benchmark could not have: those other processes used plus those the hypervisor stole."""
    return cpu.get("other_cores", 0.0) + cpu.get("stolen_cores", 0.0)


def _others(row: dict[str, Any] | None) -> str:
    """Cores lost to other processes and the hypervisor while ``row`` was timed (its CpuMeter reading), or a dash."""
    cpu = (row or {}).get("extra", {}).get("cpu") or {}
    return f"{_lost(cpu):.1f}" if "other_cores" in cpu else "–"


def markdown_report(doc: dict[str, Any], command: str = "") -> str:
    """The results document as markdown: machine, tables per section, SMAX ratios, targets, profiles, noise."""
    m = doc["machine"]
    out = ["# smac-hard-gym throughput", ""]
    out.append(f"Machine: {m['cpu']}, {m['cores']} cores, {m.get('memory_gib')} GiB; Python {m['python']}, "
               f"smac-hard-gym {m.get('smac_hard_gym')}, numpy {m['numpy']}, numba {m['numba']} "
               f"({m['numba_threads']} threads, {m.get('numba_threading_layer')}), gymnasium {m.get('gymnasium')}. "
               + (f"Run: {doc['started']} to {m['date']}." if doc.get("started") else f"Run ended {m['date']}."))
    src = doc.get("source") or {}
    if src:
        modified = src.get("git_modified")
        out.append(f"Code: commit {src.get('git_commit', 'unknown')}" + (f" with {len(modified)} modified files"
                   if modified else "") + f", simulator sources digest {src['source_digest']}.")
    for warning in doc.get("warnings", []):
        out.append(f"**Warning: {warning}.**")
    peer = doc.get("peer") or {}
    if peer.get("machine"):
        pm = peer["machine"]
        out.append(f"Peer: SMAX (jaxmarl {pm['jaxmarl']}, jax {pm['jax']} on {', '.join(pm['devices'])}), "
                   "`HeuristicEnemySMAX`, default options, in the same run.")
    cfg = doc["config"]
    out += ["", f"Unit: env steps per second (one step = 8 game loops of one battle; N battles stepped once = N). "
            f"Policy: uniform over legal actions. Resets included (SameStep autoreset). Median of {cfg['repeats']} "
            f"windows of ≥ {cfg['seconds']} s after two warm-up steps; (min–max) of the windows in brackets. "
            "Compile time excluded (see cold start)."]
    if command:
        out += ["", f"Command: `{command}`"]
    out += _noise_lines(doc)
    out += _native_table(doc)
    out += _subproc_table(doc)
    out += _single_env_table(doc)
    out += _opponent_table(doc)
    out += _memory_lines(doc)
    out += _targets_table(doc)
    out += _profile_tables(doc)
    return "\n".join(out) + "\n"


def _noise_lines(doc: dict[str, Any]) -> list[str]:
    probes = [p["seconds"] for p in doc.get("cpu_probes", [])]
    if not probes:
        return []
    load = doc.get("load_average_start")
    readings = [r["extra"]["cpu"] for r in doc["results"] if "other_cores" in r.get("extra", {}).get("cpu", {})]
    others = [c["other_cores"] for c in readings]
    steal = [c.get("stolen_cores", 0.0) for c in readings]
    lost = [_lost(c) for c in readings]
    lines = ["", f"Noise: load average at start {', '.join(f'{x:.1f}' for x in load) if load else 'n/a'}; "
             f"whole run {doc.get('elapsed_seconds', 0) / 60:.1f} min; a single-thread CPU probe took "
             f"{min(probes):.2f}–{max(probes):.2f} s (it finds a free core even when the other one is taken, so it "
             "shows slowdowns of a core, not a lost core)."]
    if others:
        lines[-1] += (f" While figures were timed, other processes used {np.median(others):.1f} cores (median; "
                      f"max {max(others):.1f}) of the {doc['machine']['cores']} and the hypervisor stole up to "
                      f"{max(steal, default=0.0):.2f}; {sum(x >= 0.5 for x in lost)} of {len(lost)} figures lost "
                      "half a core or more. The \"cores lost\" columns give, per figure (ours / SMAX's), the cores "
                      "other processes used plus those the hypervisor stole while it was timed.")
    return lines


def _native_table(doc: dict[str, Any]) -> list[str]:
    rows = _rows(doc, "native")
    if not rows:
        return []
    have_smax = bool(_rows(doc, "smax", mode="scan"))
    head = "| map | N | native vector env | engine alone | peak KB/battle |"
    rule = "|---|---:|---:|---:|---:|"
    if have_smax:
        head += " SMAX (jit+scan) | ours / SMAX |"
        rule += "---:|---:|"
    head += " cores lost |"
    rule += "---:|"
    out = ["", f"## Native vector env through the gymnasium API (opponent `{doc['config']['opponent']}`)", "",
           head, rule]
    for r in rows:
        eng = next((e for e in _rows(doc, "engine", map=r["map"], num_envs=r["num_envs"])), None)
        kb = "–" if r["peak_bytes_per_env"] is None else f"{r['peak_bytes_per_env'] / 1024:,.1f}"
        line = (f"| {r['map']} | {r['num_envs']} | {_fmt(r['steps_per_second'])}{_spread(r)} | "
                f"{_fmt(eng['steps_per_second']) if eng else '–'} | {kb} |")
        s = next(iter(_rows(doc, "smax", mode="scan", map=r["map"], num_envs=r["num_envs"])), None)
        if have_smax:
            ratio = f"{r['steps_per_second'] / s['steps_per_second']:.2f}×" if s else "–"
            line += f" {_fmt(s['steps_per_second'])}{_spread(s)} | {ratio} |" if s else " – | – |"
        line += f" {_others(r)}{' / ' + _others(s) if s else ''} |"
        out.append(line)
    if have_smax:
        out += ["", "Best batch per map (the must-reach comparison), also per CPU-second: steps/s divided by the cores "
                "each process actually got while timed (on a shared machine the two rarely get the same):", "",
                "| map | ours (N) | SMAX (N) | ratio | ours per CPU-s | SMAX per CPU-s | ratio per CPU-s |",
                "|---|---:|---:|---:|---:|---:|---:|"]
        for name in dict.fromkeys(r["map"] for r in rows):
            ours, smax = _best_row(doc, "native", map=name), _best_row(doc, "smax", map=name, mode="scan")
            if ours and smax:
                a, b = _per_cpu(ours), _per_cpu(smax)
                out.append(f"| {name} | {_fmt(ours['steps_per_second'])} ({ours['num_envs']}) | "
                           f"{_fmt(smax['steps_per_second'])} ({smax['num_envs']}) | "
                           f"{ours['steps_per_second'] / smax['steps_per_second']:.2f}× | {_fmt(a)} | {_fmt(b)} | "
                           + (f"{a / b:.2f}× |" if a and b else "– |"))
    return out


def _per_cpu(row: dict[str, Any] | None) -> float | None:
    """Env steps per CPU-second of the measuring process(es): steps/s over the cores they used while timed."""
    cores = ((row or {}).get("extra", {}).get("cpu") or {}).get("our_cores")
    return row["steps_per_second"] / cores if cores else None


def _subproc_table(doc: dict[str, Any]) -> list[str]:
    scaling = _subproc_scaling(doc)
    if not scaling:
        return []
    workers = sorted({r["workers"] for r in _rows(doc, "subproc")})
    out = ["", "## Subprocess vector env (workers × K battles each, one numba thread per worker)", "",
           "| map | K | " + " | ".join(f"{w} worker{'s' if w > 1 else ''}" for w in workers) + " | "
           + " | ".join(f"{w}w / 1w" for w in workers if w > 1) + " |",
           "|---|---:|" + "---:|" * (2 * len(workers) - 1)]
    out[-2] += " cores lost |"
    out[-1] += "---:|"
    for s in scaling:
        rows = {r["workers"]: r for r in _rows(doc, "subproc", map=s["map"]) if r["extra"]["envs_per_worker"] == s["k"]}
        out.append(f"| {s['map']} | {s['k']} | " + " | ".join(_fmt(s.get(f"sps_{w}")) for w in workers) + " | "
                   + " | ".join(f"{s[f'ratio_{w}']:.2f}×" if f"ratio_{w}" in s else "–" for w in workers if w > 1)
                   + " | " + " / ".join(_others(rows.get(w)) for w in workers) + " |")
    out += ["", "Speed-up needs free cores: the last column gives the cores lost to other processes and the "
            "hypervisor while each worker count was timed (1 / 2 / 4 workers)."]
    return out


def _single_env_table(doc: dict[str, Any]) -> list[str]:
    rows = _rows(doc, "starcraft2")
    if not rows:
        return []
    out = ["", "## One battle: `StarCraft2Env` on 3m in pymarl's loop (get_state, get_avail_actions, get_obs, step)",
           "", "| env | opponent | steps/s | episodes/s | cores lost |", "|---|---|---:|---:|---:|"]
    for r in rows:
        out.append(f"| StarCraft2Env | {r['opponent']} | {_fmt(r['steps_per_second'])}{_spread(r)} | "
                   f"{r['episodes_per_second']:,.1f} | {_others(r)} |")
    labels = {"loop": "SMAX, Python loop over one jitted step (results stay in jax)",
              "pymarl": "SMAX, pymarl-style loop (obs, state, masks to numpy each step)"}
    for mode, label in labels.items():
        smax = _best_row(doc, "smax", map="3m", mode=mode)
        if smax:
            out.append(f"| {label} | HeuristicEnemySMAX | {_fmt(smax['steps_per_second'])}{_spread(smax)} | – | "
                       f"{_others(smax)} |")
    loop, ours = _best_row(doc, "smax", map="3m", mode="loop"), _best_row(doc, "starcraft2", opponent="base")
    if loop and ours:
        ratio = ours["steps_per_second"] / loop["steps_per_second"]
        out += ["", f"StarCraft2Env (base) / SMAX Python loop: {ratio:.2f}× (the must-reach comparison uses SMAX's "
                "faster loop)."]
    return out


def _opponent_table(doc: dict[str, Any]) -> list[str]:
    rows = _rows(doc, "opponents")
    if not rows:
        return []
    n = rows[0]["num_envs"]
    out = ["", f"## Opponent cost: `base` vs the `default` mixture (N={n})", "",
           "| map | base | default | default / base |", "|---|---:|---:|---:|"]
    for name in dict.fromkeys(r["map"] for r in rows):
        base = next(iter(_rows(doc, "opponents", map=name, opponent="base")), None)
        mix = next(iter(_rows(doc, "opponents", map=name, opponent="default")), None)
        if base and mix:
            out.append(f"| {name} | {_fmt(base['steps_per_second'])} | {_fmt(mix['steps_per_second'])} | "
                       f"{mix['steps_per_second'] / base['steps_per_second']:.2f}× |")
    return out


def _memory_lines(doc: dict[str, Any]) -> list[str]:
    probes = doc.get("memory", [])
    if not probes:
        return []
    out = ["", "## Cold start and memory (fresh process)", "",
           "| map × N | import s | first step s | peak RSS growth per battle |", "|---|---:|---:|---:|"]
    for p in probes:
        out.append(f"| {p['map']} × {p['num_envs']} | {p['import_seconds']:.1f} | {p['cold_start_seconds']:.1f} | "
                   f"{p['rss_bytes_per_env'] / 1024:,.1f} KB |")
    out += ["", "First step = import + building one env + its first step (numba's on-disk cache loaded, or compiled "
            "on a cold cache). Peak RSS growth: VmHWM after building N battles and 5 steps, minus RSS with a "
            "warmed one-battle env. The native table's KB/battle is tracemalloc's peak over build, reset and two "
            "steps."]
    return out


def _targets_table(doc: dict[str, Any]) -> list[str]:
    targets = doc.get("must_reach") or []
    if not targets:
        return []
    out = ["", "## Must-reach targets", "", "| target | measured | needed | result | detail |",
           "|---|---:|---:|---|---|"]
    for t in targets:
        unit = " KB" if "memory" in t["target"] else "×"
        verdict = "hit" if t["hit"] else "miss"
        how = f"{t['margin']:.2f}× the target" if t["hit"] else f"{t['margin']:.0%} of the target"
        out.append(f"| {t['target']} | {t['value']:,.2f}{unit} | {t['threshold']:g}{unit} | {verdict} ({how}) | "
                   f"{t['detail']} |")
    return out


def _profile_tables(doc: dict[str, Any]) -> list[str]:
    profiles = doc.get("profiles") or []
    if not profiles:
        return []
    labels = list(dict.fromkeys(k for p in profiles for k in p["share"]))
    cols = [f"{p['what']} {p['map']} N={p['num_envs']}" for p in profiles]
    out = ["", "## Where a step's time goes (wall-time share; µs per vector step in brackets)", "",
           "| part | " + " | ".join(cols) + " |", "|---|" + "---:|" * len(cols)]
    for label in labels:
        cells = []
        for p in profiles:
            share, us = p["share"].get(label), p["us_per_step"].get(label)
            cells.append("–" if share is None else f"{share:.0%} ({us:,.0f})")
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    out.append("| steps/s while profiled | " + " | ".join(_fmt(p["steps_per_second"]) for p in profiles) + " |")
    out += ["", "The overhead row is everything not in a named part (env and core bookkeeping in Python, infos, "
            "autoreset)."]
    return out


def plot_report(doc: dict[str, Any], path: str | os.PathLike) -> bool:
    """A PNG: steps/s against N per map (ours solid, SMAX dashed) and subprocess scaling, each when measured.
    False without matplotlib (an optional dependency: the ``[dev]`` and ``[render]`` extras) or with nothing to
    draw."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    panels = [draw for draw, rows in ((_plot_native, _rows(doc, "native")), (_plot_scaling, _subproc_scaling(doc)))
              if rows]
    if not panels:
        return False
    fig, axes = plt.subplots(1, len(panels), figsize=(6.5 * len(panels) + 0.5, 5), squeeze=False)
    for draw, ax in zip(panels, axes[0], strict=True):
        draw(doc, ax, plt.rcParams["axes.prop_cycle"].by_key()["color"])
    m = doc["machine"]
    fig.suptitle(f"smac-hard-gym {m.get('smac_hard_gym')} on {m['cpu']} ({m['cores']} cores), {m['date']}",
                 fontsize=9)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _plot_native(doc: dict[str, Any], ax: Any, colours: list[str]) -> None:
    for i, name in enumerate(dict.fromkeys(r["map"] for r in _rows(doc, "native"))):
        colour = colours[i % len(colours)]
        rows = sorted(_rows(doc, "native", map=name), key=lambda r: r["num_envs"])
        ax.plot([r["num_envs"] for r in rows], [r["steps_per_second"] for r in rows], "o-", color=colour, label=name)
        smax = sorted(_rows(doc, "smax", map=name, mode="scan"), key=lambda r: r["num_envs"])
        if smax:
            ax.plot([r["num_envs"] for r in smax], [r["steps_per_second"] for r in smax], "s--", color=colour,
                    alpha=0.6, label=f"{name} SMAX")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("battles stepped together (num_envs)")
    ax.set_ylabel("env steps / s")
    ax.set_title("NativeVectorEnv (solid) vs SMAX jit+scan (dashed)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)


def _plot_scaling(doc: dict[str, Any], ax: Any, colours: list[str]) -> None:
    workers = sorted({r["workers"] for r in _rows(doc, "subproc")})
    for i, s in enumerate(_subproc_scaling(doc)):
        ws = [w for w in workers if f"ratio_{w}" in s]
        ax.plot(ws, [s[f"ratio_{w}"] for w in ws], "o-", color=colours[i % len(colours)],
                label=f"{s['map']}, K={s['k']} per worker")
    cores = doc["machine"]["cores"] or 1
    ax.plot(workers, [min(w, cores) for w in workers], ":", color="grey", label=f"ideal on {cores} cores")
    ax.axhline(1.7, color="red", lw=0.8, ls="--", label="target 1.7x at 2 workers")
    ax.set_xticks(workers)
    ax.set_xlabel("worker processes")
    ax.set_ylabel("env steps/s over one worker")
    ax.set_title("SubprocVectorEnv scaling")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
