"""The SMAX peer (JaxMARL), run by ``benchmarks/smax_bench.py`` in its own Python."""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

from smac_hard_gym.bench.machine import REPO_ROOT
from smac_hard_gym.bench.timing import Measurement
from smac_hard_gym.lifetime import die_with_parent

SMAX_MAPS = ("3m", "8m", "2s3z", "27m_vs_30m")  # the maps of ours that SMAX also has
SMAX_SCRIPT = REPO_ROOT / "benchmarks" / "smax_bench.py"


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
                                  preexec_fn=die_with_parent)
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
