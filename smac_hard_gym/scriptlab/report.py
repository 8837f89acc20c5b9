"""The lab's files: per-round tables, the kept scripts, the pool file, report.md; and the readers of a lab's folder
(:func:`list_scripts` for ``smac-hard-gym scripts --path DIR``, :func:`load_pool` for the pool file).

Layout of ``out/``::

    transcript.jsonl        every prompt and reply (client.Transcript; never the API key)
    round_k/red.py, blue.py what the coders sent (written even when it failed its checks)
    round_k/table.csv, table.json, round.md   the round's duels, scores, feedback and advice
    red.py, blue.py         the kept scripts (the last that passed): opponent="out/blue.py:LabScript"
    pool.json               the kept blue script mixed with the map's SMAC-HARD pool (load_pool)
    report.md               the summary
"""

from __future__ import annotations

import ast
import csv
import io
import json
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any

from smac_hard_gym.files import write_json, write_text
from smac_hard_gym.maps import MapSpec
from smac_hard_gym.scriptlab.judging import PairingResult, format_table
from smac_hard_gym.scriptlab.prompts import SCRIPT_CLASS

if TYPE_CHECKING:
    from smac_hard_gym.scriptlab.client import ChatClient
    from smac_hard_gym.scriptlab.loop import LabResult, RoundRecord

__all__ = ["SCRIPT_CLASS", "POOL_FILE", "write_round", "keep_scripts", "write_pool", "load_pool", "write_report",
           "list_scripts"]

POOL_FILE = "pool.json"
_CSV_FIELDS = [f for f in PairingResult.__dataclass_fields__ if f != "lab_sides"] + ["lab_sides", "red_win_rate",
                                                                                    "blue_win_rate"]


def _csv(rows: list[PairingResult]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=_CSV_FIELDS)
    writer.writeheader()
    for row in rows:
        d = row.to_dict()
        d["lab_sides"] = "+".join(row.lab_sides)
        writer.writerow(d)
    return buffer.getvalue()


def write_round(folder: Path, record: RoundRecord) -> None:
    """``table.csv``, ``table.json`` and ``round.md`` of one round."""
    folder.mkdir(parents=True, exist_ok=True)
    write_text(folder / "table.csv", _csv(record.rows))
    write_json(folder / "table.json", {
        "round": record.number, "scores": record.scores, "pairings": [r.to_dict() for r in record.rows],
        "checks": {s: {"ok": c.ok, "feedback": c.feedback, "path": str(c.path) if c.path else None}
                   for s, c in record.checks.items()},
        "tokens": {"prompt": record.prompt_tokens, "completion": record.completion_tokens},
        "seconds": {"llm": round(record.llm_seconds, 3), "checks": round(record.check_seconds, 3),
                    "judging": round(record.judge_seconds, 3)}}, indent=1)
    parts = [f"# Round {record.number}", "## Plan", record.plan, "## Duels", format_table(record.rows)]
    for side, check in record.checks.items():
        parts.append(f"## {side} script: " + ("passed" if check.ok else "failed") +
                     (f"\n\n{check.feedback}" if check.feedback else ""))
    if record.advice:
        parts += ["## Critic's advice"] + [f"**{k}**: {v}" for k, v in record.advice.items()]
    write_text(folder / "round.md", "\n\n".join(parts) + "\n")


def write_pool(out: Path, spec: MapSpec, blue: Path) -> Path:
    """``out/pool.json``: the kept blue script with the map's SMAC-HARD pool, equal weights (edit them freely)."""
    from smac_hard_gym.opponents import pool_for_map

    names = [f"{blue.name}:{SCRIPT_CLASS}", *pool_for_map(spec)]
    doc = {"map": spec.name, "opponent": names, "opponent_probs": [round(1 / len(names), 6)] * len(names),
           "note": "file references are relative to this file; load with smac_hard_gym.scriptlab.load_pool"}
    path = out / POOL_FILE
    write_json(path, doc, indent=1)
    return path


def load_pool(path: str | Path) -> tuple[list[str], list[float] | None]:
    """(opponent, opponent_probs) of a pool file, file references made absolute: pass them to any env or
    ``make_opponent`` (``opponent=..., opponent_probs=...``); a file script in it runs in the sandbox."""
    from smac_hard_gym.opponents.loader import is_reference

    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise ValueError(f"cannot read pool file {str(path)!r}: {err}") from None
    names = doc.get("opponent") if isinstance(doc, dict) else None
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        raise ValueError(f"pool file {str(path)!r} needs an 'opponent' list of script names or references")
    probs = doc.get("opponent_probs")
    if probs is not None and (not isinstance(probs, list) or len(probs) != len(names)):
        raise ValueError(f"pool file {str(path)!r}: 'opponent_probs' must list one weight per opponent")
    out = []
    for name in names:
        target, sep, cls = name.rpartition(":") if name.count(":") == 1 else (name, "", "")
        if is_reference(name) and target.endswith(".py") and not Path(target).is_absolute():
            name = f"{(path.parent / target).resolve()}{sep}{cls}"
        out.append(name)
    if probs is not None:
        total = sum(float(p) for p in probs)
        probs = [float(p) / total for p in probs] if total > 0 else None  # rounded weights: renormalised
    return out, probs


def keep_scripts(out: Path, spec: MapSpec, paths: dict[str, Path | None]) -> dict[str, Path]:
    """Copy each side's last passing script to ``out/<side>.py`` (and write the pool file for the blue one)."""
    kept: dict[str, Path] = {}
    for side, src in paths.items():
        if src is not None and Path(src).is_file():
            dst = out / f"{side}.py"
            shutil.copyfile(src, dst)
            kept[side] = dst
    if "blue" in kept:
        write_pool(out, spec, kept["blue"])
    return kept


def write_report(out: Path, result: LabResult, client: ChatClient) -> Path:
    """``out/report.md``: rounds, scores, costs, the final table and how to use the kept scripts."""
    config, rounds = result.config, result.rounds
    lines = [f"# Script lab: {config.map_name}", "",
             f"Model `{client.model}` at `{client.endpoint}`; {len(rounds)} round(s) of at most {config.rounds}, "
             f"{config.episodes} seeded episodes per pairing (seed {config.seed}), tolerance {config.tolerance}. "
             + ("Both sides' win rates settled." if result.settled else "The win rates did not settle "
                "(stopped at the round limit)." if not result.error else f"Stopped early: {result.error}"), "",
             "| round | red script | blue script | red score | blue score | prompt tokens | completion tokens | "
             "LLM s | checks s | judging s |", "|" + "---|" * 10]
    for r in rounds:
        def status(side: str, r: Any = r) -> str:
            c = r.checks.get(side)
            return "passed" if c is not None and c.ok else "failed"

        def score(side: str, r: Any = r) -> str:
            v = r.scores.get(side)
            return "-" if v is None else f"{v:.2f}"

        lines.append(f"| {r.number} | {status('red')} | {status('blue')} | {score('red')} | {score('blue')} | "
                     f"{r.prompt_tokens} | {r.completion_tokens} | {r.llm_seconds:.1f} | {r.check_seconds:.1f} | "
                     f"{r.judge_seconds:.1f} |")
    lines += ["", f"Total: {client.calls} LLM calls, {client.prompt_tokens} prompt and {client.completion_tokens} "
              "completion tokens.", ""]
    if rounds:
        lines += [f"## Last round's duels (round {rounds[-1].number})", "", format_table(rounds[-1].rows), ""]
    lines += ["## Kept scripts", ""]
    if not result.kept:
        lines.append("None: no script passed its checks.")
    for side, path in result.kept.items():
        lines.append(f"- {side}: `{path.name}` (`opponent=\"{path}:{SCRIPT_CLASS}\"`; runs in the process sandbox)")
    if "blue" in result.kept:
        lines += ["", f"Pool: `{POOL_FILE}` mixes the blue script with the map's SMAC-HARD pool:", "",
                  "```python", "from smac_hard_gym.scriptlab import load_pool",
                  f"opponent, probs = load_pool(\"{out / POOL_FILE}\")",
                  f"env = StarCraft2Env(map_name=\"{config.map_name}\", opponent=opponent, opponent_probs=probs)",
                  "```"]
    lines += ["", "Every prompt and reply: `transcript.jsonl`; each round's tables: `round_k/table.csv|json`."]
    path = out / "report.md"
    write_text(path, "\n".join(lines) + "\n")
    return path


def _const(node: ast.AST) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def _describe(tree: ast.Module) -> list[dict[str, str]]:
    """The script classes of a module, read from its syntax tree (the file is never imported or run)."""
    found = []
    aliases = {t.id: n.value.id for n in tree.body if isinstance(n, ast.Assign) and isinstance(n.value, ast.Name)
               for t in n.targets if isinstance(t, ast.Name)}
    for node in tree.body:
        if not isinstance(node, ast.ClassDef):
            continue
        bases = [ast.unparse(b) for b in node.bases]
        if not any(b.endswith("Script") for b in bases):
            continue
        attrs = {t.id: _const(n.value) for n in node.body if isinstance(n, ast.Assign)
                 for t in n.targets if isinstance(t, ast.Name)}
        doc = (ast.get_docstring(node) or "").split("\n")[0]
        found.append({"class": node.name, "name": attrs.get("name") or node.name,
                      "description": attrs.get("description") or doc,
                      "aliases": [a for a, target in aliases.items() if target == node.name]})
    return found


def list_scripts(folder: str | Path) -> list[dict[str, str]]:
    """Every script class in the ``.py`` files of ``folder`` (and its ``round_*`` folders), as ``file``, ``class``,
    ``name``, ``description`` and ``reference`` (what ``opponent=`` takes). Files are parsed, never run."""
    folder = Path(folder)
    if not folder.is_dir():
        raise FileNotFoundError(f"no folder {str(folder)!r}")
    files = sorted(folder.glob("*.py")) + sorted(folder.glob("round_*/*.py"),
                                                 key=lambda p: (len(p.parent.name), p.parent.name, p.name))
    out = []
    for path in files:
        try:
            tree = ast.parse(path.read_text(encoding="utf-8", errors="replace"))
        except SyntaxError as err:
            out.append({"file": str(path), "class": "", "name": "", "description": f"(does not parse: {err.msg}, "
                        f"line {err.lineno})", "reference": ""})
            continue
        for info in _describe(tree):
            cls = SCRIPT_CLASS if SCRIPT_CLASS in info["aliases"] else info["class"]
            out.append({"file": str(path), "class": cls, "name": info["name"], "description": info["description"],
                        "reference": f"{path}:{cls}"})
    return out
