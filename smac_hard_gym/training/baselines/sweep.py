"""Running a sweep (:func:`run_sweep`): each run not done yet is trained and then evaluated (black-box, value
estimates) in its own processes, at most ``jobs`` runs at a time, with :func:`~.results.aggregate` after each."""

from __future__ import annotations

import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from smac_hard_gym.files import write_json
from smac_hard_gym.training.baselines.planning import (
    Run,
    SweepConfig,
    blackbox_command,
    plan,
    resume_command,
    run_state,
    train_command,
    value_command,
)
from smac_hard_gym.training.baselines.results import MalformedFile, aggregate, recorded_runs

__all__ = ["run_sweep", "sweep_states"]

# What a run's state means for the sweep (``run_state``, plus ``recorded``: listed in results.json, no folder).
STATE_NAMES = {"done": "done", "recorded": "recorded in results.json (no folder)",
               "resumable": "cut short with a checkpoint (resumed)", "partial": "partial (redone)", "todo": "to do"}


def _start(command: list[str], log: Path) -> subprocess.Popen:
    from smac_hard_gym.lifetime import die_with_parent_hook

    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("a") as handle:  # the child keeps its own copy; a resumed run's log goes on after its first part
        return subprocess.Popen(command, stdout=handle, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                preexec_fn=die_with_parent_hook())


Step = tuple[list[str], Path]  # a command and the log it writes


def _run_all(jobs: Sequence[tuple[str, Sequence[Step]]], parallel: int, bar: Any, describe: Callable[[str], str],
             on_done: Callable[[str], None] = lambda key: None) -> list[str]:
    """Run ``(key, steps)`` jobs, at most ``parallel`` at a time, each job's steps one after another (a step starts
    when the one before it succeeded), from this (the main) thread so that ``die_with_parent_hook`` holds;
    ``on_done(key)`` is called as each job ends, failed or not. Returns the keys of the jobs that failed."""
    pending = [(key, list(steps)) for key, steps in jobs]
    running: dict[str, tuple[subprocess.Popen, list[Step]]] = {}
    failed: list[str] = []
    try:
        while pending or running:
            while pending and len(running) < parallel:
                key, steps = pending.pop(0)
                command, log = steps.pop(0)
                running[key] = (_start(command, log), steps)
                if bar is not None:
                    bar.set_postfix_str(describe(key), refresh=True)
            time.sleep(0.2)
            for key, (proc, steps) in list(running.items()):
                if proc.poll() is None:
                    continue
                if proc.returncode == 0 and steps:
                    command, log = steps.pop(0)
                    running[key] = (_start(command, log), steps)
                    continue
                del running[key]
                if proc.returncode != 0:
                    failed.append(key)
                if bar is not None:
                    bar.update(1)
                on_done(key)
    finally:
        for proc, _ in running.values():  # interrupted: our children go with us
            proc.kill()
            proc.wait()
    return failed


def _evaluations(run: Run, config: SweepConfig) -> list[Step]:
    """The evaluations a trained run still lacks: black-box for a ``smac`` model, the value estimate for the mixing
    experiment."""
    path = run.path(config.out)
    steps: list[Step] = []
    if config.blackbox and run.opponent == "smac" and not (path / "blackbox.json").is_file():
        steps.append((blackbox_command(run, config), path / "eval.log"))
    if config.values and not (path / "value.json").is_file():
        steps.append((value_command(run, config), path / "value.log"))
    return steps


def sweep_states(config: SweepConfig) -> dict[Run, str]:
    """Each planned run's state: :func:`~.planning.run_state` of its folder, or ``"recorded"`` for a run without one
    that ``results.json`` lists (:func:`~.results.recorded_runs`): done, as far as the sweep is concerned."""
    recorded = recorded_runs(config.out)
    states = {}
    for run in plan(config):
        state = run_state(run.path(config.out), config.timesteps)
        states[run] = "recorded" if state == "todo" and run.label in recorded else state
    return states


def describe_states(states: dict[Run, str]) -> str:
    """``done 3, recorded ... 2, ...``: how many runs are in each state, in a fixed order."""
    counts = list(states.values())
    return ", ".join(f"{name} {counts.count(state)}" for state, name in STATE_NAMES.items())


def run_sweep(config: SweepConfig, *, progress: bool = True, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Train the runs not done yet, each followed at once by its evaluations (black-box for the ``smac`` models, the
    mixing experiment's values), and return :func:`aggregate`'s results. ``results.json`` and the tables are
    rewritten as each run ends, so a sweep cut short (or its machine lost) keeps every finished run's figures."""
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    states = sweep_states(config)
    runs = list(states)
    log(f"{len(runs)} runs: {describe_states(states)}")
    jobs: list[tuple[str, list[Step]]] = []
    for run in runs:
        path = run.path(out)
        if states[run] == "recorded":
            continue
        if states[run] == "partial":
            shutil.rmtree(path)
        command = resume_command(run, config) if states[run] == "resumable" else train_command(run, config)
        train = [] if states[run] == "done" else [(command, path / "train.log")]
        steps = train + _evaluations(run, config)
        if steps:
            jobs.append((run.label, steps))
    by_label = {run.label: run for run in runs}

    def describe(label: str) -> str:
        run = by_label[label]
        return f"{run.map_name} vs {run.opponent} seed {run.seed}"

    def refresh(label: str) -> None:
        try:
            aggregate(out, config)
        except MalformedFile as err:  # reported again by the final aggregation; the sweep goes on
            log(f"results not refreshed after {label}: {err}")

    bar = _bar(len(runs), len(runs) - len(jobs), "runs", progress)
    try:
        failed = _run_all(jobs, config.jobs, bar, describe, on_done=refresh)
    finally:
        if bar is not None:
            bar.close()
    results = aggregate(out, config)
    results["failed"] = sorted(set(failed))
    write_json(out / "results.json", results)
    for label in results["failed"]:
        log(f"failed: {label} (see {by_label[label].path(out)}/*.log)")
    return results


def _bar(total: int, initial: int, desc: str, progress: bool) -> Any:
    if not progress or total == 0:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="run", desc=desc, dynamic_ncols=True,
                mininterval=0.5 if sys.stderr.isatty() else 30.0)
