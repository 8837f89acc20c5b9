"""Baseline sweeps (``smac-hard-gym baselines``): the SMAC-HARD paper's experiments on this engine with MaskablePPO.

A sweep trains one MaskablePPO run per (map, opponent, seed), each in its own process (``smac-hard-gym train``, so
memory stays flat over a night of runs), evaluates each model trained against ``smac`` as soon as it is trained
against each script of its map's ``blackbox`` pool (the paper's black-box evaluation, section 6.2), and aggregates
everything under ``out`` as each run ends:

- ``runs/<map>-<opponent>-s<seed>/``: each run's ``train`` files, ``train.log``, and for ``smac`` runs
  ``blackbox.json`` and ``eval.log``;
- ``results.json``: the sweep's settings, every run's final test win rate, and per map and opponent the mean,
  standard deviation (over seeds, ``ddof=0``), minimum and maximum; the black-box rows per script; the ``default``
  runs' final test win rate per script of the pool; the value estimates of the mixing experiment;
- ``results.csv``, ``blackbox.csv`` and ``pool.csv``: the same tables flat; ``curves/<map>.png``: test win rate
  against env steps, mean over seeds with a min-max band, one line per opponent.

The sweep is resumable: a run whose ``summary.json`` exists (and was not interrupted) is skipped, any other run
directory is cleared and the run redone. It can also be carried on elsewhere: every run's row in ``results.json``
holds its final figures, black-box rates and learning curve, so a run that ``results.json`` lists and whose folder
is gone (a published sweep keeps no models; a machine was lost) is *recorded*: done, kept in the tables and curves
beside the runs with folders (:func:`~.results.recorded_runs`). To train such a run again, delete its row.
:func:`~.report.write_report` writes a markdown table from ``results.json`` next to the paper's QMIX and MAPPO
columns (:data:`~.paper.PAPER`), without training.

``experiment="mixing"`` is the paper's section 4.2 on 10m_vs_11m: ``nearest``, ``weakest`` and their 50/50
mixture, and at the end of each run the critic's value of the first observation of test episodes, averaged
(:func:`~.values.value_estimate`); the paper reports the mixture gives the most conservative values.

Modules, one job each: :mod:`.paper` (the paper's numbers), :mod:`.planning` (settings, runs, job command lines),
:mod:`.sweep` (running the jobs), :mod:`.values` (the value estimate), :mod:`.results` (results from run folders),
:mod:`.claims` (the paper's claims checked), :mod:`.report` (the markdown report).
"""

from __future__ import annotations

from smac_hard_gym.training.baselines.claims import findings, spearman
from smac_hard_gym.training.baselines.paper import PAPER, SOURCES
from smac_hard_gym.training.baselines.planning import EXPERIMENTS, Run, SweepConfig, plan, run_state
from smac_hard_gym.training.baselines.report import report_markdown, training_time, write_report
from smac_hard_gym.training.baselines.results import MalformedFile, aggregate, mean_curve, spread
from smac_hard_gym.training.baselines.sweep import run_sweep
from smac_hard_gym.training.baselines.values import value_estimate, value_main

__all__ = ["SweepConfig", "Run", "PAPER", "SOURCES", "plan", "run_state", "run_sweep", "aggregate", "write_report",
           "report_markdown", "value_estimate", "value_main", "EXPERIMENTS", "findings", "spearman", "mean_curve",
           "spread", "training_time", "MalformedFile"]
