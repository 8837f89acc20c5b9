"""Reading a sweep's finished runs into its results (:func:`aggregate`): ``results.json``, the CSV tables and the
learning curves per map. A malformed run file raises :class:`MalformedFile` naming it."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.files import atomic_path, atomic_write, read_json, write_json
from smac_hard_gym.training.baselines.claims import findings
from smac_hard_gym.training.baselines.paper import MAP_ORDER
from smac_hard_gym.training.baselines.planning import SWEEP_OPPONENTS, SweepConfig, run_state
from smac_hard_gym.training.evaluation import MIXTURE_ROW

__all__ = ["aggregate", "recorded_runs", "spread", "mean_curve", "MalformedFile", "json_object", "table_order",
           "write_csv", "plot_curves"]


def spread(values: Sequence[float]) -> dict[str, float]:
    """Mean, population standard deviation (``ddof=0``), minimum and maximum over seeds."""
    array = np.asarray(values, dtype=float)
    return {"seeds": int(array.size), "mean": float(array.mean()), "std": float(array.std()),
            "min": float(array.min()), "max": float(array.max())}


class MalformedFile(ValueError):
    """A file of a run or of the sweep cannot be read (the message names the file and what is wrong)."""


# One finished run as read back: its table row, its learning curve (step -> test win rate), its black-box evaluation
# ({"scripts", "mixture", "weights"}) and its value estimate; the last three may be missing (None).
RunReading = tuple[dict[str, Any], dict[int, float] | None, dict[str, Any] | None, float | None]


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


def json_object(data: Any, path: Path, what: str) -> dict[str, Any]:
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


def _read_run(path: Path, out: Path) -> RunReading:
    """One finished run's row, curve, black-box evaluation and value estimate; malformed files raise
    :class:`MalformedFile` naming them."""
    summary_path = path / "summary.json"
    summary = json_object(read_json(summary_path, "run summary"), summary_path, "run summary")
    train_config = {}
    if (path / "config.json").is_file():
        train_config = json_object(read_json(path / "config.json", "run config"), path / "config.json", "run config")
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
        evaluation = json_object(read_json(bb_path, "black-box evaluation"), bb_path, "black-box evaluation")
        scripts = evaluation.get("scripts")
        mixture = evaluation.get("mixture")
        weights = evaluation.get("weights")
        if not isinstance(scripts, dict) or not isinstance(mixture, dict) or not isinstance(weights, dict):
            raise MalformedFile(f"{bb_path}: malformed black-box evaluation (needs 'scripts', 'mixture' and "
                                "'weights' objects)")
        evaluation = {"scripts": {str(name): _number(json_object(r, bb_path, f"row of {name!r}"), "win_rate", bb_path,
                                                     rate=True) for name, r in scripts.items()},
                      "mixture": _number(mixture, "win_rate", bb_path, rate=True),
                      "weights": {str(name): _number(weights, name, bb_path) for name in weights}}
    value = None
    if (path / "value.json").is_file():
        value_path = path / "value.json"
        value = _number(json_object(read_json(value_path, "value estimate"), value_path, "value estimate"),
                        "mean_value", value_path)
    return row, curve, evaluation, value


def _previous(out: Path) -> dict[str, Any]:
    """``out/results.json`` as the last aggregation wrote it ({} when there is none), checked to be an object."""
    if not (out / "results.json").is_file():
        return {}
    return json_object(read_json(out / "results.json", "sweep results"), out / "results.json", "sweep results")


def _recorded_row(data: Any, path: Path) -> RunReading:
    """A run row of ``results.json`` read back as :func:`_read_run` reads a run folder (its black-box weights are
    the sweep's, filled in by the caller)."""
    row = json_object(data, path, "run row")
    seed = row.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
        raise MalformedFile(f"{path}: malformed run row (seed is {seed!r}, expected an int)")
    checked = {"map": _text(row, "map", path), "opponent": _text(row, "opponent", path), "seed": seed,
               "timesteps": _number(row, "timesteps", path),
               "final_win_rate": _number(row, "final_win_rate", path, rate=True),
               "best_win_rate": _number(row, "best_win_rate", path, rate=True),
               "train_wall_s": _number(row, "train_wall_s", path, optional=True), "dir": _text(row, "dir", path),
               "final_per_opponent": _rates(row.get("final_per_opponent"), path, "final_per_opponent")}
    curve = None
    if row.get("curve") is not None:
        points = row["curve"]
        if not isinstance(points, list) or not all(isinstance(p, list) and len(p) == 2 for p in points):
            raise MalformedFile(f"{path}: malformed run row (curve is {points!r}, expected [[step, win rate], ...])")
        curve = {}
        for step, rate in points:
            if isinstance(step, bool) or not isinstance(step, int) or step < 0:
                raise MalformedFile(f"{path}: malformed run row (curve step {step!r}, expected an int >= 0)")
            curve[step] = _number({"win_rate": rate}, "win_rate", path, rate=True)
    evaluation = None
    if row.get("blackbox") is not None:
        rates = _rates(row["blackbox"], path, "blackbox")
        mixture = rates.pop(MIXTURE_ROW, None)
        if mixture is None:
            raise MalformedFile(f"{path}: malformed run row (blackbox has no {MIXTURE_ROW!r} rate)")
        evaluation = {"scripts": rates, "mixture": mixture, "weights": {}}
    value = _number(row, "mean_value", path, optional=True)
    return checked, curve, evaluation, value


def recorded_runs(out: str | Path) -> dict[str, RunReading]:
    """The runs ``out/results.json`` lists whose folder is not under ``out`` (a published sweep keeps its results,
    not its models; a sweep carried on another machine has only those): run label -> what :func:`_read_run` gives.
    They count as done: not trained again, and kept in the tables beside the runs with folders."""
    out = Path(out)
    return _recorded(out, _previous(out))


def _recorded(out: Path, previous: dict[str, Any]) -> dict[str, RunReading]:
    """:func:`recorded_runs` from ``previous``, ``out/results.json`` already read."""
    rows = previous.get("runs", [])
    if not isinstance(rows, list):
        raise MalformedFile(f"{out / 'results.json'}: malformed sweep results (runs is not a list)")
    weights = {(r.get("map"), r.get("script")): r.get("weight") for r in previous.get("blackbox", [])
               if isinstance(r, dict)}
    recorded = {}
    for data in rows:
        row, curve, evaluation, value = _recorded_row(data, out / "results.json")
        if (out / row["dir"]).exists():
            continue
        if evaluation is not None:
            evaluation["weights"] = {name: _number({"weight": weights.get((row["map"], name), 1.0)}, "weight",
                                                   out / "results.json") for name in evaluation["scripts"]}
        recorded[Path(row["dir"]).name] = (row, curve, evaluation, value)
    return recorded


def aggregate(out: str | Path, config: SweepConfig | None = None) -> dict[str, Any]:
    """Read every finished run under ``out/runs`` (and the runs ``results.json`` records without a folder,
    :func:`recorded_runs`) and write ``results.json``, ``results.csv``, ``blackbox.csv``, ``pool.csv`` and
    ``curves/<map>.png``; returns the results. Without ``config``, the one saved in ``results.json`` (if any) is
    kept. Each run's row carries its learning curve, so a run recorded this way keeps it."""
    out = Path(out)
    runs: list[dict[str, Any]] = []
    curves: dict[tuple[str, str], list[dict[int, float]]] = {}
    blackbox: dict[tuple[str, str], list[float]] = {}
    weights: dict[tuple[str, str], float] = {}
    values: dict[tuple[str, str], list[float]] = {}
    pool: dict[tuple[str, str], list[float]] = {}  # (map, script) -> final test win rate per `default` seed
    folders = [_read_run(path, out) for path in sorted((out / "runs").glob("*")) if run_state(path) == "done"]
    previous = _previous(out)  # read once: the recorded runs and, without ``config``, the saved config
    recorded = _recorded(out, previous)
    for row, curve, evaluation, value in sorted([*folders, *recorded.values()], key=lambda r: r[0]["dir"]):
        per_opponent = row["final_per_opponent"]
        key = (row["map"], row["opponent"])
        if row["opponent"] == "default":
            for script, rate in per_opponent.items():
                pool.setdefault((row["map"], script), []).append(rate)
        if curve is not None:
            curves.setdefault(key, []).append(curve)
            row["curve"] = [[step, rate] for step, rate in sorted(curve.items())]
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
    for key in sorted({(r["map"], r["opponent"]) for r in runs}, key=table_order):
        rates = [r["final_win_rate"] for r in runs if (r["map"], r["opponent"]) == key]
        table.append({"map": key[0], "opponent": key[1], **spread(rates)})
    def script_order(item: tuple[tuple[str, str], list[float]]) -> tuple[Any, ...]:
        (map_name, script), _ = item
        return (table_order((map_name, "")), script == MIXTURE_ROW, script)  # the scripts by name, then their mixture

    bb_table = [{"map": m, "script": s, "weight": weights.get((m, s), 1.0), **spread(v)}
                for (m, s), v in sorted(blackbox.items(), key=script_order)]
    value_table = [{"map": m, "opponent": o, **spread(v)} for (m, o), v in sorted(values.items(), key=table_order)]
    pool_table = [{"map": m, "script": s, **spread(v)} for (m, s), v in sorted(pool.items(), key=script_order)]
    saved = {}
    if config is None:
        saved = previous.get("config", {})
        if not isinstance(saved, dict):
            raise MalformedFile(f"{out / 'results.json'}: malformed sweep results (config is {saved!r}, expected "
                                "an object)")
    results = {"config": asdict(config) if config is not None else saved, "runs": runs, "table": table,
               "blackbox": bb_table, "values": value_table, "pool": pool_table}
    results["findings"] = findings(results)
    write_csv(out / "results.csv", table, ("map", "opponent", "seeds", "mean", "std", "min", "max"))
    write_csv(out / "blackbox.csv", bb_table, ("map", "script", "weight", "seeds", "mean", "std", "min", "max"))
    if pool_table:
        write_csv(out / "pool.csv", pool_table, ("map", "script", "seeds", "mean", "std", "min", "max"))
    if value_table:
        write_csv(out / "values.csv", value_table, ("map", "opponent", "seeds", "mean", "std", "min", "max"))
    plot_curves(out / "curves", curves)
    write_json(out / "results.json", results)
    return results


def table_order(key: tuple[str, str]) -> tuple[int, str, int, str]:
    """The paper's map order, then ``smac``, ``default`` and other opponents by name."""
    map_name, opponent = key
    rank = SWEEP_OPPONENTS.index(opponent) if opponent in SWEEP_OPPONENTS else len(SWEEP_OPPONENTS)
    return (MAP_ORDER.index(map_name) if map_name in MAP_ORDER else len(MAP_ORDER), map_name, rank, opponent)


def write_csv(path: Path, rows: list[dict[str, Any]], columns: Sequence[str]) -> None:
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


def plot_curves(folder: Path, curves: dict[tuple[str, str], list[dict[int, float]]]) -> None:
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
