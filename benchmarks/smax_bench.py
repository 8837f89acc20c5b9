"""SMAX (JaxMARL) throughput with the policy and counting of ``smac-hard-gym bench vector``.

Run it with the Python of a separate environment that has ``jaxmarl`` (see ``benchmarks/README.md``); it does not
import smac-hard-gym (it loads ``smac_hard_gym/bench/arguments.py``, which needs only the standard library, by path), so
``smac-hard-gym bench vector --peer smax`` can call it as a subprocess and merge its JSON (written to ``--json`` or,
without it, printed as the last line of stdout).

What is measured, per map and batch size N (``HeuristicEnemySMAX``, SMAX's built-in enemy, default options):

- ``scan``: N envs vmapped, ``lax.scan`` over a chunk of steps inside one ``jit`` (SMAX at its fastest: no Python
  per step). Each step samples uniformly among the allies' available actions, then calls the public
  ``env.step``, which auto-resets finished episodes.
- ``loop`` (N = 1 only): a Python ``for`` loop calling one jitted function per step (sample + ``env.step``);
  results stay on the device. The fastest way to drive one SMAX env from Python.
- ``pymarl`` (N = 1 only): the loop of a pymarl-style runner: each step brings the observations, global state and
  available actions to the host as numpy arrays, samples the actions there with numpy, and calls one jitted
  ``env.step`` (+ ``get_avail_actions``).

An env step is one joint step of one env (8 world ticks); N envs stepped once count N. Compile time is measured
apart (the first two calls) and excluded; the figure is the median of the timed repeats.

    ../smax-venv/bin/python benchmarks/smax_bench.py --maps 3m,8m --num-envs 1,256 --seconds 1
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

MODES = ("scan", "loop", "pymarl")
DEFAULT_CACHE = os.path.join(os.path.expanduser("~"), ".cache", "smax-bench-jax")
STEPS_PER_CALL = 4096  # env steps one scan chunk aims at (N envs x chunk length), so small N still amortise


def _load_arguments():
    """The benchmark command lines' value types, ``smac_hard_gym/bench/arguments.py``, loaded by its path: this
    script runs in a Python without smac-hard-gym, always from the repository, and parses as ``bench`` does."""
    path = Path(__file__).resolve().parents[1] / "smac_hard_gym" / "bench" / "arguments.py"
    spec = importlib.util.spec_from_file_location("smac_hard_gym_bench_arguments", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_arguments = _load_arguments()
comma_ints, comma_names = _arguments.comma_ints, _arguments.comma_names


def _use_compilation_cache(path: str) -> None:
    """Keep compiled graphs on disk, as numba's cache does for our engine: a second run loads instead of compiling
    (compile time is reported apart either way)."""
    import jax

    os.makedirs(path, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)


def machine() -> dict:
    import jax
    import jaxmarl

    return {"python": platform.python_version(), "jax": jax.__version__,
            "jaxmarl": getattr(jaxmarl, "__version__", "unknown"),
            "devices": [str(d) for d in jax.devices()], "cores": os.cpu_count()}


class SmaxRunner:
    """Jitted batched steps of one SMAX scenario with the uniform-over-available-actions policy."""

    def __init__(self, map_name: str) -> None:
        import jax
        import jax.numpy as jnp
        from jaxmarl.environments.smax import HeuristicEnemySMAX, map_name_to_scenario

        self.jax, self.jnp = jax, jnp
        self.env = HeuristicEnemySMAX(scenario=map_name_to_scenario(map_name))
        self.agents = list(self.env.agents)

    def _policy_step(self, key, state):
        """One env step of one env: uniform draw per (agent, action) plus the mask, argmax (never illegal)."""
        jax, jnp = self.jax, self.jnp
        k_act, k_step = jax.random.split(key)
        avail = self.env.get_avail_actions(state)
        masks = jnp.stack([avail[a] for a in self.agents])
        draws = jax.random.uniform(k_act, masks.shape)
        choice = jnp.argmax(draws + masks, axis=-1)
        actions = {a: choice[i] for i, a in enumerate(self.agents)}
        _, state, _, dones, _ = self.env.step(k_step, state, actions)
        return state, dones["__all__"]

    def batch_reset(self, key, n: int):
        keys = self.jax.random.split(key, n)
        _, states = self.jax.vmap(self.env.reset)(keys)
        return states

    def scan_fn(self, n: int, length: int):
        """jit(carry -> carry): ``length`` steps of N vmapped envs; counts finished episodes."""
        jax = self.jax
        vstep = jax.vmap(self._policy_step)

        def body(carry, _):
            key, states, episodes = carry
            key, sub = jax.random.split(key)
            states, done = vstep(jax.random.split(sub, n), states)
            return (key, states, episodes + done.sum()), None

        def run(carry):
            return jax.lax.scan(body, carry, None, length=length)[0]

        return jax.jit(run)

    def loop_fn(self):
        jax = self.jax

        def one(key, state):
            key, sub = jax.random.split(key)
            state, done = self._policy_step(sub, state)
            return key, state, done

        return jax.jit(one)


    def pymarl_fn(self):
        jax, jnp = self.jax, self.jnp

        def one(key, state, choice):
            key, sub = jax.random.split(key)
            actions = {a: choice[i] for i, a in enumerate(self.agents)}
            obs, state, _, dones, _ = self.env.step(sub, state, actions)
            avail = self.env.get_avail_actions(state)
            agent_obs = jnp.stack([obs[a] for a in self.agents])
            masks = jnp.stack([avail[a] for a in self.agents])
            return key, state, agent_obs, obs["world_state"], masks, dones["__all__"]

        return jax.jit(one)


def _block(tree) -> None:
    import jax

    for leaf in jax.tree_util.tree_leaves(tree):
        leaf.block_until_ready()


def _warm_up(call) -> float:
    """Seconds of the first two calls: the first compiles; the second may retrace once when the carried state's
    dtypes settle (weak types after reset). Neither is timed as throughput."""
    t0 = time.perf_counter()
    call()
    call()
    return time.perf_counter() - t0


def _cpu_now() -> tuple[float, float, float]:
    """(wall, busy CPU seconds of the machine from /proc/stat, this process's CPU seconds)."""
    busy = 0.0
    try:
        with open("/proc/stat") as f:
            fields = [int(v) for v in f.readline().split()[1:]]
        user, nice, system, _idle, _iowait, irq, softirq = (fields + [0] * 7)[:7]
        busy = (user + nice + system + irq + softirq) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError):
        pass
    return time.perf_counter(), busy, time.process_time()


def _cpu_since(start: tuple[float, float, float]) -> dict:
    """Cores in use since ``start``: the machine's, this process's, and everyone else's (the noise)."""
    t1, busy1, ours1 = _cpu_now()
    wall = max(t1 - start[0], 1e-9)
    busy, ours = (busy1 - start[1]) / wall, (ours1 - start[2]) / wall
    return {"busy_cores": round(busy, 2), "our_cores": round(ours, 2), "other_cores": round(max(0.0, busy - ours), 2)}


def _timed_repeats(call, steps_per_call: int, seconds: float, repeats: int) -> tuple[list[float], dict]:
    """Run ``call`` (which blocks) until ``seconds`` pass, ``repeats`` times; env-steps/s of each repeat and the
    cores in use meanwhile."""
    runs, start = [], _cpu_now()
    for _ in range(repeats):
        calls, t0 = 0, time.perf_counter()
        while True:
            call()
            calls += 1
            elapsed = time.perf_counter() - t0
            if elapsed >= seconds:
                break
        runs.append(calls * steps_per_call / elapsed)
    return runs, _cpu_since(start)


def bench_scan(runner: SmaxRunner, map_name: str, n: int, seconds: float, repeats: int, seed: int) -> dict:
    jax = runner.jax
    length = max(1, STEPS_PER_CALL // n)
    fn = runner.scan_fn(n, length)
    episodes = runner.jnp.zeros((), runner.jnp.int32)
    carry = [(jax.random.PRNGKey(seed + 1), runner.batch_reset(jax.random.PRNGKey(seed), n), episodes)]

    def call():
        carry[0] = fn(carry[0])
        _block(carry[0])

    compile_s = _warm_up(call)
    runs, cpu = _timed_repeats(call, n * length, seconds, repeats)
    state_bytes = sum(leaf.nbytes for leaf in jax.tree_util.tree_leaves(carry[0][1]))
    return {"engine": "smax", "mode": "scan", "map": map_name, "num_envs": n, "chunk": length,
            "steps_per_second": statistics.median(runs), "runs": runs, "compile_seconds": compile_s,
            "episodes": int(carry[0][2]), "state_bytes_per_env": state_bytes / n, "cpu": cpu}


def bench_loop(runner: SmaxRunner, map_name: str, seconds: float, repeats: int, seed: int) -> dict:
    jax = runner.jax
    fn = runner.loop_fn()
    _, state0 = runner.env.reset(jax.random.PRNGKey(seed))
    holder = [jax.random.PRNGKey(seed + 1), state0]

    def call():
        # A Python loop of single steps; block once per call of 64 steps, as a user reading a result would.
        key, state = holder
        for _ in range(64):
            key, state, done = fn(key, state)
        _block(done)
        holder[0], holder[1] = key, state

    compile_s = _warm_up(call)
    runs, cpu = _timed_repeats(call, 64, seconds, repeats)
    return {"engine": "smax", "mode": "loop", "map": map_name, "num_envs": 1,
            "steps_per_second": statistics.median(runs), "runs": runs, "compile_seconds": compile_s, "cpu": cpu}


def bench_pymarl(runner: SmaxRunner, map_name: str, seconds: float, repeats: int, seed: int) -> dict:
    import numpy as np

    jax = runner.jax
    fn = runner.pymarl_fn()
    _, state0 = runner.env.reset(jax.random.PRNGKey(seed))
    masks0 = np.stack([np.asarray(m) for m in runner.env.get_avail_actions(state0).values()])
    rng = np.random.default_rng(seed)
    holder = [jax.random.PRNGKey(seed + 1), state0, masks0]

    def call():
        key, state, masks = holder
        choice = np.argmax(rng.random(masks.shape, dtype=np.float32) + masks, axis=1)
        key, state, obs, world, avail, done = fn(key, state, choice)
        obs, world, masks = np.asarray(obs), np.asarray(world), np.asarray(avail)  # to the host, as pymarl needs
        bool(done)
        holder[0], holder[1], holder[2] = key, state, masks

    compile_s = _warm_up(call)
    runs, cpu = _timed_repeats(call, 1, seconds, repeats)
    return {"engine": "smax", "mode": "pymarl", "map": map_name, "num_envs": 1,
            "steps_per_second": statistics.median(runs), "runs": runs, "compile_seconds": compile_s, "cpu": cpu}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--maps", type=comma_names, default=["3m"], help="comma-separated SMAX map names")
    parser.add_argument("--num-envs", type=comma_ints, default=[1, 16, 256, 1024, 4096], help="batch sizes")
    parser.add_argument("--modes", type=comma_names, default=list(MODES), help=f"subset of {','.join(MODES)}")
    parser.add_argument("--seconds", type=float, default=1.0, help="seconds per timed repeat")
    parser.add_argument("--repeats", type=int, default=3, help="timed repeats; the median is reported")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", default=None, help="write the results here (default: last line of stdout)")
    parser.add_argument("--cache-dir", default=DEFAULT_CACHE,
                        help=f"jax's persistent compilation cache (default {DEFAULT_CACHE}); '' turns it off")
    args = parser.parse_args(argv)
    bad = [m for m in args.modes if m not in MODES]
    if bad:
        parser.error(f"unknown modes {bad}; choose from {list(MODES)}")
    if args.cache_dir:
        _use_compilation_cache(args.cache_dir)
    from jaxmarl.environments.smax import map_name_to_scenario

    for name in args.maps:
        try:
            map_name_to_scenario(name)
        except (KeyError, ValueError):
            parser.error(f"SMAX has no map {name!r}")
    results = []
    for name in args.maps:
        runner = SmaxRunner(name)
        if "loop" in args.modes:
            results.append(bench_loop(runner, name, args.seconds, args.repeats, args.seed))
            print(f"smax {name:<12} loop  N=1     {results[-1]['steps_per_second']:>12,.0f} steps/s",
                  file=sys.stderr)
        if "pymarl" in args.modes:
            results.append(bench_pymarl(runner, name, args.seconds, args.repeats, args.seed))
            print(f"smax {name:<12} pymarl N=1    {results[-1]['steps_per_second']:>12,.0f} steps/s",
                  file=sys.stderr)
        if "scan" in args.modes:
            for n in args.num_envs:
                results.append(bench_scan(runner, name, n, args.seconds, args.repeats, args.seed))
                r = results[-1]
                print(f"smax {name:<12} scan  N={n:<6}{r['steps_per_second']:>12,.0f} steps/s "
                      f"(compile {r['compile_seconds']:.1f} s)", file=sys.stderr)
    doc = {"benchmark": "smax", "machine": machine(), "results": results}
    text = json.dumps(doc)
    if args.json:
        with open(args.json, "w") as f:
            f.write(text)
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
