"""Neither side is favoured by the engine itself: order-free mechanics and mirrored battles.

SMAC's symmetric maps put the same army on both sides, mirrored through the map's vertical centre line. With the same
unit types on both sides (the learner's ``*_RL`` copies replaced by the standard units), the same orders mirrored and
no random weapon delay, the battle must stay the exact mirror image of itself every game loop: any mechanic that
resolves units one slot after another (red slots come first) would break the symmetry and hand one side a systematic
edge. Before the fix, pairwise pushes resolved in sweep order and heals landed between red's and blue's shots; the
same script on both sides then won 2s3z 64-0 for red.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from engine_helpers import WIND_UP, battle_rows_of, engine_with, on_grid

from smac_hard_gym.engine import CMD_ATTACK, CMD_ATTACK_MOVE, BattleEngine, Commands
from smac_hard_gym.engine.kernels import _separation
from smac_hard_gym.engine.state import ORDER_IDLE
from smac_hard_gym.engine.units import STATS, unit_index
from smac_hard_gym.maps import load_map


def _standard_units_on_both_sides(map_name: str):
    spec = load_map(map_name)
    standard = tuple(dataclasses.replace(g, unit=g.unit.replace("Colosus_RL", "Colossus").replace("_RL", ""))
                     for g in spec.red)
    return dataclasses.replace(spec, red=standard)


def _mirror_partners(engine: BattleEngine, width: float) -> np.ndarray:
    """For each slot, the slot of the other side with the same type standing at its mirror point."""
    st = engine.state
    x, y, utype = st.x[0], st.y[0], st.utype[0]
    red = np.arange(x.size) < engine.n_red
    partner = np.empty(x.size, dtype=np.int64)
    for i in range(x.size):
        d = np.hypot(x - (width - x[i]), y - y[i])
        d[(red == red[i]) | (utype != utype[i])] = np.inf
        partner[i] = int(d.argmin())
        assert d[partner[i]] < 1e-5, f"slot {i} has no mirror partner"
    return partner


@pytest.mark.parametrize("map_name", ["3m", "8m", "2s3z", "3s5z", "MMM", "1c3s5z"])
def test_a_mirrored_battle_stays_the_mirror_image_of_itself_every_loop(map_name):
    spec = _standard_units_on_both_sides(map_name)
    width = float(spec.size[0])
    engine = BattleEngine(spec, batch_size=1, cooldown_jitter=None)
    st = engine.state
    partner = _mirror_partners(engine, width)
    red = slice(0, engine.n_red)
    blue = slice(engine.n_red, engine.n_units)
    # Make the spawn exactly mirrored (the layout is rounded to 6 decimals).
    st.x[0, blue] = width - st.x[0, partner[blue]]
    st.y[0, blue] = st.y[0, partner[blue]]
    commands = Commands.empty(1, engine.n_units)
    shots = 0
    for loop in range(3000):
        commands.clear()
        if loop % 8 == 0:  # SMAC-HARD's base on both sides: attack-move to the other spawn, every step
            commands.kind[0, :] = CMD_ATTACK_MOVE
            commands.x[0, red], commands.y[0, red] = width - 9.0, 16.0
            commands.x[0, blue], commands.y[0, blue] = 9.0, 16.0
        engine.step(commands, n_loops=1)
        x, y = st.x[0], st.y[0]
        np.testing.assert_allclose(x, width - x[partner], atol=1e-7, err_msg=f"x at loop {loop}")
        np.testing.assert_allclose(y, y[partner], atol=1e-7, err_msg=f"y at loop {loop}")
        np.testing.assert_allclose(st.health[0], st.health[0, partner], atol=1e-9, err_msg=f"health, loop {loop}")
        np.testing.assert_allclose(st.shield[0], st.shield[0, partner], atol=1e-9, err_msg=f"shield, loop {loop}")
        assert (st.alive[0] == st.alive[0, partner]).all(), f"deaths differ at loop {loop}"
        target = st.target[0]
        mirrored = np.where(target[partner] >= 0, partner[np.maximum(target[partner], 0)], -1)
        assert (target == mirrored).all(), f"targets differ at loop {loop}"
        shots += int((st.cooldown[0] > 0).sum())
        if not st.alive[0, red].any():
            break
    assert shots > 0  # the armies met and fought
    assert not st.alive[0, red].any() or loop == 2999  # medivacs outlive their armies on MMM


def test_separation_pushes_do_not_depend_on_slot_order():
    # Three marines overlapping in a row: the middle one is pushed by both neighbours at once. Computed from the
    # positions when the pass began, the outcome is the same whatever the slot order.
    x0 = np.array([10.0, 10.6, 11.2])
    y0 = np.array([10.0, 10.0, 10.3])
    slot_stats = np.ascontiguousarray(STATS[[unit_index("marine")] * 3])
    walk = np.ones((2, 32, 32), dtype=np.uint8)
    results = []
    for perm in ([0, 1, 2], [2, 0, 1], [1, 2, 0]):
        rows = battle_rows_of(x0[perm], y0[perm], np.ones(3, dtype=bool), np.full(3, ORDER_IDLE, np.int8))
        _separation(3, rows, slot_stats, walk, 0.375)
        x, y = rows.x, rows.y
        back = np.argsort(perm)
        results.append((x[back], y[back]))
    for x, y in results[1:]:
        np.testing.assert_allclose(x, results[0][0], atol=1e-12)
        np.testing.assert_allclose(y, results[0][1], atol=1e-12)
    # Hand-computed for the pair (0, 1): overlap 0.75 - 0.6 = 0.15 along x, half each; 9.925 lands on SC2's
    # position grid (1/4096) as 40653 / 4096.
    assert results[0][0][0] == on_grid(10.0 - 0.075) == 40653 / 4096


HEAL = 0.5625  # a medivac's heal per game loop: 12.6 HP per Faster second = 9 per Normal second, / 16


def _medivac_save(marine_health: float) -> tuple[bool, float]:
    # Red marine (slot 0) shoots a damaged blue marine (slot 2) that a blue medivac (slot 1) is healing. Blue's
    # medivac has a higher slot than the red shooter, so a heal applied in slot order would land after the shot.
    # The marine's attack starts in loop 0 and shoots WIND_UP = 1 loop later: the run ends with the loop of the
    # shot, and the target has had one heal per loop of the wind-up before it.
    engine = engine_with(["Marine_RL"], ["Medivac", "Marine"],
                         {0: (12.0, 16.0), 1: (16.0, 16.5), 2: (16.0, 16.0)})
    engine.place(0, 2, health=marine_health)
    engine.commands.kind[0, 0] = CMD_ATTACK
    engine.commands.target[0, 0] = 2
    engine.step(n_loops=WIND_UP["Marine"] + 1)
    return bool(engine.state.alive[0, 2]), float(engine.state.health[0, 2])


def test_a_heal_does_not_save_a_unit_killed_in_the_same_loop():
    # 5.2 + 0.5625 (the wind-up loop's heal) - 6 (one marine shot) = -0.2375: dead, although the heal of that loop
    # (0.5625) would bring it back above 0. (5.2, not the 5.8 of before the wind-up: 5.8 + 0.5625 survives the shot.)
    assert 5.2 + WIND_UP["Marine"] * HEAL - 6.0 < 0.0 < 5.2 + (WIND_UP["Marine"] + 1) * HEAL - 6.0
    alive, health = _medivac_save(5.2)
    assert not alive and health == 0.0


def test_a_unit_that_survives_the_shot_is_healed_in_the_same_loop():
    # 10 + 0.5625 (the wind-up loop's heal) - 6 + 0.5625 (the shot's loop) = 5.125.
    alive, health = _medivac_save(10.0)
    assert alive and health == pytest.approx(10.0 + WIND_UP["Marine"] * HEAL - 6.0 + HEAL)
