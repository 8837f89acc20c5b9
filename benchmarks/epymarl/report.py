"""Report of the EPyMARL reference runs made by run_reference.py: win-rate table beside the SMAC-HARD paper's, curves.

Reads every job's sacred ``info.json`` (``sacred/<start>/<id>/info.json``: ``test_battle_won_mean`` over
``test_battle_won_mean_T`` = t_env), joins the segments of a resumed job (a later start supersedes the points of
earlier ones from its first t_env on), and writes ``<out>/report.md`` and ``<out>/curves/<map>.png`` (each written
to a temporary file, then renamed into place).

Final win rate = the mean of the job's last ``--last`` (default 3) test evaluations; with EPyMARL's sc2.yaml
(test_interval 50000, test_nepisode 100) these are the evaluations at about t_env 1.95M, 2.0M and 2.05M, 300 greedy
episodes in all. A job without done.json is shown as in progress with the same mean over its latest evaluations.
``--out`` takes several folders (runs kept apart, e.g. made on different pinned installs); the report and curves
go to the first. Below the table: Spearman's rank correlation of each algorithm's finished runs (mean over seeds)
with the paper's column, over the maps where it has one.

A machine can be lost with its run folders, so ``--record FILE`` writes what the table is made of (each run's
evaluation curve, whether it finished, the engine fingerprint and commits it ran) as a JSON file meant to be kept
in the repository (``benchmarks/results/``), with no machine paths; ``--records FILE ...`` reads such files back
as runs of their own, so a table can join runs kept on record with runs still going (a live folder's run
supersedes a recorded one of the same algorithm, map, seed and engine).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import tempfile
from pathlib import Path
from typing import NamedTuple

from smac_hard_gym.training.baselines.claims import spearman
from smac_hard_gym.training.baselines.paper import PAPER

# SMAC-HARD paper (arXiv 2412.17707), appendix table "Final performance at 2M time step with default opponent
# policy" (SMAC's own opponent): (QMIX, MAPPO) per map; QMIX from pymarl2, MAPPO from Yu et al.'s on-policy code.
PAPER_2M_DEFAULT_OPPONENT = PAPER["smac_2m"]
PAPER_COL = {"qmix": 0, "mappo": 1}
KEY = "test_battle_won_mean"

# QMIX in StarCraft II along the way, not only at 2M: the SMAC paper's (Samvelyan et al. 2019, arXiv 1902.04043)
# pymarl QMIX (GRU agent, RMSprop, one env, 2M steps, SC2 4.6.2), mean test win rate of its 5 runs from SMAC's
# released run data (smac_run_data.json) as plotted in FlickerNiko/SAC-QMIX figures/<map>_all.svg, read at
# t_env = 0.1M, 0.2M, ..., 2.0M (linear between the plot's points, every 0.02M). Their ends agree with the SMAC
# paper's table of medians (5m_vs_6m 70%, MMM2 69%, 27m_vs_30m 49%, 3s5z_vs_3s6z 2%, 6h_vs_8z 3%).
SC2_QMIX_CURVE_STEP = 100_000
SC2_QMIX_CURVES: dict[str, tuple[float, ...]] = {
    "5m_vs_6m": (0.0, 0.01, 0.06, 0.21, 0.32, 0.47, 0.49, 0.56, 0.54, 0.57,
                 0.53, 0.64, 0.65, 0.6, 0.67, 0.69, 0.68, 0.69, 0.69, 0.65),
    "27m_vs_30m": (0.0, 0.0, 0.0, 0.0, 0.03, 0.03, 0.05, 0.08, 0.06, 0.11,
                   0.18, 0.11, 0.12, 0.23, 0.23, 0.32, 0.28, 0.36, 0.37, 0.4),
    "3s5z_vs_3s6z": (0.0, 0.0, 0.0, 0.0, 0.01, 0.01, 0.01, 0.01, 0.0, 0.01,
                     0.01, 0.0, 0.0, 0.01, 0.01, 0.0, 0.01, 0.01, 0.03, 0.02),
    "6h_vs_8z": (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.02,
                 0.03, 0.02, 0.04, 0.01, 0.0, 0.01, 0.03, 0.03, 0.03, 0.02),
    "MMM2": (0.0, 0.0, 0.0, 0.0, 0.01, 0.01, 0.03, 0.05, 0.09, 0.14,
             0.22, 0.2, 0.26, 0.48, 0.47, 0.46, 0.58, 0.6, 0.64, 0.64),
}


def sc2_qmix_at(map_name: str, t_env: float) -> float | None:
    """The SMAC paper's QMIX test win rate in SC2 at t_env (linear between its points, 0 at t_env 0; its last
    value past 2M); None for a map without a curve."""
    points = SC2_QMIX_CURVES.get(map_name)
    if points is None:
        return None
    grid = (0.0, *points)  # grid[k]: the win rate at k * SC2_QMIX_CURVE_STEP steps
    x = max(0.0, t_env / SC2_QMIX_CURVE_STEP)
    k = int(x)
    if k >= len(grid) - 1:
        return grid[-1]
    return grid[k] + (grid[k + 1] - grid[k]) * (x - k)


def curve(job_dir: Path, key: str = KEY) -> list[tuple[int, float]]:
    """(t_env, value) of one job over all its sacred runs (restarts), later runs superseding earlier ones."""
    runs = sorted((d for d in (job_dir / "sacred").glob("*/*") if d.name.isdigit() and d.parent.name.isdigit()),
                  key=lambda d: (int(d.parent.name), int(d.name)))
    points: list[tuple[int, float]] = []
    for run in runs:
        try:
            info = json.loads((run / "info.json").read_text())
        except (OSError, ValueError):
            continue
        ts, vs = info.get(f"{key}_T", []), info.get(key, [])
        seg = [(int(t), float(v)) for t, v in zip(ts, vs, strict=False)]
        if not seg:
            continue
        points = [p for p in points if p[0] < seg[0][0]] + seg
    return points


def recent_speed(job_dir: Path, window: int = 100_000) -> float | None:
    """env steps/s of the latest start over its last `window` steps, from sacred's metrics.json timestamps of the
    runner's stats (logged every runner_log_interval = 10000 steps)."""
    import datetime as dt

    runs = sorted((d for d in (job_dir / "sacred").glob("*/*") if d.name.isdigit() and d.parent.name.isdigit()),
                  key=lambda d: (int(d.parent.name), int(d.name)))
    if not runs:
        return None
    try:
        m = json.loads((runs[-1] / "metrics.json").read_text())["ep_length_mean"]
    except (OSError, ValueError, KeyError):
        return None
    steps, stamps = m["steps"], [dt.datetime.fromisoformat(t) for t in m["timestamps"]]
    if len(steps) < 2:
        return None
    i = next(k for k in range(len(steps)) if steps[-1] - steps[k] <= window or k == len(steps) - 2)
    secs = (stamps[-1] - stamps[i]).total_seconds()
    return (steps[-1] - steps[i]) / secs if secs > 0 else None


# sacred settings every run_reference.py job passes, or that name machine paths: not part of what tells runs apart
_ROUTINE_SETTINGS = ("env_args.map_name", "seed", "t_max", "save_model", "save_model_interval", "local_results_path",
                     "checkpoint_path", "load_step", "buffer_size")


def provenance(job_dir: Path) -> dict:
    """What a job ran: the engine fingerprint (engine.json), the smac-hard-gym and EPyMARL commits (each start's
    log header, written by run_reference.py; those of every start, in order, joined by ' then ') and the EPyMARL
    settings of its first start beyond the routine ones (e.g. ``runner=parallel``, ``use_rnn=True``)."""
    found: dict[str, list[str]] = {"smac_hard_gym": [], "epymarl": []}
    settings: list[str] | None = None
    for log in sorted((job_dir / "logs").glob("*.log"), key=lambda f: int(f.stem) if f.stem.isdigit() else 0):
        with open(log, errors="replace") as f:
            command, head = f.readline(), f.readline()
        if settings is None and " with " in command:
            settings = [w for w in command.split(" with ", 1)[1].split() if w.split("=")[0] not in _ROUTINE_SETTINGS]
        m = re.match(r"# smac-hard-gym (.+); EPyMARL (.+)", head.strip())
        if m:
            for name, rev in zip(("smac_hard_gym", "epymarl"), m.groups(), strict=True):
                if rev not in found[name]:
                    found[name].append(rev)
    try:
        engine = json.loads((job_dir / "engine.json").read_text())["fingerprint"]
    except (OSError, ValueError, KeyError):
        engine = "unrecorded"
    return {"engine": engine, **{k: " then ".join(v) or "unknown" for k, v in found.items()},
            "settings": settings or []}


def record(algo: str, map_name: str, seed: str, job_dir: Path) -> dict:
    """One run as kept on record: its curve and provenance, no paths."""
    return {"algo": algo, "map": map_name, "seed": seed, **provenance(job_dir),
            "done": (job_dir / "done.json").is_file(), KEY: [[t, v] for t, v in curve(job_dir)]}


def read_records(paths: list[Path]) -> list[dict]:
    runs = []
    for path in paths:
        data = json.loads(path.read_text())
        if not isinstance(data, dict) or not isinstance(data.get("runs"), list):
            raise SystemExit(f"{path}: not a report.py --record file (expected an object with a 'runs' list)")
        runs += data["runs"]
    return runs


def _identity(run: dict) -> tuple:
    """What tells two recorded runs apart: a live run replaces a recorded one with the same identity."""
    return run["algo"], run["map"], run["seed"], run["engine"], tuple(run.get("settings", ()))


def jobs(out: Path) -> list[tuple[str, str, str, Path]]:
    """(algo, map, seed-folder, dir) of every job folder under out (not the ``seed<n>.engine-<fingerprint>``
    folders that ``run_reference.py --restart-changed`` moved aside: runs on an earlier engine)."""
    found = []
    for d in sorted(out.glob("*/*/seed*")):
        if re.fullmatch(r"seed\d+", d.name) and ((d / "sacred").is_dir() or (d / "logs").is_dir()):
            found.append((d.parent.parent.name, d.parent.name, d.name, d))
    return found


# run_reference.py's own choice for QMIX (two envs, docs/reference_epymarl.md): not repeated on every row's label
_RUN_REFERENCE_DEFAULTS = ("runner=parallel", "batch_size_run=2")


class Row(NamedTuple):
    """One run in the table: its final win rate (mean of the last evaluations), how far it got, whether it
    finished, and the SMAC paper's QMIX in SC2 averaged over the same evaluation steps (None: no curve)."""

    seed: str
    final: float | None
    t_reached: int
    done: bool
    sc2_same_steps: float | None


def fmt(x: float | None) -> str:
    return "–" if x is None else f"{x:.3f}"


def atomic_write_text(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        f.write(text)
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)


def plot(path: Path, map_name: str, series: dict[str, list[tuple[int, float]]], t_max: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.6))
    for label, pts in sorted(series.items()):
        if pts:
            ax.plot([t / 1e6 for t, _ in pts], [v for _, v in pts], label=label, lw=1.2)
    sc2 = SC2_QMIX_CURVES.get(map_name)
    if sc2:
        ax.plot([k * SC2_QMIX_CURVE_STEP / 1e6 for k in range(len(sc2) + 1)], [0.0, *sc2], ls="--", color="k", lw=1,
                label="SC2 QMIX (SMAC paper)")
    paper = PAPER_2M_DEFAULT_OPPONENT.get(map_name)
    if paper:
        for algo, col, marker in (("qmix", 0, "o"), ("mappo", 1, "s")):
            ax.plot([2.0], [paper[col]], marker=marker, ls="none", color="k", mfc="none",
                    label=f"paper {algo.upper()} @2M")
    ax.set(xlim=(0, t_max / 1e6), ylim=(-0.02, 1.02), xlabel="env steps (M)", ylabel=KEY,
           title=f"{map_name}: EPyMARL vs SMAC's opponent")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=".png")
    os.close(fd)
    fig.savefig(tmp, dpi=110)
    plt.close(fig)
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, nargs="*", default=[],
                   help="run_reference.py --out folder(s); the report and curves are written to the first")
    p.add_argument("--records", type=Path, nargs="*", default=[], help="--record files to join as runs")
    p.add_argument("--record", type=Path, help="write the runs of the --out folders to this JSON file")
    p.add_argument("--last", type=int, default=3, help="final win rate = mean of the last N test evaluations")
    p.add_argument("--t-max", type=int, default=2_050_000)
    p.add_argument("--no-plots", action="store_true")
    args = p.parse_args(argv)
    if not args.out and not args.records:
        p.error("give --out folder(s), --records file(s) or both")
    folders = [o.expanduser().resolve() for o in args.out]
    all_jobs = [job for folder in folders for job in jobs(folder)]
    live = [record(algo, map_name, seed, d) for algo, map_name, seed, d in all_jobs]
    if args.record:
        atomic_write_text(args.record, json.dumps({"runs": live}, indent=1) + "\n")
    ident = {_identity(r) for r in live}
    runs = live + [r for r in read_records(args.records) if _identity(r) not in ident]

    rows: dict[str, dict[str, list[Row]]] = {}
    per_map: dict[str, dict[str, list[tuple[int, float]]]] = {}
    for run in runs:
        pts = [(int(t), float(v)) for t, v in run[KEY]]
        last = pts[-args.last:]
        final = sum(v for _, v in last) / len(last) if last else None
        sc2 = [sc2_qmix_at(run["map"], t) for t, _ in last]
        sc2_mean = sum(sc2) / len(sc2) if sc2 and None not in sc2 else None
        label = " ".join([run["seed"], *(w for w in run.get("settings", ()) if w not in _RUN_REFERENCE_DEFAULTS)])
        row = Row(label, final, pts[-1][0] if pts else 0, run["done"], sc2_mean)
        rows.setdefault(run["map"], {}).setdefault(run["algo"], []).append(row)
        per_map.setdefault(run["map"], {})[f"{run['algo']} {label}"] = pts  # runs with other settings: own curves

    lines = [
        "# EPyMARL reference runs vs SMAC's opponent (smac-hard-gym engine)",
        "",
        f"Ours: mean `{KEY}` of the last {args.last} test evaluations of each run (EPyMARL sc2.yaml: 100 greedy "
        "episodes every 50k steps), t_max 2.05M; `*` = run still in progress (value so far, t_env reached shown).",
        "Paper: SMAC-HARD (arXiv 2412.17707), appendix table *Final performance at 2M time step with default "
        "opponent policy* (QMIX = pymarl2, MAPPO = Yu et al.; 5 seeds, 32 test episodes).",
        "SC2 QMIX, same steps: the SMAC paper's pymarl QMIX in SC2 (mean of 5 runs) averaged over the t_env of "
        "the same evaluations as ours, so a run still going can be compared too (where that paper has a curve).",
        "",
        "| map | QMIX (ours) | QMIX (paper) | SC2 QMIX, same steps | MAPPO (ours) | MAPPO (paper) |",
        "|---|---|---|---|---|---|",
    ]

    def cell(entries: list[Row] | None) -> str:
        if not entries:
            return "not run"
        return "<br>".join(f"{fmt(r.final)}" + ("" if r.done else f"* ({r.t_reached / 1e6:.2f}M)") + f" [{r.seed}]"
                           for r in entries)

    def sc2_cell(entries: list[Row] | None) -> str:
        known = [r for r in entries or [] if r.sc2_same_steps is not None]
        return "<br>".join(f"{fmt(r.sc2_same_steps)} [{r.seed}]" for r in known) or "–"

    order = list(PAPER_2M_DEFAULT_OPPONENT)
    for map_name in sorted(rows, key=lambda m: (order.index(m) if m in order else len(order), m)):
        paper = PAPER_2M_DEFAULT_OPPONENT.get(map_name, (None, None))
        qmix = rows[map_name].get("qmix")
        lines.append(f"| {map_name} | {cell(qmix)} | {fmt(paper[0])} | {sc2_cell(qmix)} | "
                     f"{cell(rows[map_name].get('mappo'))} | {fmt(paper[1])} |")
    if not rows:
        lines.append("| (no runs found) | | | | | |")
    lines.append("")
    for algo, column in PAPER_COL.items():
        finished = {m: [r.final for r in entries[algo] if r.done and r.final is not None]
                    for m, entries in rows.items() if algo in entries and m in PAPER_2M_DEFAULT_OPPONENT}
        finished = {m: sum(v) / len(v) for m, v in finished.items() if v}
        maps = sorted(finished)
        rho = spearman([finished[m] for m in maps], [PAPER_2M_DEFAULT_OPPONENT[m][column] for m in maps])
        lines.append(f"Spearman, {algo.upper()} (finished runs) with the paper's {algo.upper()}: "
                     f"{'–' if math.isnan(rho) else f'{rho:.2f}'} over {len(maps)} maps ({', '.join(maps) or 'none'}).")
    lines.append("")
    if folders and not args.no_plots and per_map:
        out = folders[0]
        (out / "curves").mkdir(exist_ok=True)
        for map_name, series in per_map.items():
            plot(out / "curves" / f"{map_name}.png", map_name, series, args.t_max)
        lines.append("Curves: " + ", ".join(f"[{m}](curves/{m}.png)" for m in sorted(per_map)))
        lines.append("")
    lines += ["## Progress", "", "| run | t_env reached | steps/s (last 100k) | hours left at that rate |",
              "|---|---|---|---|"]
    for algo, map_name, seed, d in all_jobs:
        pts = curve(d, "ep_length_mean") or curve(d)
        t = pts[-1][0] if pts else 0
        done = (d / "done.json").is_file()
        v = None if done else recent_speed(d)
        left = "done" if done else ("–" if not v else f"{max(0, args.t_max - t) / v / 3600:.1f}")
        lines.append(f"| {algo}/{map_name}/{seed} | {t} | {'–' if v is None else f'{v:.0f}'} | {left} |")
    lines.append("")
    if folders:
        atomic_write_text(folders[0] / "report.md", "\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
