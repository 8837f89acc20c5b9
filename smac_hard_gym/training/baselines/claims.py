"""The paper's claims checked on a sweep's finished maps (:func:`findings`): is the mixed pool, and black-box play,
harder than SMAC's opponent, and do our tables rank the maps as the paper's do (Spearman's correlation)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from smac_hard_gym.training.baselines.paper import MAP_ORDER, PAPER
from smac_hard_gym.training.baselines.planning import SWEEP_OPPONENTS
from smac_hard_gym.training.evaluation import MIXTURE_ROW

__all__ = ["findings", "findings_markdown", "spearman", "average_ranks", "HARDER_BY"]

HARDER_BY = 1 / 32  # one test episode of each seed's 32: a smaller gap between two cells is counted level


RANKED = (("smac", "smac", "smac_2m"), ("default", "default", "default_10m"), ("default", "default", "default_2m"),
          ("black-box", MIXTURE_ROW, "blackbox_10m"))


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
    table.update({(r["map"], MIXTURE_ROW): r for r in results.get("blackbox", []) if r["script"] == MIXTURE_ROW})
    seeds = max((r["seeds"] for r in table.values()), default=0)
    maps = [m for m in MAP_ORDER if all(table.get((m, o), {}).get("seeds") == seeds for o in SWEEP_OPPONENTS)]

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
            "blackbox_vs_smac": against_smac(MIXTURE_ROW), "spearman": ranked}


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
