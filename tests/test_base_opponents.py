"""The two base opponents: ``smac`` (SMAC's one-player maps: the spawn order once, then SC2's automatic targeting)
and ``base`` (SMAC-HARD's base_script.py: a per-map attack-move re-issued every step, none on three maps).

Expected points are SMAC's map triggers (docs/smac_interface.md §9) and SMAC-HARD's base_script.py
(docs/smac_hard_reference.md §3).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_opponents_library import Battle

from smac_hard_gym.engine.state import CMD_ATTACK_MOVE, CMD_NOOP, ORDER_ATTACK_MOVE, ORDER_IDLE
from smac_hard_gym.envs.duel import run_duel
from smac_hard_gym.opponents import make_opponent, pool_for_map


def test_smac_attack_moves_to_the_learner_spawn_once_then_lets_automatic_targeting_retarget():
    battle = Battle("3m", red="stop", blue="smac")
    battle.reset_scripts()
    n = battle.n_red
    battle.act()
    np.testing.assert_array_equal(battle.commands.kind[0, n:], [CMD_ATTACK_MOVE] * 3)
    np.testing.assert_allclose(battle.commands.x[0, n:], 9.0)  # SMAC: attack-move to "Team 1" (9, 16)
    np.testing.assert_allclose(battle.commands.y[0, n:], 16.0)
    battle.engine.step(battle.commands, battle.active)
    battle.steps += 1
    st = battle.state
    assert (st.order[0, n:] == ORDER_ATTACK_MOVE).all()
    targets_seen: set[int] = set()
    for _ in range(60):
        battle.act()
        assert (battle.commands.kind[0, n:] == CMD_NOOP).all()  # after the first step smac sends nothing
        battle.engine.step(battle.commands, battle.active)
        battle.steps += 1
        tgt = st.target[0, n:][st.alive[0, n:]]
        for t in tgt[tgt >= 0]:
            assert st.alive[0, t] and t < n  # engaged targets are alive learner units
            targets_seen.add(int(t))
        if not st.alive[0, :n].any():
            break
    assert not st.alive[0, :n].any()
    assert len(targets_seen) == 3  # after each kill the blue marines took a new target


def test_smac_on_2m_vs_1z_attack_moves_to_a_seeded_point_between_the_marines():
    battle = Battle("2m_vs_1z", red="stop", blue="smac", batch=3)
    battle.reset_scripts()
    battle.act()
    x, y = battle.commands.x[:, 2], battle.commands.y[:, 2]
    np.testing.assert_allclose(y, 12.0)  # the segment (13, 12) - (19, 12)
    assert ((x >= 13.0) & (x <= 19.0)).all() and len(set(np.round(x, 6))) == 3
    again = Battle("2m_vs_1z", red="stop", blue="smac", batch=3)
    again.reset_scripts()
    again.act()
    np.testing.assert_array_equal(again.commands.x[:, 2], x)  # same seeds, same points


@pytest.mark.parametrize("map_name, point", [
    ("3m", (9.0, 16.0)), ("MMM2", (9.0, 16.0)), ("3s_vs_5z", (9.0, 16.0)), ("1c3s5z", (9.0, 16.0)),
    ("corridor", (4.0, 4.0)),  # SMAC-HARD's point, not the learner's spawn (19.04, 19.12) nor SMAC's (4.47, 4.33)
    ("6h_vs_8z", (14.5, 9.5)), ("bane_vs_bane", (16.0, 8.0)), ("so_many_baneling", (4.5, 4.5)),
])
def test_base_reissues_smac_hards_attack_move_every_step(map_name, point):
    battle = Battle(map_name, red="stop", blue="base")
    battle.reset_scripts()
    n = battle.n_red
    for _ in range(4):
        battle.act()
        alive = battle.state.alive[0, n:]
        np.testing.assert_array_equal(battle.commands.kind[0, n:][alive], CMD_ATTACK_MOVE)
        np.testing.assert_allclose(battle.commands.x[0, n:][alive], point[0])
        np.testing.assert_allclose(battle.commands.y[0, n:][alive], point[1])
        battle.engine.step(battle.commands, battle.active)
        battle.steps += 1


@pytest.mark.parametrize("map_name", ["2m_vs_1z", "2s_vs_1sc", "2c_vs_64zg"])
def test_base_gives_no_order_where_smac_hard_gives_none(map_name):
    battle = Battle(map_name, red="stop", blue="base")
    battle.reset_scripts()
    for _ in range(3):
        battle.act()
        assert (battle.commands.kind[0, battle.n_red:] == CMD_NOOP).all()
        battle.engine.step(battle.commands, battle.active)
        battle.steps += 1


def test_base_zealot_on_2m_vs_1z_idles_out_of_reach_while_smacs_walks_in():
    # Zealot at (16, 19), marines at (13, 12) and (19, 12): 7.6 apart, beyond its scan range (5 + 0.875 between
    # centres). SMAC-HARD's base gives no order, so it stands idle; SMAC's order walks it to the marines.
    still = Battle("2m_vs_1z", red="stop", blue="base")
    still.reset_scripts()
    still.step(5)
    assert (still.state.x[0, 2], still.state.y[0, 2]) == (16.0, 19.0) and still.state.order[0, 2] == ORDER_IDLE
    walking = Battle("2m_vs_1z", red="stop", blue="smac")
    walking.reset_scripts()
    walking.step(5)
    assert walking.state.y[0, 2] < 19.0 - 4.0


def test_base_on_the_red_side_mirrors_the_point():
    battle = Battle("3m", red="base", blue="stop")
    battle.reset_scripts()
    battle.act()
    np.testing.assert_array_equal(battle.commands.kind[0, :3], CMD_ATTACK_MOVE)
    np.testing.assert_allclose(battle.commands.x[0, :3], 32.0 - 9.0)
    np.testing.assert_allclose(battle.commands.y[0, :3], 16.0)


def test_default_pools_use_smac_hards_base_and_blackbox_leaves_it_out():
    assert "base" in pool_for_map("3s5z_vs_3s6z", "default") and "smac" not in pool_for_map("3m", "default")
    assert "base" not in pool_for_map("3s5z_vs_3s6z", "blackbox")
    assert make_opponent("3m", "smac").name == "smac" and make_opponent("3m", "base").name == "base"


def test_base_and_smac_are_different_opponents_on_2m_vs_1z():
    # A red side that only stops: SMAC's zealot walks in and kills both marines; SMAC-HARD's base zealot never
    # reaches them (no order, nothing in scan range) and the episode runs to the limit.
    smac = run_duel("2m_vs_1z", "stop", "smac", episodes=4, seed=0, progress=False)
    base = run_duel("2m_vs_1z", "stop", "base", episodes=4, seed=0, progress=False)
    assert smac.blue_wins == 4 and base.timeouts == 4
