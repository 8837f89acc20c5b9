"""The must-reach targets, checked against a results document."""

from __future__ import annotations

from typing import Any

from smac_hard_gym.bench.document import best_row, cores_lost_text, select_rows, steps_per_cpu_second, subproc_scaling


def must_reach(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """The issue's targets against this document: measured value, threshold, hit, and the configurations used."""
    targets = []
    for name in ("3m", "8m", "27m_vs_30m"):
        ours, smax = best_row(doc, "native", map=name), best_row(doc, "smax", map=name, mode="scan")
        if ours and smax:
            a, b = steps_per_cpu_second(ours), steps_per_cpu_second(smax)
            per_cpu = f"; per CPU-second {a / b:.2f}×" if a and b else ""
            targets.append(_target(f"native best batch >= 5x SMAX best batch, {name}", ours["steps_per_second"]
                                   / smax["steps_per_second"], 5.0, f"ours N={ours['num_envs']} "
                                   f"{ours['steps_per_second']:,.0f} vs SMAX N={smax['num_envs']} "
                                   f"{smax['steps_per_second']:,.0f} steps/s{per_cpu}"))
    sc2, loop = best_row(doc, "starcraft2", map="3m", opponent="base"), best_row(doc, "smax", map="3m", mode="loop")
    if sc2 and loop:
        a, b = steps_per_cpu_second(sc2), steps_per_cpu_second(loop)
        per_cpu = f"; per CPU-second {a / b:.2f}×" if a and b else ""
        targets.append(_target("StarCraft2Env 3m B=1 >= 2x SMAX single-env Python loop", sc2["steps_per_second"]
                               / loop["steps_per_second"], 2.0, f"{sc2['steps_per_second']:,.0f} vs "
                               f"{loop['steps_per_second']:,.0f} steps/s{per_cpu}"))
    scaling = [s for s in subproc_scaling(doc) if "ratio_2" in s]
    if scaling:
        # "Where the environment dominates": the configuration whose one-worker step takes longest.
        heavy = max(scaling, key=lambda s: s["seconds_per_step_1"])
        rows = {r["workers"]: r for r in select_rows(doc, "subproc", map=heavy["map"])
                if r["extra"]["envs_per_worker"] == heavy["k"]}
        targets.append(_target("subprocess 2 workers >= 1.7x 1 worker (env-dominated)", heavy["ratio_2"], 1.7,
                               f"{heavy['map']} K={heavy['k']}: {heavy['sps_1']:,.0f} -> {heavy['sps_2']:,.0f} "
                               f"steps/s; cores lost to others meanwhile {cores_lost_text(rows.get(1))} / "
                               f"{cores_lost_text(rows.get(2))}"))
    ray_rows = {r["workers"]: r for r in select_rows(doc, "ray", map="27m_vs_30m", mode="ray")
                if r["extra"]["envs_per_worker"] == 256}
    if 1 in ray_rows and 2 in ray_rows:
        one, two = ray_rows[1], ray_rows[2]
        targets.append(_target("Ray 2 actors >= 1.5x 1 actor, 27m_vs_30m K=256", two["steps_per_second"]
                               / one["steps_per_second"], 1.5,
                               f"{one['steps_per_second']:,.0f} -> {two['steps_per_second']:,.0f} steps/s "
                               f"(medians of {len(two['runs'])} interleaved rounds); cores lost to others meanwhile "
                               f"{cores_lost_text(one)} / {cores_lost_text(two)}"))
    for probe in doc.get("memory", []):
        if probe["map"] == "3m" and probe["num_envs"] == 4096:
            traced = next((r["peak_bytes_per_env"] for r in select_rows(doc, "native", map="3m", num_envs=4096)
                           if r["peak_bytes_per_env"] is not None), None)
            worst = max(probe["rss_bytes_per_env"], traced or 0.0)
            targets.append(_target("peak memory, 3m x 4096 <= 100 KB per battle", worst / 1024, 100.0,
                                   f"RSS growth {probe['rss_bytes_per_env'] / 1024:,.1f} KB, traced peak "
                                   f"{(traced or 0) / 1024:,.1f} KB per battle", lower_is_better=True))
    return targets


def _target(name: str, value: float, threshold: float, detail: str, lower_is_better: bool = False) -> dict:
    hit = value <= threshold if lower_is_better else value >= threshold
    return {"target": name, "value": value, "threshold": threshold, "hit": bool(hit),
            "margin": (threshold / value if lower_is_better else value / threshold) if value else 0.0,
            "detail": detail}
