"""Queries over a ``bench vector`` results document (plain JSON data), shared by the targets, tables and plot."""

from __future__ import annotations

from typing import Any


def select_rows(doc: dict[str, Any], section: str, **match: Any) -> list[dict[str, Any]]:
    """The rows of ``section`` whose fields equal ``match``, in document order."""
    return [r for r in doc["results"] if r["section"] == section and all(r.get(k) == v for k, v in match.items())]


def best_row(doc: dict[str, Any], section: str, **match: Any) -> dict[str, Any] | None:
    """The fastest of those rows, or None."""
    return max(select_rows(doc, section, **match), key=lambda r: r["steps_per_second"], default=None)


def subproc_scaling(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """Per (map, K battles per worker) measured with one worker: steps/s (``sps_W``) and speed-up over one worker
    (``ratio_W``) for each worker count W, and the seconds one worker takes per step (``seconds_per_step_1``)."""
    out = []
    groups = {(r["map"], r["extra"]["envs_per_worker"]) for r in select_rows(doc, "subproc")}
    for name, k in sorted(groups):
        by_w = {r["workers"]: r for r in select_rows(doc, "subproc", map=name) if r["extra"]["envs_per_worker"] == k}
        if 1 not in by_w:
            continue
        one = by_w[1]["steps_per_second"]
        row = {"map": name, "k": k, "sps_1": one, "seconds_per_step_1": k / one}
        for w, r in by_w.items():
            row[f"sps_{w}"] = r["steps_per_second"]
            row[f"ratio_{w}"] = r["steps_per_second"] / one
        out.append(row)
    return out


def cores_lost(cpu: dict[str, float]) -> float:
    """Cores this benchmark could not have: those other processes used plus those the hypervisor stole."""
    return cpu.get("other_cores", 0.0) + cpu.get("stolen_cores", 0.0)


def cores_lost_text(row: dict[str, Any] | None) -> str:
    """Cores lost to other processes and the hypervisor while ``row`` was timed (its CpuMeter reading), or a dash."""
    cpu = (row or {}).get("extra", {}).get("cpu") or {}
    return f"{cores_lost(cpu):.1f}" if "other_cores" in cpu else "–"


def steps_per_cpu_second(row: dict[str, Any] | None) -> float | None:
    """Env steps per CPU-second of the measuring process(es): steps/s over the cores they used while timed."""
    cores = ((row or {}).get("extra", {}).get("cpu") or {}).get("our_cores")
    return row["steps_per_second"] / cores if cores else None
