"""Running a sweep (:func:`run_sweep`): the runs not done yet, then the black-box evaluations and value estimates,
each job in its own process, at most ``jobs`` at a time; then :func:`~.results.aggregate`."""

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
    SweepConfig,
    blackbox_command,
    plan,
    run_state,
    train_command,
    value_command,
)
from smac_hard_gym.training.baselines.results import aggregate

__all__ = ["run_sweep"]


def _start(command: list[str], log: Path) -> subprocess.Popen:
    from smac_hard_gym.lifetime import die_with_parent_hook

    log.parent.mkdir(parents=True, exist_ok=True)
    with log.open("w") as handle:  # the child keeps its own copy of the descriptor
        return subprocess.Popen(command, stdout=handle, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                preexec_fn=die_with_parent_hook())


def _run_all(jobs: Sequence[tuple[str, list[str], Path]], parallel: int, bar: Any,
             describe: Callable[[str], str]) -> list[str]:
    """Run ``(key, command, log)`` jobs, at most ``parallel`` at a time, from this (the main) thread so that
    ``die_with_parent_hook`` holds; returns the keys of the jobs that failed."""
    pending = list(jobs)
    running: dict[str, subprocess.Popen] = {}
    failed: list[str] = []
    try:
        while pending or running:
            while pending and len(running) < parallel:
                key, command, log = pending.pop(0)
                running[key] = _start(command, log)
                if bar is not None:
                    bar.set_postfix_str(describe(key), refresh=True)
            time.sleep(0.2)
            for key, proc in list(running.items()):
                if proc.poll() is not None:
                    del running[key]
                    if proc.returncode != 0:
                        failed.append(key)
                    if bar is not None:
                        bar.update(1)
    finally:
        for proc in running.values():  # interrupted: our children go with us
            proc.kill()
            proc.wait()
    return failed


def run_sweep(config: SweepConfig, *, progress: bool = True, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Train the runs not done yet, evaluate the ``smac`` models black-box (and the mixing experiment's values),
    aggregate, and return :func:`aggregate`'s results (also written under ``config.out``)."""
    out = Path(config.out)
    out.mkdir(parents=True, exist_ok=True)
    runs = plan(config)
    states = {run: run_state(run.path(out)) for run in runs}
    todo = [run for run in runs if states[run] != "done"]
    log(f"{len(runs)} runs: {len(runs) - len(todo)} done, {sum(s == 'partial' for s in states.values())} partial "
        f"(redone), {sum(s == 'todo' for s in states.values())} to do")
    for run in todo:
        if states[run] == "partial":
            shutil.rmtree(run.path(out))
    by_label = {run.label: run for run in runs}

    def describe(label: str) -> str:
        run = by_label[label]
        return f"{run.map_name} vs {run.opponent} seed {run.seed}"

    failed: list[str] = []
    bar = _bar(len(runs), len(runs) - len(todo), "train", progress)
    try:
        failed += _run_all([(r.label, train_command(r, config), r.path(out) / "train.log") for r in todo],
                           config.jobs, bar, describe)
    finally:
        if bar is not None:
            bar.close()
    finished = [run for run in runs if run_state(run.path(out)) == "done"]
    evals: list[tuple[str, list[str], Path]] = []
    if config.blackbox:
        evals += [(r.label, blackbox_command(r, config), r.path(out) / "eval.log") for r in finished
                  if r.opponent == "smac" and not (r.path(out) / "blackbox.json").is_file()]
    if config.values:
        evals += [(r.label, value_command(r, config), r.path(out) / "value.log") for r in finished
                  if not (r.path(out) / "value.json").is_file()]
    if evals:
        bar = _bar(len(evals), 0, "evaluate", progress)
        try:
            failed += _run_all(evals, config.jobs, bar, describe)
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
