"""The sweep's markdown report (``smac-hard-gym baselines --report``): our tables beside the paper's QMIX and MAPPO
columns, the findings, training time, and the per-script and value tables."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from smac_hard_gym.files import read_json, write_text
from smac_hard_gym.training.baselines.claims import findings, findings_markdown
from smac_hard_gym.training.baselines.paper import MAP_ORDER, PAPER, SOURCES
from smac_hard_gym.training.baselines.planning import SWEEP_OPPONENTS
from smac_hard_gym.training.baselines.results import MalformedFile, aggregate, json_object, table_order
from smac_hard_gym.training.evaluation import MIXTURE_ROW

__all__ = ["report_markdown", "write_report", "training_time"]


def training_time(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Per map: the runs' training wall time (``train``'s clock, test evaluations left out), in minutes."""
    minutes: dict[str, list[float]] = {}
    for run in results.get("runs", []):
        if run.get("train_wall_s") is not None:
            minutes.setdefault(run["map"], []).append(run["train_wall_s"] / 60)
    return [{"map": m, "runs": len(v), "median": float(np.median(v)), "min": min(v), "max": max(v), "total": sum(v)}
            for m, v in sorted(minutes.items(), key=lambda item: table_order((item[0], "")))]


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
    bb = {r["map"]: r for r in results.get("blackbox", []) if r["script"] == MIXTURE_ROW}
    steps = sorted({r["timesteps"] for r in results.get("runs", [])})
    budget = f"{steps[0]:,}" if len(steps) == 1 else ", ".join(f"{s:,}" for s in steps) or "-"
    maps = list(maps) if maps is not None else list(MAP_ORDER)
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
    scripts = [r for r in results.get("blackbox", []) if r["script"] != MIXTURE_ROW]
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
        results = json_object(read_json(out / "results.json", "sweep results"), out / "results.json", "sweep results")
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
        maps = [m for m in MAP_ORDER if m in found] + sorted(m for m in found - set(MAP_ORDER) if isinstance(m, str))
    return write_text(path, report_markdown(results, maps))
