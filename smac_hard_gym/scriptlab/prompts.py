"""The lab's prompts, built from the project's own sources so they never drift from the code:

- the map (:class:`~smac_hard_gym.maps.MapSpec`: units per side, size, pathable share, cliff levels, spawns,
  episode limit) and the unit table (:data:`smac_hard_gym.engine.units.UNITS`) for the unit types on the map;
- the script API from docstrings (``inspect``): :class:`SideView`, :class:`Script`, :class:`PerBattleScript`,
  :class:`BattleView`, :class:`UnitRows`, and the command constants of :mod:`smac_hard_gym.engine.state`;
- library scripts' source (``inspect.getsource``) as examples;
- the previous round's results table and the critic's advice.

Roles: a strategy **planner** (both sides), a **coder** per side (red, blue) and a **critic**. Every system prompt
starts with ``ROLE: <role>`` so a transcript (or a test's fake server) can tell them apart.
"""

from __future__ import annotations

import inspect
import re
from functools import lru_cache

import numpy as np

from smac_hard_gym.engine import state as engine_state
from smac_hard_gym.engine.units import (
    ARMORED,
    BIO,
    LIGHT,
    LOOPS_PER_SECOND,
    MASSIVE,
    MECH,
    STRUCTURE,
    UNITS,
    unit_index,
)
from smac_hard_gym.maps import MapSpec

__all__ = ["ROLES", "SCRIPT_CLASS", "map_summary", "unit_table", "api_reference", "example_sources",
           "environment_prompt", "planner_messages", "coder_messages", "critic_messages", "split_sections"]

SCRIPT_CLASS = "LabScript"  # the class every generated script defines: load it as "file.py:LabScript"
ROLES = ("planner", "red_coder", "blue_coder", "critic")
SIDES = ("red", "blue")
_ATTRIBUTES = ((LIGHT, "light"), (ARMORED, "armored"), (BIO, "biological"), (MECH, "mechanical"),
               (MASSIVE, "massive"), (STRUCTURE, "structure"))
_EXAMPLE_LINES = 60  # lines of a library script's source shown at most


def _units_of(groups) -> str:
    counts: dict[str, int] = {}
    for g in groups:
        counts[g.unit] = counts.get(g.unit, 0) + g.count
    return ", ".join(f"{n} x {u}" for u, n in counts.items())


def _spawn(groups) -> tuple[float, float]:
    pts = np.array([g.spawn for g in groups], dtype=float)
    w = np.array([g.count for g in groups], dtype=float)
    c = (pts * w[:, None]).sum(axis=0) / w.sum()
    return round(float(c[0]), 1), round(float(c[1]), 1)


def map_summary(spec: MapSpec) -> str:
    """The map's units, size, terrain and limits, as the engine loads them."""
    cliff = spec.cliff[spec.pathable]
    levels, counts = np.unique(cliff, return_counts=True) if cliff.size else (np.array([]), np.array([]))
    level_text = ", ".join(f"level {lv:g}: {c / max(1, cliff.size):.0%}" for lv, c in zip(levels, counts,
                                                                                          strict=True))
    order = spec.enemy_order
    order_text = order.kind + (f" to {order.point}" if order.point else "") + (
        f" between {list(order.points)}" if order.points else "")
    lines = [
        f"Map {spec.name}: {spec.size[0]} x {spec.size[1]} cells (x right, y up), "
        f"{spec.pathable.mean():.0%} of cells pathable for ground units; pathable cliff levels: {level_text}.",
        f"Red side ({spec.red_race}, the learner's side, slots 0..{spec.n_red - 1}): {_units_of(spec.red)}, "
        f"spawning around {_spawn(spec.red)}. Red units are SMAC's passive *_RL units: they never act on their own "
        "(not even to shoot back), so a red script must order every attack.",
        f"Blue side ({spec.blue_race}, the opponent, slots {spec.n_red}..{spec.n_red + spec.n_blue - 1}): "
        f"{_units_of(spec.blue)}, spawning around {_spawn(spec.blue)}. Blue units are standard units: idle or "
        "attack-moving units pick targets themselves.",
        f"SMAC's own blue behaviour on this map: {order_text}. Episode limit: {spec.episode_limit} env steps "
        "(one step = 8 game loops = 0.5 game seconds); reaching it is a draw. A side wins when all the other "
        "side's fighting units are dead.",
    ]
    return "\n".join(lines)


def _attributes(bits: int) -> str:
    return "/".join(name for bit, name in _ATTRIBUTES if bits & bit) or "-"


def unit_table(spec: MapSpec) -> str:
    """A table of the unit types on the map, from the engine's unit table (Normal game speed)."""
    header = ("| unit | health | shield | armor | damage x hits | bonus | cooldown s | range | speed/s | radius | "
              "attributes | notes |")
    rows = [header, "|" + "---|" * 12]
    seen: list[str] = []
    for g in (*spec.red, *spec.blue):
        if g.unit not in seen:
            seen.append(g.unit)
    for name in seen:
        u = UNITS[unit_index(name)]
        bonus = f"+{u.bonus_damage:g} vs {_attributes(u.bonus_attribute)}" if u.bonus_damage else "-"
        notes = []
        if u.is_air:
            notes.append("air")
        if u.cliff_walk:
            notes.append("walks cliffs")
        if u.splash_radius:
            notes.append(f"explodes, radius {u.splash_radius:g}")
        if u.splash_length:
            notes.append(f"line splash {u.splash_length:g} x {u.splash_width:g}")
        if u.heal_rate:
            notes.append(f"heals {u.heal_rate:.1f} HP/s")
        if not (u.hits_ground or u.hits_air or u.heal_rate):
            notes.append("no weapon")
        if u.regen:
            notes.append(f"regenerates {u.regen:g} HP/s")
        if u.passive:
            notes.append("passive (*_RL)")
        rows.append(f"| {name} | {u.health:g} | {u.shield:g} | {u.armor:g} | {u.damage:g} x {u.hits} | {bonus} | "
                    f"{u.cooldown / LOOPS_PER_SECOND:.2f} | {u.range:g} | {u.speed:.2f} | {u.radius:g} | "
                    f"{_attributes(u.attributes)} | {', '.join(notes) or '-'} |")
    return "\n".join(rows)


def _doc(obj: object) -> str:
    return inspect.cleandoc(inspect.getdoc(obj) or "")


def _members(cls: type, names: list[str] | None = None) -> list[str]:
    """``name(signature): first docstring paragraph`` for the public methods and properties of ``cls``."""
    out = []
    for name, member in cls.__dict__.items():
        if name.startswith("_") or (names is not None and name not in names):
            continue
        if isinstance(member, property):
            doc = _doc(member.fget) if member.fget is not None and member.fget.__doc__ else ""
            out.append(f"- {name}" + (f": {doc.splitlines()[0]}" if doc else ""))
        elif inspect.isfunction(member):
            sig = str(inspect.signature(member)).replace("self, ", "").replace("(self)", "()")
            doc = _doc(member)
            out.append(f"- {name}{sig}" + (f": {doc.split(chr(10) + chr(10))[0]}" if doc else ""))
    return out


def _commands() -> str:
    names = engine_state.COMMAND_NAMES
    consts = sorted((v, k) for k, v in vars(engine_state).items() if k.startswith("CMD_") and isinstance(v, int))
    lines = [f"- {k} = {v} ({names[v]})" for v, k in consts]
    return "\n".join(lines)


@lru_cache(maxsize=1)
def api_reference() -> str:
    """The script API, generated from the docstrings of the opponent modules and the engine's constants."""
    from smac_hard_gym.opponents import api, per_battle
    from smac_hard_gym.opponents.per_battle import BattleView, PerBattleScript, UnitRows

    unit_fields = [f"{n}" for n in ("type", "alive", "x", "y", "health", "shield", "energy", "cooldown", "order",
                                    "health_max", "shield_max", "radius", "range")]
    parts = [
        "## The opponent contract (smac_hard_gym.opponents.api)",
        _doc(api),
        "## Script", _doc(api.Script), "\n".join(_members(api.Script, ["reset", "act"])),
        "## SideView", _doc(api.SideView),
        "## Per-battle scripts (smac_hard_gym.opponents.per_battle): WRITE THIS KIND", _doc(per_battle),
        "### PerBattleScript", _doc(PerBattleScript),
        "\n".join(_members(PerBattleScript, ["reset_battle", "act_battle"])),
        "### BattleView (the `battle` argument)", _doc(BattleView),
        "Attributes: index, spec (the MapSpec: size, pathable[x, y], cliff[x, y]), side, step (env steps since the "
        "episode began), rng (seeded numpy Generator), memory (dict kept for the episode), own, enemy (UnitRows).",
        "\n".join(_members(BattleView)),
        "### UnitRows (`battle.own`, `battle.enemy`)", _doc(UnitRows),
        "1-D arrays over the side's units: " + ", ".join(unit_fields) + "; cooldown is in game loops (<= 0: the "
        "weapon is ready; one env step is 8 loops).", "\n".join(_members(UnitRows)),
        "## Command kinds (smac_hard_gym.engine.state)", _doc(engine_state.Commands), _commands(),
        "Invalid commands (attacking a dead or own unit, healing an enemy, non-finite points, writing another "
        "side's slots) end the script's run with an error.",
    ]
    return "\n\n".join(p for p in parts if p)


def _short_source(obj: object) -> str:
    lines = inspect.getsource(obj).splitlines()
    if len(lines) > _EXAMPLE_LINES:
        lines = lines[:_EXAMPLE_LINES] + ["    # ... (truncated)"]
    return "\n".join(lines)


def example_sources(spec: MapSpec) -> str:
    """Library scripts' source: the per-battle example shipped with the project's docs, a generic batched script
    and the first map script of the map's SMAC-HARD pool (batched scripts: read them for tactics)."""
    from smac_hard_gym.opponents import SCRIPTS, pool_for_map
    from smac_hard_gym.opponents.generic import FocusFire

    parts = ["### Library script `focus_fire` (batched form; shows a tactic, not the form to write)",
             "```python\n" + _short_source(FocusFire) + "\n```"]
    for name in pool_for_map(spec):
        if name in SCRIPTS and SCRIPTS[name].maps is not None:
            cls = type(SCRIPTS[name].factory())
            parts += [f"### Library script `{name}` from this map's SMAC-HARD pool (batched form)",
                      "```python\n" + _short_source(cls) + "\n```"]
            break
    return "\n\n".join(parts)


def _template(side: str) -> str:
    return f'''```python
import numpy as np

from smac_hard_gym.opponents import PerBattleScript


class {SCRIPT_CLASS}(PerBattleScript):
    """One line saying what this {side} script does."""

    name = "lab_{side}"
    description = "one line saying what it does"

    def reset_battle(self, battle):
        battle.memory["phase"] = 0

    def act_battle(self, battle):
        for i in battle.own.alive_indices():
            k = battle.nearest_enemy(i)
            if k >= 0:
                battle.attack(i, k)
```'''


def environment_prompt(spec: MapSpec) -> str:
    """The environment both sides share: the map and the unit data (the paper's environment prompt)."""
    return f"# Map\n{map_summary(spec)}\n\n# Units (from the engine's unit table)\n{unit_table(spec)}"


def _system(role: str, text: str) -> dict[str, str]:
    return {"role": "system", "content": f"ROLE: {role}\n{text}"}


def planner_messages(spec: MapSpec, table: str, advice: str) -> list[dict[str, str]]:
    """The planner's prompt: plan a strategy for each side, refined by the critic's advice."""
    system = _system("planner", "You are the strategy planner of a StarCraft II micro battle (SMAC-HARD). Plan a "
                     "decision-tree strategy for EACH side: targeting, positioning, retreat and focus rules that a "
                     "programmer can implement. Answer with two sections starting with lines 'RED:' and 'BLUE:'.")
    user = [environment_prompt(spec)]
    if table:
        user.append(f"# Results of the previous round\n{table}")
    if advice:
        user.append(f"# The critic's advice to you\n{advice}")
    user.append("Write the plan now: RED: ... BLUE: ... (each at most 15 short lines).")
    return [system, {"role": "user", "content": "\n\n".join(user)}]


def coder_messages(spec: MapSpec, side: str, plan: str, previous_code: str, feedback: str,
                   advice: str) -> list[dict[str, str]]:
    """A coder's prompt: implement this side's plan as one PerBattleScript subclass named ``LabScript``."""
    if side not in SIDES:
        raise ValueError(f"side must be one of {SIDES}, got {side!r}")
    system = _system(f"{side}_coder", f"You are the decision-tree coder of the {side.upper()} side. Write one "
                     f"Python module defining a class {SCRIPT_CLASS}, a subclass of PerBattleScript, that implements "
                     "the plan with the API below. Use only numpy and the smac_hard_gym package. Each act_battle call "
                     "must return quickly (well under a second). Answer with exactly one ```python code block.")
    user = [environment_prompt(spec), f"# Script API (generated from the package's docstrings)\n{api_reference()}",
            f"# Examples from the script library\n{example_sources(spec)}",
            f"# Template (the required form)\n{_template(side)}",
            f"# The plan for the {side.upper()} side\n{plan or '(no plan: choose a sound strategy)'}"]
    if previous_code:
        user.append(f"# Your script of the previous round\n```python\n{previous_code}\n```")
    if feedback:
        user.append(f"# Problems found when your last script was checked (fix them)\n{feedback}")
    if advice:
        user.append(f"# The critic's advice to you\n{advice}")
    user.append(f"Write the complete module now, defining class {SCRIPT_CLASS}.")
    return [system, {"role": "user", "content": "\n\n".join(user)}]


def critic_messages(spec: MapSpec, plan: str, table: str, feedback: dict[str, str]) -> list[dict[str, str]]:
    """The critic's prompt: read the duel results and advise the planner and both coders."""
    system = _system("critic", "You are the critic. Read the duel results of this round and give concrete "
                     "refinements. Answer with three sections starting with lines 'PLANNER:', 'RED CODER:' and "
                     "'BLUE CODER:'.")
    user = [map_summary(spec), f"# This round's plan\n{plan}", f"# Duel results\n{table}"]
    for side in SIDES:
        if feedback.get(side):
            user.append(f"# Problems of the {side} script\n{feedback[side]}")
    user.append("Write your advice now: PLANNER: ... RED CODER: ... BLUE CODER: ...")
    return [system, {"role": "user", "content": "\n\n".join(user)}]


def split_sections(text: str, labels: tuple[str, ...]) -> dict[str, str]:
    """Split ``text`` at lines starting with ``LABEL:`` (case-insensitive, markdown markers allowed); a label that
    is missing gets the whole text (so a reply that ignores the format still reaches everyone)."""
    pattern = re.compile(r"^[\s#*>_-]*(" + "|".join(re.escape(lb) for lb in labels) + r")\s*[*_]*\s*:",
                         re.IGNORECASE | re.MULTILINE)
    hits = list(pattern.finditer(text))
    out: dict[str, str] = {}
    for i, m in enumerate(hits):
        end = hits[i + 1].start() if i + 1 < len(hits) else len(text)
        key = next(lb for lb in labels if lb.lower() == m.group(1).lower())
        out[key] = (out.get(key, "") + "\n" + text[m.end():end].strip(" *_\n")).strip()
    return {lb: out.get(lb) or text.strip() for lb in labels}
