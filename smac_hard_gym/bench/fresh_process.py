"""Cold start and peak memory, measured in a fresh Python process so that nothing is loaded or cached in advance."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from typing import Any

from smac_hard_gym.bench.machine import peak_rss_of
from smac_hard_gym.bench.policy import VectorLoop
from smac_hard_gym.lifetime import die_with_parent


def _rss_now() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise OSError("no VmRSS in /proc/self/status")


def probe_main(map_name: str, num_envs: int, opponent: str) -> None:
    """Runs in a fresh process (``python -c``): cold start, then peak RSS growth of a NativeVectorEnv of
    ``num_envs`` battles over the same process with a warmed one-battle env; prints JSON."""
    t0 = time.perf_counter()
    from smac_hard_gym.envs.vector import NativeVectorEnv

    t_import = time.perf_counter() - t0
    small = NativeVectorEnv(map_name, 1, opponent=opponent, autoreset_mode="SameStep")
    small.reset(seed=0)
    loop = VectorLoop(small, small.view.n_agents, small.view.n_actions, 0)
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
    loop = VectorLoop(env, env.view.n_agents, env.view.n_actions, 0)
    for _ in range(5):
        loop.step()
    peak = peak_rss_of(os.getpid()) or _rss_now()
    print(json.dumps({"import_seconds": t_import, "cold_start_seconds": t_first, "baseline_rss": baseline,
                      "peak_rss": peak, "peak_reset": reset_peak,
                      "rss_bytes_per_env": (peak - baseline) / num_envs}))


def cold_start(map_name: str = "3m", num_envs: int = 4096, opponent: str = "base",
               timeout: float = 600.0) -> dict[str, Any]:
    """A fresh process: seconds to import and to make the first step (numba's disk cache load, or its compile on
    a cold cache), and peak RSS growth per battle of ``num_envs`` battles (``rss_bytes_per_env``)."""
    code = f"from {__name__} import probe_main; probe_main({map_name!r}, {int(num_envs)}, {opponent!r})"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                         preexec_fn=die_with_parent)
    if out.returncode != 0:
        raise RuntimeError(f"memory probe for {map_name} x {num_envs} failed:\n{out.stderr[-2000:]}")
    result = json.loads(out.stdout.strip().splitlines()[-1])
    result.update(map=map_name, num_envs=int(num_envs), opponent=opponent)
    return result
