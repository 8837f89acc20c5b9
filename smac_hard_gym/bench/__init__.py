"""Throughput benchmarks: env-steps/s through the public APIs, with the machine, versions and date named.

Units and rules (every figure this package produces follows them):

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

from smac_hard_gym.bench.fresh_process import cold_start
from smac_hard_gym.bench.machine import REPO_ROOT, CpuMeter, cpu_probe, machine_info, source_version
from smac_hard_gym.bench.measure import bench_engine, bench_native, bench_starcraft2, bench_subproc
from smac_hard_gym.bench.plot import plot_report
from smac_hard_gym.bench.policy import RandomLegalPolicy
from smac_hard_gym.bench.profiles import profile_native, profile_starcraft2
from smac_hard_gym.bench.report import markdown_report
from smac_hard_gym.bench.smax import SMAX_MAPS, SMAX_SCRIPT, run_smax, smax_python
from smac_hard_gym.bench.suite import (
    DEFAULT_ENVS_PER_WORKER,
    DEFAULT_MAPS,
    DEFAULT_NUM_ENVS,
    DEFAULT_RAY_ACTORS,
    DEFAULT_RAY_MAPS,
    DEFAULT_SECTIONS,
    DEFAULT_SUBPROC_MAPS,
    DEFAULT_WORKERS,
    OPPONENTS,
    SECTIONS,
    SuiteConfig,
    run_suite,
)
from smac_hard_gym.bench.targets import must_reach
from smac_hard_gym.bench.timing import Measurement, timed_repeats, write_json

__all__ = [
    "DEFAULT_MAPS", "DEFAULT_NUM_ENVS", "SECTIONS", "SMAX_MAPS", "Measurement", "RandomLegalPolicy", "SuiteConfig",
    "CpuMeter", "bench_engine", "bench_native", "bench_starcraft2", "bench_subproc", "cold_start", "cpu_probe",
    "machine_info", "markdown_report", "must_reach", "plot_report", "profile_native", "profile_starcraft2",
    "run_smax", "run_suite", "smax_python", "source_version", "timed_repeats", "write_json",
    # The CLI's defaults and the paths the suite uses.
    "DEFAULT_ENVS_PER_WORKER", "DEFAULT_SUBPROC_MAPS", "DEFAULT_SECTIONS", "DEFAULT_RAY_MAPS", "DEFAULT_RAY_ACTORS",
    "DEFAULT_WORKERS", "OPPONENTS", "REPO_ROOT", "SMAX_SCRIPT",
]
