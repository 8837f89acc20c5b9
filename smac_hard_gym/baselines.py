"""Baseline sweeps (``smac-hard-gym baselines``): the SMAC-HARD paper's experiments on this engine with MaskablePPO.

A sweep trains one MaskablePPO run per (map, opponent, seed), each in its own process (``smac-hard-gym train``, so
memory stays flat over a night of runs), then evaluates every model trained against ``smac`` against each script of
its map's ``blackbox`` pool (the paper's black-box evaluation, section 6.2), and aggregates everything under ``out``:

- ``runs/<map>-<opponent>-s<seed>/``: each run's ``train`` files, ``train.log``, and for ``smac`` runs
  ``blackbox.json`` and ``eval.log``;
- ``results.json``: the sweep's settings, every run's final test win rate, and per map and opponent the mean,
  standard deviation (over seeds, ``ddof=0``), minimum and maximum; the black-box rows per script; the ``default``
  runs' final test win rate per script of the pool; the value estimates of the mixing experiment;
- ``results.csv``, ``blackbox.csv`` and ``pool.csv``: the same tables flat; ``curves/<map>.png``: test win rate
  against env steps, mean over seeds with a min-max band, one line per opponent.

The sweep is resumable: a run whose ``summary.json`` exists (and was not interrupted) is skipped, any other run
directory is cleared and the run redone. :func:`write_report` writes a markdown table from ``results.json`` next to
the paper's QMIX and MAPPO columns (:data:`PAPER`), without training.

``experiment="mixing"`` is the paper's section 4.2 on 10m_vs_11m: ``nearest``, ``weakest`` and their 50/50
mixture, and at the end of each run the critic's value of the first observation of test episodes, averaged
(:func:`value_estimate`); the paper reports the mixture gives the most conservative values.
"""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.files import atomic_path, atomic_write, read_json, write_json, write_text
from smac_hard_gym.training import TEST_SEED_BASE

__all__ = ["SweepConfig", "Run", "PAPER", "plan", "run_state", "run_sweep", "aggregate", "write_report",
           "value_estimate", "EXPERIMENTS", "findings", "spearman"]

# The paper's section 4.2: 10m_vs_11m against 'attack the nearest' (N), 'attack the weakest' (W) and the 50/50 mix.
EXPERIMENTS: dict[str, dict[str, Any]] = {
    "mixing": {"maps": ["10m_vs_11m"], "opponents": ["nearest", "weakest", "nearest,weakest"], "blackbox": False,
               "values": True},
}
SWEEP_OPPONENTS = ("smac", "default")
MIXTURE = "mixture"  # the black-box pool's row: the scripts' win rates weighted by the pool

# ---------------------------------------------------------------------------------------------------------------
# The paper's numbers (arXiv 2412.17707, SMAC-HARD; SC2 with pymarl2 QMIX and MAPPO, 5 seeds, 32 test episodes).
# (QMIX, MAPPO) per map, copied from the tables named in SOURCES.

_MAP_ORDER = ("3m", "8m", "5m_vs_6m", "8m_vs_9m", "10m_vs_11m", "25m", "27m_vs_30m", "2s3z", "3s5z", "3s5z_vs_3s6z",
              "1c3s5z", "3s_vs_3z", "3s_vs_4z", "3s_vs_5z", "bane_vs_bane", "so_many_baneling", "2s_vs_1sc",
              "2m_vs_1z", "2c_vs_64zg", "MMM", "MMM2", "6h_vs_8z", "corridor")


def _table(*pairs: tuple[float, float]) -> dict[str, tuple[float, float]]:
    return dict(zip(_MAP_ORDER, pairs, strict=True))


PAPER: dict[str, dict[str, tuple[float, float]]] = {
    # Appendix A, "Final performance at 2M time step with default opponent policy" (SMACv1's opponent).
    "smac_2m": _table(
        (0.9798, 0.9897), (0.9797, 0.9538), (0.544, 0.5103), (0.9137, 0.7821), (0.9515, 0.6859), (0.975, 0.9692),
        (0.4202, 0.6051), (0.9732, 0.941), (0.9485, 0.4512), (0.0256, 0.1128), (0.9893, 0.982), (0.994, 0.982),
        (0.9857, 0.9744), (0.7771, 0.9744), (0.783, 0.9974), (0.9672, 0.9821), (0.9917, 1.0), (0.9926, 1.0),
        (0.9226, 0.9359), (0.9824, 0.9256), (0.7875, 0.4487), (0.1438, 0.0154), (0.0, 0.3077)),
    # Section 6.1, Table "Performance in SMAC-HARD tasks within 10M time steps" (the mixed pool).
    "default_10m": _table(
        (0.9938, 1.0), (0.9628, 0.6438), (0.4375, 0.3138), (0.4938, 0.3528), (0.6813, 0.5681), (0.7813, 0.4562),
        (0.0313, 0.0938), (0.4125, 0.8735), (0.3625, 0.7225), (0.0, 0.1569), (0.9625, 0.5445), (0.9913, 0.9875),
        (0.7938, 0.9875), (0.3438, 0.9407), (0.975, 0.9125), (0.9625, 0.8813), (0.7563, 0.8375), (0.0, 0.0),
        (0.7891, 0.9741), (0.9875, 0.3267), (0.275, 0.1925), (0.0188, 0.0607), (0.3063, 0.1804)),
    # Appendix A, "Final performance at 2M time step with mixed edited opponent policy".
    "default_2m": _table(
        (0.9917, 0.6166), (0.8083, 0.5979), (0.3166, 0.3104), (0.4063, 0.2958), (0.3646, 0.3813), (0.5313, 0.2583),
        (0.0, 0.0125), (0.3438, 0.7042), (0.2312, 0.0667), (0.0, 0.0), (0.4708, 0.5292), (0.8771, 0.9979),
        (0.4437, 0.95), (0.2125, 0.7479), (0.9646, 0.8813), (0.9375, 0.7896), (0.0167, 0.5604), (0.0, 0.0),
        (0.0958, 0.6542), (0.8167, 0.25), (0.0, 0.0), (0.0, 0.0125), (0.0, 0.0)),
    # Section 6.2, Table "Performance in SMAC-HARD tasks in black-box mode" (trained 10M steps on SMACv1).
    "blackbox_10m": _table(
        (0.0117, 0.1028), (0.0375, 0.0513), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0),
        (0.0508, 0.1217), (0.0313, 0.0375), (0.0, 0.0), (0.0703, 0.1027), (0.3359, 0.4125), (0.7461, 0.4467),
        (0.5305, 0.5359), (0.2578, 0.3484), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.6238, 0.3419), (0.0, 0.0),
        (0.0, 0.0), (0.0898, 0.0), (0.0, 0.0)),
}
SOURCES = {
    "smac_2m": "paper, appendix A, table 'Final performance at 2M time step with default opponent policy'",
    "default_10m": "paper, section 6.1, table 'Performance in SMAC-HARD tasks within 10M time steps'",
    "default_2m": "paper, appendix A, table 'Final performance at 2M time step with mixed edited opponent policy'",
    "blackbox_10m": "paper, section 6.2, table 'Performance in SMAC-HARD tasks in black-box mode'",
}

# ---------------------------------------------------------------------------------------------------------------
# Planning.


@dataclass
class SweepConfig:
    """What a sweep trains and evaluates (written to ``results.json``)."""

    maps: list[str] = field(default_factory=list)  # [] means every map
    seeds: int = 3
    timesteps: int = 1_000_000
    out: str = "results"
    opponents: list[str] = field(default_factory=lambda: list(SWEEP_OPPONENTS))
    eval_episodes: int = 32
    num_envs: int = 64
    jobs: int = 1
    experiment: str = ""  # "" (the baseline sweep) or a key of EXPERIMENTS
    train_args: list[str] = field(default_factory=list)  # extra arguments for `smac-hard-gym train`

    def __post_init__(self) -> None:
        from smac_hard_gym.maps import list_maps

        if self.experiment:
            if self.experiment not in EXPERIMENTS:
                raise ValueError(f"unknown experiment {self.experiment!r}; experiments: {', '.join(EXPERIMENTS)}")
            spec = EXPERIMENTS[self.experiment]
            self.maps = list(self.maps or spec["maps"])
            self.opponents = list(spec["opponents"])
        known = list_maps()
        if not self.maps:
            self.maps = list(known)
        unknown = [m for m in self.maps if m not in known]
        if unknown:
            raise ValueError(f"unknown map {unknown[0]!r}; maps: {', '.join(known)}")
        for name in ("seeds", "timesteps", "eval_episodes", "num_envs", "jobs"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive int, got {value!r}")
        if not self.opponents:
            raise ValueError("opponents must name at least one opponent (smac, default, ...)")
        from smac_hard_gym.opponents import make_opponent, opponent_from_text

        for map_name in self.maps:
            for opponent in self.opponents:
                make_opponent(map_name, opponent_from_text(opponent))  # ValueError naming script and map

    @property
    def blackbox(self) -> bool:
        return EXPERIMENTS[self.experiment]["blackbox"] if self.experiment else "smac" in self.opponents

    @property
    def values(self) -> bool:
        return bool(self.experiment and EXPERIMENTS[self.experiment]["values"])


@dataclass(frozen=True)
class Run:
    """One training run of a sweep."""

    map_name: str
    opponent: str
    seed: int

    @property
    def label(self) -> str:
        return f"{self.map_name}-{self.opponent.replace(',', '+')}-s{self.seed}"

    def path(self, out: str | Path) -> Path:
        return Path(out) / "runs" / self.label


def plan(config: SweepConfig) -> list[Run]:
    """Every run of the sweep, map by map, then opponent, then seed (0 .. seeds-1)."""
    return [Run(m, o, s) for m in config.maps for o in config.opponents for s in range(config.seeds)]


def run_state(path: Path) -> str:
    """``"done"`` (``summary.json`` of an uninterrupted run), ``"partial"`` (the directory exists without one) or
    ``"todo"``."""
    summary = path / "summary.json"
    if summary.is_file():
        try:
            data = json.loads(summary.read_bytes().decode("utf-8"))
        except (OSError, ValueError, RecursionError):  # unreadable or malformed: the run is redone
            return "partial"
        if isinstance(data, dict) and data.get("interrupted", False) is False:
            return "done"
        return "partial"
    return "partial" if path.exists() else "todo"


def train_command(run: Run, config: SweepConfig) -> list[str]:
    return [sys.executable, "-m", "smac_hard_gym.cli", "train", "--map", run.map_name, "--opponent", run.opponent,
            "--timesteps", str(config.timesteps), "--num-envs", str(config.num_envs), "--seed", str(run.seed),
            "--eval-episodes", str(config.eval_episodes), "--out", str(run.path(config.out)), "--no-progress",
            *config.train_args]


def blackbox_command(run: Run, config: SweepConfig) -> list[str]:
    path = run.path(config.out)
    return [sys.executable, "-m", "smac_hard_gym.cli", "eval", "--model", str(path / "model.zip"), "--opponent",
            "blackbox", "--episodes", str(config.eval_episodes), "--json", str(path / "blackbox.json")]
    # no --seed: eval's default test battles, the ones train evaluates on (training.TEST_SEED_BASE)


def value_command(run: Run, config: SweepConfig) -> list[str]:
    path = run.path(config.out)
    code = (f"from smac_hard_gym.baselines import value_main; value_main({str(path / 'model.zip')!r}, "
            f"{run.opponent!r}, {config.eval_episodes}, {TEST_SEED_BASE}, {str(path / 'value.json')!r})")
    return [sys.executable, "-c", code]


# ---------------------------------------------------------------------------------------------------------------
# Running.


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


# ---------------------------------------------------------------------------------------------------------------
# The mixing experiment's value estimate.


def value_estimate(model: Any, venv: Any, *, seed: int) -> float:
    """Mean critic value ``model.policy.predict_values`` over the first observations of ``venv``'s battles after
    ``reset(seed=seed)``: what the learner expects to win from the start of a test episode."""
    import torch

    obs, _ = venv.reset(seed=seed)
    with torch.no_grad():
        tensor, _ = model.policy.obs_to_tensor(obs)
        values = model.policy.predict_values(tensor)
    return float(values.mean())


def value_main(model_path: str, opponent: str, episodes: int, seed: int, out: str) -> None:
    """Runs in its own process (:func:`value_command`): :func:`value_estimate` of a trained model on ``episodes``
    test battles against ``opponent``, written as JSON to ``out``."""
    import torch

    from smac_hard_gym.envs.vector import NativeVectorEnv
    from smac_hard_gym.opponents import opponent_from_text
    from smac_hard_gym.training import load_model, load_run_config

    torch.set_num_threads(1)
    config = load_run_config(model_path)
    if config is None:
        raise FileNotFoundError(f"no config.json next to {model_path}")
    kwargs = config.env_kwargs()
    map_name = kwargs.pop("map_name")
    model = load_model(model_path)
    venv = NativeVectorEnv(map_name, episodes, autoreset_mode="SameStep", opponent=opponent_from_text(opponent),
                           **kwargs)
    try:
        value = value_estimate(model, venv, seed=seed)  # TEST_SEED_BASE from value_command: train's test battles
    finally:
        venv.close()
    write_json(out, {"map": map_name, "opponent": opponent, "episodes": episodes, "mean_value": value})


# ---------------------------------------------------------------------------------------------------------------
# Aggregation.


def spread(values: Sequence[float]) -> dict[str, float]:
    """Mean, population standard deviation (``ddof=0``), minimum and maximum over seeds."""
    array = np.asarray(values, dtype=float)
    return {"seeds": int(array.size), "mean": float(array.mean()), "std": float(array.std()),
            "min": float(array.min()), "max": float(array.max())}


class MalformedFile(ValueError):
    """A file of a run or of the sweep cannot be read (the message names the file and what is wrong)."""


def _read_curve(path: Path) -> dict[int, float]:
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            curve = {}
            for row in csv.DictReader(handle):
                step, rate = int(row["timesteps"]), float(row["win_rate"])
                if step < 0 or not 0.0 <= rate <= 1.0:  # also rejects nan
                    raise ValueError(f"timesteps {step}, win rate {rate} out of range")
                curve[step] = rate
            return curve
    except (OSError, ValueError, KeyError, TypeError, csv.Error) as err:
        raise MalformedFile(f"{path}: malformed learning curve ({type(err).__name__}: {err})") from None


def _number(data: dict[str, Any], key: str, path: Path, *, rate: bool = False, optional: bool = False) -> Any:
    """``data[key]`` checked to be a finite number (in 0..1 for a ``rate``; None allowed when ``optional``)."""
    if key not in data:
        if optional:
            return None
        raise MalformedFile(f"{path}: malformed file (no {key!r} entry)")
    value = data[key]
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) \
            or (rate and not 0.0 <= value <= 1.0):
        raise MalformedFile(f"{path}: malformed file ({key} is {value!r}, expected a "
                            f"{'win rate in 0..1' if rate else 'finite number'})")
    return value


def _text(data: dict[str, Any], key: str, path: Path) -> str:
    if key not in data:
        raise MalformedFile(f"{path}: malformed file (no {key!r} entry)")
    value = data[key]
    if not isinstance(value, str):
        raise MalformedFile(f"{path}: malformed file ({key} is {value!r}, expected a string)")
    return value


def _object(data: Any, path: Path, what: str) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise MalformedFile(f"{path}: malformed {what} (a JSON object expected, got {type(data).__name__})")
    return data


def _rates(data: Any, path: Path, key: str) -> dict[str, float]:
    """A mapping of names to win rates (``final_per_opponent``), checked."""
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise MalformedFile(f"{path}: malformed file ({key} is {data!r}, expected an object of win rates)")
    return {str(name): _number(data, name, path, rate=True) for name in data}


def _read_run(path: Path, out: Path) -> tuple[dict[str, Any], dict[int, float] | None, dict[str, Any] | None,
                                              float | None]:
    """One finished run's row, curve, black-box evaluation and value estimate; malformed files raise
    :class:`MalformedFile` naming them."""
    summary_path = path / "summary.json"
    summary = _object(read_json(summary_path, "run summary"), summary_path, "run summary")
    train_config = {}
    if (path / "config.json").is_file():
        train_config = _object(read_json(path / "config.json", "run config"), path / "config.json", "run config")
    seed = train_config.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
        raise MalformedFile(f"{path / 'config.json'}: malformed file (seed is {seed!r}, expected an int)")
    row = {"map": _text(summary, "map", summary_path), "opponent": _text(summary, "opponent", summary_path),
           "seed": seed, "timesteps": _number(summary, "timesteps", summary_path),
           "final_win_rate": _number(summary, "final_win_rate", summary_path, rate=True),
           "best_win_rate": _number(summary, "best_win_rate", summary_path, rate=True),
           "train_wall_s": _number(summary, "train_wall_s", summary_path, optional=True),
           "dir": str(path.relative_to(out))}
    row["final_per_opponent"] = _rates(summary.get("final_per_opponent"), summary_path, "final_per_opponent")
    curve = _read_curve(path / "curve.csv") if (path / "curve.csv").is_file() else None
    evaluation = None
    if (path / "blackbox.json").is_file():
        bb_path = path / "blackbox.json"
        evaluation = _object(read_json(bb_path, "black-box evaluation"), bb_path, "black-box evaluation")
        scripts = evaluation.get("scripts")
        mixture = evaluation.get("mixture")
        weights = evaluation.get("weights")
        if not isinstance(scripts, dict) or not isinstance(mixture, dict) or not isinstance(weights, dict):
            raise MalformedFile(f"{bb_path}: malformed black-box evaluation (needs 'scripts', 'mixture' and "
                                "'weights' objects)")
        evaluation = {"scripts": {str(name): _number(_object(r, bb_path, f"row of {name!r}"), "win_rate", bb_path,
                                                     rate=True) for name, r in scripts.items()},
                      "mixture": _number(mixture, "win_rate", bb_path, rate=True),
                      "weights": {str(name): _number(weights, name, bb_path) for name in weights}}
    value = None
    if (path / "value.json").is_file():
        value_path = path / "value.json"
        value = _number(_object(read_json(value_path, "value estimate"), value_path, "value estimate"),
                        "mean_value", value_path)
    return row, curve, evaluation, value


def aggregate(out: str | Path, config: SweepConfig | None = None) -> dict[str, Any]:
    """Read every finished run under ``out/runs`` and write ``results.json``, ``results.csv``, ``blackbox.csv``,
    ``pool.csv`` and ``curves/<map>.png``; returns the results. Without ``config``, the one saved in
    ``results.json`` (if any) is kept."""
    out = Path(out)
    runs: list[dict[str, Any]] = []
    curves: dict[tuple[str, str], list[dict[int, float]]] = {}
    blackbox: dict[tuple[str, str], list[float]] = {}
    weights: dict[tuple[str, str], float] = {}
    values: dict[tuple[str, str], list[float]] = {}
    pool: dict[tuple[str, str], list[float]] = {}  # (map, script) -> final test win rate per `default` seed
    for path in sorted((out / "runs").glob("*")):
        if run_state(path) != "done":
            continue
        row, curve, evaluation, value = _read_run(path, out)
        per_opponent = row.pop("final_per_opponent")
        key = (row["map"], row["opponent"])
        if row["opponent"] == "default":
            for script, rate in per_opponent.items():
                pool.setdefault((row["map"], script), []).append(rate)
        if curve is not None:
            curves.setdefault(key, []).append(curve)
        if evaluation is not None:
            row["blackbox"] = dict(evaluation["scripts"])
            row["blackbox"]["mixture"] = evaluation["mixture"]
            for name, rate in row["blackbox"].items():
                blackbox.setdefault((row["map"], name), []).append(rate)
            for name, weight in evaluation["weights"].items():
                weights[(row["map"], name)] = weight
        if value is not None:
            row["mean_value"] = value
            values.setdefault(key, []).append(value)
        runs.append(row)
    table = []
    for key in sorted({(r["map"], r["opponent"]) for r in runs}, key=_order):
        rates = [r["final_win_rate"] for r in runs if (r["map"], r["opponent"]) == key]
        table.append({"map": key[0], "opponent": key[1], **spread(rates)})
    def script_order(item: tuple[tuple[str, str], list[float]]) -> tuple[Any, ...]:
        (map_name, script), _ = item
        return (_order((map_name, "")), script == MIXTURE, script)  # the scripts by name, then their mixture

    bb_table = [{"map": m, "script": s, "weight": weights.get((m, s), 1.0), **spread(v)}
                for (m, s), v in sorted(blackbox.items(), key=script_order)]
    value_table = [{"map": m, "opponent": o, **spread(v)} for (m, o), v in sorted(values.items(), key=_order)]
    pool_table = [{"map": m, "script": s, **spread(v)} for (m, s), v in sorted(pool.items(), key=script_order)]
    saved = {}
    if config is None and (out / "results.json").is_file():
        saved = _object(read_json(out / "results.json", "sweep results"), out / "results.json",
                        "sweep results").get("config", {})
        if not isinstance(saved, dict):
            raise MalformedFile(f"{out / 'results.json'}: malformed sweep results (config is {saved!r}, expected "
                                "an object)")
    results = {"config": asdict(config) if config is not None else saved, "runs": runs, "table": table,
               "blackbox": bb_table, "values": value_table, "pool": pool_table}
    results["findings"] = findings(results)
    _write_csv(out / "results.csv", table, ("map", "opponent", "seeds", "mean", "std", "min", "max"))
    _write_csv(out / "blackbox.csv", bb_table, ("map", "script", "weight", "seeds", "mean", "std", "min", "max"))
    if pool_table:
        _write_csv(out / "pool.csv", pool_table, ("map", "script", "seeds", "mean", "std", "min", "max"))
    if value_table:
        _write_csv(out / "values.csv", value_table, ("map", "opponent", "seeds", "mean", "std", "min", "max"))
    _plot_curves(out / "curves", curves)
    write_json(out / "results.json", results)
    return results


def _order(key: tuple[str, str]) -> tuple[int, str, int, str]:
    """The paper's map order, then ``smac``, ``default`` and other opponents by name."""
    map_name, opponent = key
    rank = SWEEP_OPPONENTS.index(opponent) if opponent in SWEEP_OPPONENTS else len(SWEEP_OPPONENTS)
    return (_MAP_ORDER.index(map_name) if map_name in _MAP_ORDER else len(_MAP_ORDER), map_name, rank, opponent)


def _write_csv(path: Path, rows: list[dict[str, Any]], columns: Sequence[str]) -> None:
    with atomic_write(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        for row in rows:
            writer.writerow([f"{row[c]:.4f}" if isinstance(row[c], float) else row[c] for c in columns])


def mean_curve(curves: Sequence[dict[int, float]]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Steps every seed evaluated at, and the mean, minimum and maximum win rate there."""
    steps = sorted(set.intersection(*(set(c) for c in curves)))
    rates = np.array([[c[s] for s in steps] for c in curves])
    return np.array(steps), rates.mean(axis=0), rates.min(axis=0), rates.max(axis=0)


def _plot_curves(folder: Path, curves: dict[tuple[str, str], list[dict[int, float]]]) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    folder.mkdir(parents=True, exist_ok=True)
    for map_name in sorted({m for m, _ in curves}):
        fig, axes = plt.subplots(figsize=(7, 4), dpi=100)
        for (m, opponent), seeds in sorted(curves.items()):
            if m != map_name:
                continue
            steps, mean, low, high = mean_curve(seeds)
            count = f"{len(seeds)} seed" + ("s" if len(seeds) > 1 else "")
            line = axes.plot(steps, mean, "o-", markersize=3, label=f"vs {opponent} ({count})")[0]
            axes.fill_between(steps, low, high, color=line.get_color(), alpha=0.2)
        axes.set_xlabel("env steps")
        axes.set_ylabel("test win rate (mean, min-max band)")
        axes.set_ylim(-0.02, 1.02)
        axes.grid(alpha=0.3)
        axes.set_title(f"MaskablePPO on {map_name}")
        axes.legend(loc="best", fontsize="small")
        fig.tight_layout()
        try:
            with atomic_path(folder / f"{map_name}.png") as tmp:
                fig.savefig(tmp, format="png")
        finally:
            plt.close(fig)


# ---------------------------------------------------------------------------------------------------------------
# Report.


# ---------------------------------------------------------------------------------------------------------------
# The paper's claims, checked on the finished maps.

HARDER_BY = 1 / 32  # one test episode of each seed's 32: a smaller gap between two cells is counted level
# (our table, its opponent, the paper's table it is ranked against)
RANKED = (("smac", "smac", "smac_2m"), ("default", "default", "default_10m"), ("default", "default", "default_2m"),
          ("black-box", MIXTURE, "blackbox_10m"))


def average_ranks(values: Sequence[float]) -> np.ndarray:
    """Ranks from 1, tied values sharing the mean of the ranks they span (as Spearman's correlation ranks them)."""
    array = np.asarray(values, dtype=float)
    ranks = np.empty(array.size)
    ranks[array.argsort(kind="stable")] = np.arange(1, array.size + 1)
    for value in np.unique(array):
        ranks[array == value] = ranks[array == value].mean()
    return ranks


def spearman(a: Sequence[float], b: Sequence[float]) -> float:
    """Spearman's rank correlation (Pearson's on average ranks); NaN when either side has a single value."""
    ranks_a, ranks_b = average_ranks(a), average_ranks(b)
    if len(ranks_a) < 2 or np.ptp(ranks_a) == 0 or np.ptp(ranks_b) == 0:
        return float("nan")
    return float(np.corrcoef(ranks_a, ranks_b)[0, 1])


def findings(results: dict[str, Any]) -> dict[str, Any]:
    """The paper's claims on the maps where both opponents have the sweep's full seeds: on which maps the mixed pool
    (``default``) and the black-box scripts are lower than ``smac`` by more than :data:`HARDER_BY`, level, or higher;
    and Spearman's rank correlation of each of our tables with the paper's mean of QMIX and MAPPO over those maps."""
    table = {(r["map"], r["opponent"]): r for r in results.get("table", []) if r["opponent"] in SWEEP_OPPONENTS}
    table.update({(r["map"], MIXTURE): r for r in results.get("blackbox", []) if r["script"] == MIXTURE})
    seeds = max((r["seeds"] for r in table.values()), default=0)
    maps = [m for m in _MAP_ORDER if all(table.get((m, o), {}).get("seeds") == seeds for o in SWEEP_OPPONENTS)]

    def against_smac(opponent: str) -> dict[str, list[str]]:
        verdicts: dict[str, list[str]] = {"lower": [], "level": [], "higher": [], "missing": []}
        for m in maps:
            row, smac = table.get((m, opponent)), table[(m, "smac")]
            gap = None if row is None else row["mean"] - smac["mean"]
            verdict = ("missing" if gap is None else "lower" if gap < -HARDER_BY else "higher" if gap > HARDER_BY
                       else "level")
            verdicts[verdict].append(m)
        return verdicts

    ranked = {}
    for label, opponent, paper in RANKED:
        pairs = [(table[(m, opponent)]["mean"], float(np.mean(PAPER[paper][m])))
                 for m in maps if (m, opponent) in table]
        rho = spearman(*zip(*pairs, strict=True)) if pairs else float("nan")
        ranked[f"{label} vs paper {paper}"] = None if np.isnan(rho) else rho  # None: no ranking (JSON has no NaN)
    return {"seeds": seeds, "maps": maps, "harder_by": HARDER_BY, "pool_vs_smac": against_smac("default"),
            "blackbox_vs_smac": against_smac(MIXTURE), "spearman": ranked}


def findings_markdown(found: dict[str, Any]) -> str:
    """:func:`findings` as a few lines of the report."""
    if not found["maps"]:
        return ""
    maps = found["maps"]

    def verdicts(name: str, claim: str) -> str:
        parts = [f"{claim} on {len(v)} of {len(maps)}" if k == "lower" else f"{k} on {len(v)}"
                 for k, v in found[name].items() if v or k == "lower"]
        lists = "; ".join(f"{k}: {', '.join(v)}" for k, v in found[name].items() if v)
        return f"- {', '.join(parts)} ({lists})."

    ranks = ", ".join(f"{k} {'undefined (all tied)' if v is None else f'{v:.2f}'}"
                      for k, v in found["spearman"].items())
    return "\n".join([
        f"Checked on the {len(maps)} maps with {found['seeds']} seeds against both opponents (a gap of "
        f"{found['harder_by']:.3f} or less, one test episode per seed, counts as level):", "",
        verdicts("pool_vs_smac", "the mixed pool lower than `smac`"),
        verdicts("blackbox_vs_smac", "black-box lower than `smac`"),
        f"- Spearman rank correlation with the paper's mean of QMIX and MAPPO over these maps: {ranks}."]) + "\n"


def training_time(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Per map: the runs' training wall time (``train``'s clock, test evaluations left out), in minutes."""
    minutes: dict[str, list[float]] = {}
    for run in results.get("runs", []):
        if run.get("train_wall_s") is not None:
            minutes.setdefault(run["map"], []).append(run["train_wall_s"] / 60)
    return [{"map": m, "runs": len(v), "median": float(np.median(v)), "min": min(v), "max": max(v), "total": sum(v)}
            for m, v in sorted(minutes.items(), key=lambda item: _order((item[0], "")))]


def _time_markdown(rows: list[dict[str, Any]]) -> list[str]:
    if not rows:
        return []
    total = sum(r["total"] for r in rows) / 60
    return ["", f"Training wall time per run, minutes (`train`'s clock, test evaluations left out; {total:.1f} hours "
            f"over {sum(r['runs'] for r in rows)} runs):", "", "| map | runs | median | min-max |",
            "|---|---:|---:|---:|",
            *(f"| {r['map']} | {r['runs']} | {r['median']:.1f} | {r['min']:.1f}-{r['max']:.1f} |" for r in rows)]


def _cell(row: dict[str, Any] | None) -> str:
    if row is None:
        return "not run yet"
    if row["seeds"] == 1:
        return f"{row['mean']:.2f} (1 seed)"
    return f"{row['mean']:.2f} ± {row['std']:.2f} ({row['min']:.2f}-{row['max']:.2f})"


def _paper(table: str, map_name: str) -> tuple[str, str]:
    pair = PAPER[table].get(map_name)
    return ("", "") if pair is None else (f"{pair[0]:.2f}", f"{pair[1]:.2f}")


def report_markdown(results: dict[str, Any], maps: Sequence[str] | None = None) -> str:
    """The three tables (``smac``, ``default``, black-box) side by side with the paper's QMIX and MAPPO columns, per
    map; our cells are mean ± std (min-max) of the final test win rate over seeds, or "not run yet"."""
    table = {(r["map"], r["opponent"]): r for r in results.get("table", [])}
    bb = {r["map"]: r for r in results.get("blackbox", []) if r["script"] == "mixture"}
    steps = sorted({r["timesteps"] for r in results.get("runs", [])})
    budget = f"{steps[0]:,}" if len(steps) == 1 else ", ".join(f"{s:,}" for s in steps) or "-"
    maps = list(maps) if maps is not None else list(_MAP_ORDER)
    experiment = results.get("config", {}).get("experiment")
    found = results["findings"] if "findings" in results else findings(results)  # aggregate() stores them
    lines = [] if experiment else [findings_markdown(found),
             f"Ours: MaskablePPO on this engine, final test win rate (masked, deterministic) after {budget} env "
             "steps, mean ± std (min-max) over seeds. Paper: QMIX / MAPPO on StarCraft II.", "",
             "| map | smac: paper QMIX (2M) | smac: paper MAPPO (2M) | smac: ours | default: paper QMIX (10M) | "
             "default: paper MAPPO (10M) | default: paper QMIX (2M) | default: paper MAPPO (2M) | default: ours | "
             "black-box: paper QMIX (10M) | black-box: paper MAPPO (10M) | black-box: ours |",
             "|---|" + "---:|" * 11]
    for map_name in [] if experiment else maps:
        cells = [*_paper("smac_2m", map_name), _cell(table.get((map_name, "smac"))),
                 *_paper("default_10m", map_name), *_paper("default_2m", map_name),
                 _cell(table.get((map_name, "default"))), *_paper("blackbox_10m", map_name), _cell(bb.get(map_name))]
        lines.append(f"| {map_name} | " + " | ".join(cells) + " |")
    if not experiment:
        lines += ["", "Paper columns: " + "; ".join(f"{k}: {v}" for k, v in SOURCES.items()) + "."]
        lines += _time_markdown(training_time(results))
    scripts = [r for r in results.get("blackbox", []) if r["script"] != "mixture"]
    if scripts:
        lines += ["", "Black-box, per script (models trained against `smac`):", "",
                  "| map | script | weight | win rate |", "|---|---|---:|---:|"]
        lines += [f"| {r['map']} | {r['script']} | {r['weight']:.2f} | {_cell(r)} |" for r in scripts]
    if results.get("pool"):
        lines += ["", "Against the `default` pool, per script (the final test episodes drawn against each script; "
                  "models trained against the pool):", "", "| map | script | win rate |", "|---|---|---:|"]
        lines += [f"| {r['map']} | {r['script']} | {_cell(r)} |" for r in results["pool"]]
    if results.get("values"):
        lines += ["", "Mean value estimate (critic, first observation of test episodes):", "",
                  "| map | opponent | test win rate | mean value |", "|---|---|---:|---:|"]
        for r in results["values"]:
            lines.append(f"| {r['map']} | {r['opponent']} | {_cell(table.get((r['map'], r['opponent'])))} | "
                         f"{_cell(r)} |")
    others = [r for r in results.get("table", []) if r["opponent"] not in SWEEP_OPPONENTS]
    if others and not results.get("values"):
        lines += ["", "| map | opponent | test win rate |", "|---|---|---:|"]
        lines += [f"| {r['map']} | {r['opponent']} | {_cell(r)} |" for r in others]
    return "\n".join(lines).strip() + "\n"


def write_report(out: str | Path, path: str | Path) -> Path:
    """Aggregate the runs under ``out`` (no training) and write :func:`report_markdown` to ``path``. A published
    sweep without its run folders (``out/results.json`` alone, as under ``docs/baselines/``) is rendered from its
    ``results.json``."""
    out = Path(out)
    if (out / "runs").is_dir():
        results = aggregate(out)
    elif (out / "results.json").is_file():
        results = _object(read_json(out / "results.json", "sweep results"), out / "results.json", "sweep results")
        for key in ("config", "runs", "table", "blackbox"):
            expected = dict if key == "config" else list
            if not isinstance(results.get(key, expected()), expected):
                raise MalformedFile(f"{out / 'results.json'}: malformed sweep results ({key} is {results[key]!r}, "
                                    f"expected {'an object' if expected is dict else 'a list'})")
        results.setdefault("config", {})
    else:
        raise FileNotFoundError(f"no runs under {out} and no results.json: run `smac-hard-gym baselines --out {out}` "
                                "first")
    maps = results["config"].get("maps") or None
    if maps is not None and (not isinstance(maps, list) or not all(isinstance(m, str) for m in maps)):
        raise MalformedFile(f"{out / 'results.json'}: malformed sweep results (config maps is {maps!r}, expected a "
                            "list of map names)")
    if maps is not None:  # the last session's maps, and every map with results (a sweep run over several sessions)
        found = set(maps) | {r.get("map") for r in results.get("table", []) if isinstance(r, dict)}
        maps = [m for m in _MAP_ORDER if m in found] + sorted(m for m in found - set(_MAP_ORDER) if isinstance(m, str))
    return write_text(path, report_markdown(results, maps))

