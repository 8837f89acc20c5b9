"""The compiled kernels mean what their Python source says: with numba's JIT off (``NUMBA_DISABLE_JIT=1``), every
kernel runs as plain Python and the recorded episodes must come out bit for bit the same.

A small map (3m) through three APIs, then maps whose mechanics the small one lacks: heals and a medivac (MMM),
shields (2s3z). Plain Python is about a hundred times slower, so the runs are short ones of the corpus.
"""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _check_without_jit(maps: list[str], apis: list[str]) -> str:
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1", "PYTHONWARNINGS": "ignore"}
    run = subprocess.run([sys.executable, "-m", "tests.equivalence_corpus", "--maps", *maps, "--apis", *apis],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    return run.stdout.strip().splitlines()[-1]


def test_small_map_every_in_process_api_without_jit():
    assert _check_without_jit(["3m"], ["single", "smac", "native"]) == "identical"


def test_heals_and_shields_without_jit():
    assert _check_without_jit(["MMM", "2s3z"], ["single"]) == "identical"
