"""Battle state and command arrays: every field is a NumPy array shaped (B, U) over B battles and U unit slots.

Slots ``0 .. n_red-1`` hold the learner's (red) units in SMAC's agent order, the rest the opponent's (blue) units in
creation order (SMAC's enemy order). The arrays are the engine's public contract: the SMAC feature layer, opponent
scripts, renderers and the sc2 backend read them (the sc2 backend also writes them from raw observations).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# Orders a unit can be carrying out (``BattleState.order``).
ORDER_IDLE, ORDER_MOVE, ORDER_ATTACK, ORDER_ATTACK_MOVE, ORDER_HOLD, ORDER_HEAL = 0, 1, 2, 3, 4, 5

# Commands a controller can send (``Commands.kind``). NOOP keeps the current order.
CMD_NOOP, CMD_STOP, CMD_HOLD, CMD_MOVE, CMD_ATTACK, CMD_ATTACK_MOVE, CMD_HEAL = 0, 1, 2, 3, 4, 5, 6
COMMAND_NAMES = ("noop", "stop", "hold", "move", "attack", "attack_move", "heal")

RED, BLUE = 0, 1
NO_UNIT = -1

# What a unit did in the current game loop's movement (``BattleState.stance``), read by separation: SC2 lets a unit
# that walks push its own side's idle units but not units standing to fire, and enemies push nobody
# (docs/engine_rules.md, section 1). The kind is ``stance & STANCE_KIND``; ``STANCE_BLOCKED`` is a flag on top of it:
# the unit walked into a unit that does not give way, so its next step steers round (section 1, C11). While it goes
# round, ``STANCE_LEFT`` or ``STANCE_RIGHT`` keeps the side it took, so it does not swing back into the pocket it
# left; of two own walkers that meet going round the opposite ways, one takes the other's side (``STANCE_YIELDS``
# marks it only while movement decides that; section 8, C14).
STANCE_NONE, STANCE_WALKED, STANCE_FIRING = 0, 1, 2
STANCE_KIND, STANCE_BLOCKED, STANCE_LEFT, STANCE_RIGHT = 3, 4, 8, 16
STANCE_SIDE = STANCE_LEFT | STANCE_RIGHT
STANCE_YIELDS = 32


class BattleState(NamedTuple):
    """State of B battles (arrays (B, U) unless noted). Health and shields are current values."""

    utype: np.ndarray  # int32: row of the unit table (fixed per slot by the map's layout)
    side: np.ndarray  # int8: RED or BLUE
    alive: np.ndarray  # bool
    x: np.ndarray  # float64 world position
    y: np.ndarray  # float64
    health: np.ndarray  # float64
    shield: np.ndarray  # float64
    energy: np.ndarray  # float64
    cooldown: np.ndarray  # float64: game loops until the weapon can fire (<= 0: ready)
    shield_wait: np.ndarray  # float64: loops until shields start to regenerate
    order: np.ndarray  # int8: ORDER_*
    order_target: np.ndarray  # int32: unit slot of an attack/heal order
    order_x: np.ndarray  # float64: point of a move/attack-move order
    order_y: np.ndarray  # float64
    target: np.ndarray  # int32: unit the weapon (or heal) is engaging now, NO_UNIT if none
    attacker: np.ndarray  # int32: last unit that damaged this one (SC2's "response when attacked")
    help_at: np.ndarray  # int64: battle loop from which this unit can call for help again (SC2's CallForHelpPeriod)
    fired_at: np.ndarray  # int32: last unit fired at (or healed) during the latest env step, for rendering
    burst: np.ndarray  # bool: a baneling that exploded during the latest env step
    alive_at_loop: np.ndarray  # bool scratch: alive when the current game loop began (simultaneous fire)
    stance: np.ndarray  # int8: STANCE_* of the current loop's movement (who may push whom), plus the blocked flag
    pending_target: np.ndarray  # int32: unit a delayed hit will land on (missile in flight, zealot's second blade)
    pending_eta: np.ndarray  # int32: game loops until that hit lands
    pending_hits: np.ndarray  # int8: how many of the weapon's hits land then
    windup: np.ndarray  # int32: game loops left of the attack's wind-up (SC2's damage point) before the shot
    windup_target: np.ndarray  # int32: unit the weapon is winding up against, NO_UNIT when not winding up
    loop: np.ndarray  # int64 (B,): game loops since the battle's reset
    rng: np.ndarray  # uint64 (B,): the battle's random stream (weapon cooldown jitter), seeded at reset


class Commands(NamedTuple):
    """Per-unit commands for one env step (arrays (B, U)); NOOP everywhere means "keep the current orders"."""

    kind: np.ndarray  # int8: CMD_*
    target: np.ndarray  # int32: unit slot for attack/heal
    x: np.ndarray  # float64: point for move/attack-move
    y: np.ndarray  # float64

    @classmethod
    def empty(cls, batch: int, n_units: int) -> Commands:
        return cls(
            kind=np.zeros((batch, n_units), dtype=np.int8),
            target=np.full((batch, n_units), NO_UNIT, dtype=np.int32),
            x=np.zeros((batch, n_units), dtype=np.float64),
            y=np.zeros((batch, n_units), dtype=np.float64),
        )

    def clear(self) -> None:
        """Reset every command to NOOP in place."""
        self.kind[:] = CMD_NOOP
        self.target[:] = NO_UNIT


class Scratch(NamedTuple):
    """Working arrays of the step kernels, (B, U) like the state, allocated once per engine (``BattleEngine``).

    Nothing outside a step reads them, and no step's outcome depends on what a previous step left in them (``by_x``
    is only a faster starting point for the next sort).

    by_x: int32 slots: each battle's slots in x order, for separation's sweep; kept between steps, when it is nearly
        sorted (any permutation of the slots is valid).
    key: float64 world x of ``by_x``'s slots (the sort's keys).
    engaged: int32 slot: each unit's target when the current game loop began (targeting's "who attacks me").
    x0, y0: float64 world position of each unit when movement began (units move simultaneously); separation then
        sums its pushes in them (world units).
    life0: float64 health plus shields of each unit after the loop's timers, as its attacks find them (who was hit
        calls for help).
    """

    by_x: np.ndarray
    key: np.ndarray
    engaged: np.ndarray
    x0: np.ndarray
    y0: np.ndarray
    life0: np.ndarray

    @classmethod
    def empty(cls, batch: int, n_units: int) -> Scratch:
        return cls(
            by_x=np.tile(np.arange(n_units, dtype=np.int32), (batch, 1)),
            key=np.zeros((batch, n_units), dtype=np.float64),
            engaged=np.zeros((batch, n_units), dtype=np.int32),
            x0=np.zeros((batch, n_units), dtype=np.float64),
            y0=np.zeros((batch, n_units), dtype=np.float64),
            life0=np.zeros((batch, n_units), dtype=np.float64),
        )


_FIELD_DTYPES = {
    "utype": np.int32, "side": np.int8, "alive": np.bool_, "x": np.float64, "y": np.float64,
    "health": np.float64, "shield": np.float64, "energy": np.float64, "cooldown": np.float64,
    "shield_wait": np.float64, "order": np.int8, "order_target": np.int32, "order_x": np.float64,
    "order_y": np.float64, "target": np.int32, "attacker": np.int32, "help_at": np.int64,
    "fired_at": np.int32, "burst": np.bool_, "alive_at_loop": np.bool_, "stance": np.int8,
    "pending_target": np.int32, "pending_eta": np.int32, "pending_hits": np.int8,
    "windup": np.int32, "windup_target": np.int32,
}


def allocate_state(batch: int, n_units: int) -> BattleState:
    """Zeroed state for ``batch`` battles of ``n_units`` slots."""
    arrays = {name: np.zeros((batch, n_units), dtype=dt) for name, dt in _FIELD_DTYPES.items()}
    for name in ("order_target", "target", "attacker", "fired_at", "pending_target", "windup_target"):
        arrays[name][:] = NO_UNIT
    return BattleState(**arrays, loop=np.zeros(batch, dtype=np.int64), rng=np.zeros(batch, dtype=np.uint64))


def state_nbytes(state: BattleState) -> int:
    return sum(a.nbytes for a in state)
