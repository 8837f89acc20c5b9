"""A results document as the published markdown: machine, noise, one table per section, targets and profiles."""

from __future__ import annotations

from typing import Any

import numpy as np

from smac_hard_gym.bench.document import (
    best_row,
    cores_lost,
    cores_lost_text,
    select_rows,
    steps_per_cpu_second,
    subproc_scaling,
)


def _fmt(x: float | None) -> str:
    if x is None:
        return "–"
    return f"{x / 1000:,.1f}k" if x >= 10_000 else f"{x:,.0f}"


def _spread(row: dict[str, Any]) -> str:
    runs = row["runs"]
    if len(runs) < 2:
        return ""
    return f" ({_fmt(min(runs))}–{_fmt(max(runs))})"


def markdown_report(doc: dict[str, Any], command: str = "") -> str:
    """The results document as markdown: machine, tables per section, SMAX ratios, targets, profiles, noise."""
    m = doc["machine"]
    out = ["# smac-hard-gym throughput", ""]
    out.append(f"Machine: {m['cpu']}, {m['cores']} cores, {m.get('memory_gib')} GiB; Python {m['python']}, "
               f"smac-hard-gym {m.get('smac_hard_gym')}, numpy {m['numpy']}, numba {m['numba']} "
               f"({m['numba_threads']} threads, {m.get('numba_threading_layer')}), gymnasium {m.get('gymnasium')}. "
               + (f"Run: {doc['started']} to {m['date']}." if doc.get("started") else f"Run ended {m['date']}."))
    src = doc.get("source") or {}
    if src:
        modified = src.get("git_modified")
        out.append(f"Code: commit {src.get('git_commit', 'unknown')}" + (f" with {len(modified)} modified files"
                   if modified else "") + f", simulator sources digest {src['source_digest']}.")
    for warning in doc.get("warnings", []):
        out.append(f"**Warning: {warning}.**")
    peer = doc.get("peer") or {}
    if peer.get("machine"):
        pm = peer["machine"]
        out.append(f"Peer: SMAX (jaxmarl {pm['jaxmarl']}, jax {pm['jax']} on {', '.join(pm['devices'])}), "
                   "`HeuristicEnemySMAX`, default options, in the same run.")
    cfg = doc["config"]
    out += ["", f"Unit: env steps per second (one step = 8 game loops of one battle; N battles stepped once = N). "
            f"Policy: uniform over legal actions. Resets included (SameStep autoreset). Median of {cfg['repeats']} "
            f"windows of ≥ {cfg['seconds']} s after two warm-up steps; (min–max) of the windows in brackets. "
            "Compile time excluded (see cold start)."]
    if command:
        out += ["", f"Command: `{command}`"]
    out += _noise_lines(doc)
    out += _native_table(doc)
    out += _subproc_table(doc)
    out += _ray_table(doc)
    out += _single_env_table(doc)
    out += _opponent_table(doc)
    out += _memory_lines(doc)
    out += _targets_table(doc)
    out += _profile_tables(doc)
    return "\n".join(out) + "\n"


def _noise_lines(doc: dict[str, Any]) -> list[str]:
    probes = [p["seconds"] for p in doc.get("cpu_probes", [])]
    if not probes:
        return []
    load = doc.get("load_average_start")
    readings = [r["extra"]["cpu"] for r in doc["results"] if "other_cores" in r.get("extra", {}).get("cpu", {})]
    others = [c["other_cores"] for c in readings]
    steal = [c.get("stolen_cores", 0.0) for c in readings]
    lost = [cores_lost(c) for c in readings]
    lines = ["", f"Noise: load average at start {', '.join(f'{x:.1f}' for x in load) if load else 'n/a'}; "
             f"whole run {doc.get('elapsed_seconds', 0) / 60:.1f} min; a single-thread CPU probe took "
             f"{min(probes):.2f}–{max(probes):.2f} s (it finds a free core even when the other one is taken, so it "
             "shows slowdowns of a core, not a lost core)."]
    if others:
        lines[-1] += (f" While figures were timed, other processes used {np.median(others):.1f} cores (median; "
                      f"max {max(others):.1f}) of the {doc['machine']['cores']} and the hypervisor stole up to "
                      f"{max(steal, default=0.0):.2f}; {sum(x >= 0.5 for x in lost)} of {len(lost)} figures lost "
                      "half a core or more. The \"cores lost\" columns give, per figure (ours / SMAX's), the cores "
                      "other processes used plus those the hypervisor stole while it was timed.")
    return lines


def _native_table(doc: dict[str, Any]) -> list[str]:
    rows = select_rows(doc, "native")
    if not rows:
        return []
    have_smax = bool(select_rows(doc, "smax", mode="scan"))
    head = "| map | N | native vector env | engine alone | peak KB/battle |"
    rule = "|---|---:|---:|---:|---:|"
    if have_smax:
        head += " SMAX (jit+scan) | ours / SMAX |"
        rule += "---:|---:|"
    head += " cores lost |"
    rule += "---:|"
    out = ["", f"## Native vector env through the gymnasium API (opponent `{doc['config']['opponent']}`)", "",
           head, rule]
    for r in rows:
        eng = next((e for e in select_rows(doc, "engine", map=r["map"], num_envs=r["num_envs"])), None)
        kb = "–" if r["peak_bytes_per_env"] is None else f"{r['peak_bytes_per_env'] / 1024:,.1f}"
        line = (f"| {r['map']} | {r['num_envs']} | {_fmt(r['steps_per_second'])}{_spread(r)} | "
                f"{_fmt(eng['steps_per_second']) if eng else '–'} | {kb} |")
        s = next(iter(select_rows(doc, "smax", mode="scan", map=r["map"], num_envs=r["num_envs"])), None)
        if have_smax:
            ratio = f"{r['steps_per_second'] / s['steps_per_second']:.2f}×" if s else "–"
            line += f" {_fmt(s['steps_per_second'])}{_spread(s)} | {ratio} |" if s else " – | – |"
        line += f" {cores_lost_text(r)}{' / ' + cores_lost_text(s) if s else ''} |"
        out.append(line)
    if have_smax:
        out += ["", "Best batch per map (the must-reach comparison), also per CPU-second: steps/s divided by the cores "
                "each process actually got while timed (on a shared machine the two rarely get the same):", "",
                "| map | ours (N) | SMAX (N) | ratio | ours per CPU-s | SMAX per CPU-s | ratio per CPU-s |",
                "|---|---:|---:|---:|---:|---:|---:|"]
        for name in dict.fromkeys(r["map"] for r in rows):
            ours, smax = best_row(doc, "native", map=name), best_row(doc, "smax", map=name, mode="scan")
            if ours and smax:
                a, b = steps_per_cpu_second(ours), steps_per_cpu_second(smax)
                out.append(f"| {name} | {_fmt(ours['steps_per_second'])} ({ours['num_envs']}) | "
                           f"{_fmt(smax['steps_per_second'])} ({smax['num_envs']}) | "
                           f"{ours['steps_per_second'] / smax['steps_per_second']:.2f}× | {_fmt(a)} | {_fmt(b)} | "
                           + (f"{a / b:.2f}× |" if a and b else "– |"))
    return out


def _subproc_table(doc: dict[str, Any]) -> list[str]:
    scaling = subproc_scaling(doc)
    if not scaling:
        return []
    workers = sorted({r["workers"] for r in select_rows(doc, "subproc")})
    out = ["", "## Subprocess vector env (workers × K battles each, one numba thread per worker)", "",
           "| map | K | " + " | ".join(f"{w} worker{'s' if w > 1 else ''}" for w in workers) + " | "
           + " | ".join(f"{w}w / 1w" for w in workers if w > 1) + " |",
           "|---|---:|" + "---:|" * (2 * len(workers) - 1)]
    out[-2] += " cores lost |"
    out[-1] += "---:|"
    for s in scaling:
        rows = {r["workers"]: r for r in select_rows(doc, "subproc", map=s["map"])
                if r["extra"]["envs_per_worker"] == s["k"]}
        out.append(f"| {s['map']} | {s['k']} | " + " | ".join(_fmt(s.get(f"sps_{w}")) for w in workers) + " | "
                   + " | ".join(f"{s[f'ratio_{w}']:.2f}×" if f"ratio_{w}" in s else "–" for w in workers if w > 1)
                   + " | " + " / ".join(cores_lost_text(rows.get(w)) for w in workers) + " |")
    out += ["", "Speed-up needs free cores: the last column gives the cores lost to other processes and the "
            "hypervisor while each worker count was timed (1 / 2 / 4 workers)."]
    return out


def _ray_table(doc: dict[str, Any]) -> list[str]:
    rows = select_rows(doc, "ray")
    if not rows:
        return []
    out = ["", "## Ray actors vs subprocess workers (× K battles each, one numba thread each, interleaved rounds)", "",
           "| map | K | transport | workers | steps/s | vs 1 of its kind | cores lost |",
           "|---|---:|---|---:|---:|---:|---:|"]
    for r in rows:
        one = next((o for o in rows if o["map"] == r["map"] and o["mode"] == r["mode"] and o["workers"] == 1
                    and o["extra"]["envs_per_worker"] == r["extra"]["envs_per_worker"]), None)
        ratio = f"{r['steps_per_second'] / one['steps_per_second']:.2f}×" if one else "–"
        out.append(f"| {r['map']} | {r['extra']['envs_per_worker']} | {r['mode']} | {r['workers']} | "
                   f"{_fmt(r['steps_per_second'])}{_spread(r)} | {ratio} | {cores_lost_text(r)} |")
    for p in doc.get("ray_payload", []):
        sizes = ", ".join(f"{k.replace('_', ' ')} {v:,.0f}" for k, v in p["bytes_per_step_per_actor"].items())
        out += ["", f"Bytes per step per actor, {p['map']} K={p['envs_per_actor']}: {sizes}."]
    return out


def _single_env_table(doc: dict[str, Any]) -> list[str]:
    rows = select_rows(doc, "starcraft2")
    if not rows:
        return []
    out = ["", "## One battle: `StarCraft2Env` on 3m in pymarl's loop (get_state, get_avail_actions, get_obs, step)",
           "", "| env | opponent | steps/s | episodes/s | cores lost |", "|---|---|---:|---:|---:|"]
    for r in rows:
        out.append(f"| StarCraft2Env | {r['opponent']} | {_fmt(r['steps_per_second'])}{_spread(r)} | "
                   f"{r['episodes_per_second']:,.1f} | {cores_lost_text(r)} |")
    labels = {"loop": "SMAX, Python loop over one jitted step (results stay in jax)",
              "pymarl": "SMAX, pymarl-style loop (obs, state, masks to numpy each step)"}
    for mode, label in labels.items():
        smax = best_row(doc, "smax", map="3m", mode=mode)
        if smax:
            out.append(f"| {label} | HeuristicEnemySMAX | {_fmt(smax['steps_per_second'])}{_spread(smax)} | – | "
                       f"{cores_lost_text(smax)} |")
    loop, ours = best_row(doc, "smax", map="3m", mode="loop"), best_row(doc, "starcraft2", opponent="base")
    if loop and ours:
        ratio = ours["steps_per_second"] / loop["steps_per_second"]
        out += ["", f"StarCraft2Env (base) / SMAX Python loop: {ratio:.2f}× (the must-reach comparison uses SMAX's "
                "faster loop)."]
    return out


def _opponent_table(doc: dict[str, Any]) -> list[str]:
    rows = select_rows(doc, "opponents")
    if not rows:
        return []
    n = rows[0]["num_envs"]
    out = ["", f"## Opponent cost: `base` vs the `default` mixture (N={n})", "",
           "| map | base | default | default / base |", "|---|---:|---:|---:|"]
    for name in dict.fromkeys(r["map"] for r in rows):
        base = next(iter(select_rows(doc, "opponents", map=name, opponent="base")), None)
        mix = next(iter(select_rows(doc, "opponents", map=name, opponent="default")), None)
        if base and mix:
            out.append(f"| {name} | {_fmt(base['steps_per_second'])} | {_fmt(mix['steps_per_second'])} | "
                       f"{mix['steps_per_second'] / base['steps_per_second']:.2f}× |")
    return out


def _memory_lines(doc: dict[str, Any]) -> list[str]:
    probes = doc.get("memory", [])
    if not probes:
        return []
    out = ["", "## Cold start and memory (fresh process)", "",
           "| map × N | import s | first step s | peak RSS growth per battle |", "|---|---:|---:|---:|"]
    for p in probes:
        out.append(f"| {p['map']} × {p['num_envs']} | {p['import_seconds']:.1f} | {p['cold_start_seconds']:.1f} | "
                   f"{p['rss_bytes_per_env'] / 1024:,.1f} KB |")
    out += ["", "First step = import + building one env + its first step (numba's on-disk cache loaded, or compiled "
            "on a cold cache). Peak RSS growth: VmHWM after building N battles and 5 steps, minus RSS with a "
            "warmed one-battle env. The native table's KB/battle is tracemalloc's peak over build, reset and two "
            "steps."]
    return out


def _targets_table(doc: dict[str, Any]) -> list[str]:
    targets = doc.get("must_reach") or []
    if not targets:
        return []
    out = ["", "## Must-reach targets", "", "| target | measured | needed | result | detail |",
           "|---|---:|---:|---|---|"]
    for t in targets:
        unit = " KB" if "memory" in t["target"] else "×"
        verdict = "hit" if t["hit"] else "miss"
        how = f"{t['margin']:.2f}× the target" if t["hit"] else f"{t['margin']:.0%} of the target"
        out.append(f"| {t['target']} | {t['value']:,.2f}{unit} | {t['threshold']:g}{unit} | {verdict} ({how}) | "
                   f"{t['detail']} |")
    return out


def _profile_tables(doc: dict[str, Any]) -> list[str]:
    profiles = doc.get("profiles") or []
    if not profiles:
        return []
    labels = list(dict.fromkeys(k for p in profiles for k in p["share"]))
    cols = [f"{p['what']} {p['map']} N={p['num_envs']}" for p in profiles]
    out = ["", "## Where a step's time goes (wall-time share; µs per vector step in brackets)", "",
           "| part | " + " | ".join(cols) + " |", "|---|" + "---:|" * len(cols)]
    for label in labels:
        cells = []
        for p in profiles:
            share, us = p["share"].get(label), p["us_per_step"].get(label)
            cells.append("–" if share is None else f"{share:.0%} ({us:,.0f})")
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    out.append("| steps/s while profiled | " + " | ".join(_fmt(p["steps_per_second"]) for p in profiles) + " |")
    out += ["", "The overhead row is everything not in a named part (env and core bookkeeping in Python, infos, "
            "autoreset)."]
    return out
