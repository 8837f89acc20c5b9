"""Movement, terrain and determinism of the engine.

Speeds are Normal-speed distances per second (docs/smac_interface.md §8); an env step is 8 loops = half a second, so a
unit travels speed / 2 per step in open ground.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine_helpers import engine_with, overlaps

from smac_hard_gym.engine import CMD_ATTACK, CMD_MOVE, BattleEngine, Commands
from smac_hard_gym.engine.kernels import POSITION_GRID
from smac_hard_gym.engine.units import STATS, S

STEP_DISTANCE = {  # speed / 2, from the unit facts
    "Marine_RL": 2.25 / 2, "Marauder_RL": 2.25 / 2, "Medivac_RL": 2.75 / 2, "Medivac": 3.5 / 1.4 / 2,
    "Stalker_RL": 2.9531 / 2, "Zealot_RL": 2.25 / 2, "Colossus_RL": 2.25 / 2, "Hydralisk_RL": 2.25 / 2,
    "Zergling_RL": 2.9531 / 2, "Baneling_RL": 2.5 / 2, "SpineCrawler": 0.0,
}


@pytest.mark.parametrize("unit", sorted(STEP_DISTANCE))
def test_distance_moved_per_step(unit):
    # The other side's unit sits far away in a corner, passive and out of reach.
    engine = engine_with([unit] if unit.endswith("_RL") else ["Marine_RL"],
                         ["SpineCrawler"] if unit.endswith("_RL") else [unit], {})
    slot = 0 if unit.endswith("_RL") else 1
    engine.place(0, 1 - slot, x=30.0, y=30.0)
    engine.place(0, slot, x=5.0, y=16.0)
    engine.commands.kind[0, slot] = CMD_MOVE
    engine.commands.x[0, slot] = 25.0
    engine.commands.y[0, slot] = 16.0
    engine.step()
    # Each of the 8 loops ends on SC2's position grid (1/4096): at most half a grid step off each.
    assert engine.state.x[0, slot] - 5.0 == pytest.approx(STEP_DISTANCE[unit], abs=8 * 0.5 / POSITION_GRID)
    assert engine.state.y[0, slot] == pytest.approx(16.0)


def _random_commands(engine: BattleEngine, rng: np.random.Generator) -> Commands:
    b, u = engine.batch_size, engine.n_units
    cmd = Commands.empty(b, u)
    cmd.kind[:] = np.where(rng.random((b, u)) < 0.5, CMD_ATTACK, CMD_MOVE)
    cmd.target[:] = rng.integers(0, u, size=(b, u))
    cmd.x[:] = engine.state.x + rng.uniform(-8, 8, size=(b, u))
    cmd.y[:] = engine.state.y + rng.uniform(-8, 8, size=(b, u))
    return cmd


@pytest.mark.parametrize("map_name", ["corridor", "2c_vs_64zg", "2s_vs_1sc", "6h_vs_8z", "3s5z", "MMM2"])
def test_no_unit_in_a_wall_or_overlapping_after_random_play(map_name):
    engine = BattleEngine(map_name, batch_size=8)
    rng = np.random.default_rng(1)
    walk = engine.terrain.walk
    mover = STATS[:, S["mover"]].astype(int)
    radius = STATS[:, S["radius"]]
    worst_overlap = 0.0
    for step in range(150):
        engine.step(_random_commands(engine, rng))
        st = engine.state
        for b in range(engine.batch_size):
            for i in np.flatnonzero(st.alive[b]):
                m = mover[st.utype[b, i]]
                x, y = st.x[b, i], st.y[b, i]
                assert 0.0 < x < 32.0 and 0.0 < y < 32.0
                if m < 2:
                    assert walk[m, int(x), int(y)], (map_name, step, b, i, x, y)
            for i, j, depth in overlaps(engine, b):
                worst_overlap = max(worst_overlap, depth / (radius[st.utype[b, i]] + radius[st.utype[b, j]]))
        red, blue = engine.alive_counts()
        done = (red == 0) | (blue == 0)
        if done.any():
            engine.reset(done)
    # Units are pushed apart every game loop; after a step some overlap remains where random orders squeeze a crowd
    # (up to about a quarter of the two radii among 64 zerglings), never a unit inside another.
    assert worst_overlap < 1 / 3


def test_units_spawn_without_overlap_on_every_map():
    from smac_hard_gym.maps import list_maps

    for name in list_maps():
        engine = BattleEngine(name, batch_size=1)
        assert overlaps(engine, 0) == [], name


def _walk_to(engine: BattleEngine, slot: int, goal: tuple[float, float], steps: int) -> int | None:
    """Steps until ``slot`` is within 0.5 of ``goal`` (None if never), re-issuing the move each step."""
    for k in range(1, steps + 1):
        engine.commands.kind[0, slot] = CMD_MOVE
        engine.commands.x[0, slot], engine.commands.y[0, slot] = goal
        engine.step()
        if math.hypot(engine.state.x[0, slot] - goal[0], engine.state.y[0, slot] - goal[1]) < 0.5:
            return k
    return None


def test_corridor_neck_is_traversable():
    # corridor: the lower-left room (x, y 2-11) joins the upper area only through cells touching diagonally at
    # (12-13, 12-13). A zealot ordered from the room to the far side must get through.
    engine = BattleEngine("corridor", batch_size=1)
    engine.state.alive[0, 1:] = False
    engine.place(0, 0, x=5.5, y=5.5)
    steps = _walk_to(engine, 0, (20.5, 20.5), steps=80)
    assert steps is not None
    # The straight-line distance is 21.2; a zealot covers 1.125 per step, so it took a reasonable path.
    assert steps <= 21.2 / 1.125 * 1.5


def test_colossus_climbs_the_cliff_a_zergling_takes_the_ramp():
    # 2c_vs_64zg: low ground (y <= 11) and the high ground (y >= 14, x 7-24) are split by an unpathable cliff
    # band at y 12-13. A colossus steps straight up; a zergling must go round through the side lanes and ramps.
    engine = BattleEngine("2c_vs_64zg", batch_size=1)
    st = engine.state
    st.alive[0, :] = False
    colossus, zergling = 0, engine.n_red
    st.alive[0, [colossus, zergling]] = True
    engine.place(0, colossus, x=16.0, y=10.0)
    engine.place(0, zergling, x=20.0, y=10.0)
    goal_c, goal_z = (16.0, 16.5), (20.0, 16.5)
    colossus_steps = _walk_to(engine, colossus, goal_c, steps=20)
    assert colossus_steps is not None and colossus_steps <= math.ceil(6.5 / 1.125) + 1
    engine.place(0, colossus, x=16.0, y=10.0)
    engine.place(0, zergling, x=20.0, y=10.0)
    path_cells = set()
    steps = 0
    for _ in range(1, 60):
        steps += 1
        engine.commands.kind[0, zergling] = CMD_MOVE
        engine.commands.x[0, zergling], engine.commands.y[0, zergling] = goal_z
        engine.step()
        x, y = st.x[0, zergling], st.y[0, zergling]
        assert engine.spec.pathable[int(x), int(y)]
        path_cells.add((int(x), int(y)))
        if math.hypot(x - goal_z[0], y - goal_z[1]) < 0.5:
            break
    else:
        pytest.fail("zergling never reached the high ground")
    # It went round: through a side lane (x <= 3 or x >= 28), more than twice the straight 6.5.
    assert any(cx <= 3 or cx >= 28 for cx, _ in path_cells)
    assert steps * 1.477 > 2 * 6.5


def _rollout(batch: int, steps: int, seed: int, lanes: np.ndarray | None = None):
    engine = BattleEngine("3s5z", batch_size=batch)  # with SC2's random weapon delay
    battle_seeds = 1000 + (np.arange(batch) if lanes is None else lanes)
    engine.reset(seeds=battle_seeds)  # battle b's random stream depends on its seed only, not on the batch
    rng = np.random.default_rng(seed)
    history = []
    for _ in range(steps):
        cmd = _random_commands_fixed(engine.n_units, rng)
        if lanes is not None:
            cmd = Commands(*(a[lanes] for a in cmd))
        else:
            cmd = Commands(*(a[:batch] for a in cmd))
        engine.step(cmd)
        history.append(np.stack([engine.state.x, engine.state.y, engine.state.health, engine.state.shield]).copy())
    return history


def _random_commands_fixed(n_units: int, rng: np.random.Generator, lanes: int = 64) -> Commands:
    cmd = Commands.empty(lanes, n_units)
    cmd.kind[:] = np.where(rng.random((lanes, n_units)) < 0.5, CMD_ATTACK, CMD_MOVE)
    cmd.target[:] = rng.integers(0, n_units, size=(lanes, n_units))
    cmd.x[:] = rng.uniform(0, 32, size=(lanes, n_units))
    cmd.y[:] = rng.uniform(8, 24, size=(lanes, n_units))
    return cmd


def test_same_commands_give_bit_identical_states():
    a = _rollout(batch=64, steps=40, seed=7)
    b = _rollout(batch=64, steps=40, seed=7)
    for sa, sb in zip(a, b, strict=True):
        assert np.array_equal(sa, sb)


def test_one_battle_equals_one_lane_of_a_batch():
    batch = _rollout(batch=64, steps=40, seed=3)
    for lane in (0, 37):
        single = _rollout(batch=1, steps=40, seed=3, lanes=np.array([lane]))
        for sb, ss in zip(batch, single, strict=True):
            assert np.array_equal(sb[:, lane], ss[:, 0])


def _send_three_marines_to(point, positions):
    engine = engine_with(["Marine_RL"] * 3, ["Marine"], {**dict(enumerate(positions)), 3: (30.0, 30.0)})
    engine.commands.kind[0, :3] = CMD_MOVE
    engine.commands.x[0, :3], engine.commands.y[0, :3] = point
    return engine


def test_a_group_sent_to_one_point_stops_as_a_clump_around_it():
    # Three marines in a file 1 apart walk to (20, 10). The first reaches the point and stops; the second stops when
    # it touches the first (edges within 0.1, inside 3 of the point), the third when it touches the second. Without
    # group arrival the two followers would push toward the occupied point for ever.
    engine = _send_three_marines_to((20.0, 10.0), [(10.0, 10.0), (9.0, 10.0), (8.0, 10.0)])
    for _ in range(20):
        engine.step()
        engine.commands.clear()
    st = engine.state
    assert (st.order[0, :3] == 0).all()  # all idle
    assert st.x[0, 0] == pytest.approx(20.0, abs=0.05)
    # Each follower stands touching the one ahead: 0.75 between centres, within the 0.1 of touching.
    assert 20.0 - 0.85 - 0.05 <= st.x[0, 1] <= 20.0 - 0.75 + 0.05
    assert st.x[0, 1] - 0.85 - 0.05 <= st.x[0, 2] <= st.x[0, 1] - 0.75 + 0.05


def test_passing_an_idle_unit_far_from_the_point_does_not_stop_a_move():
    # A marine idles at (14, 10.8), touching the path of a marine walking from (10, 10) to (20, 10) but 6 from its
    # point: the walker goes on to the point.
    engine = engine_with(["Marine_RL", "Marine_RL"], ["Marine"], {0: (10.0, 10.0), 1: (14.0, 10.8), 2: (30.0, 30.0)})
    engine.commands.kind[0, 0] = CMD_MOVE
    engine.commands.x[0, 0], engine.commands.y[0, 0] = 20.0, 10.0
    for _ in range(12):
        engine.step()
        engine.commands.clear()
    assert engine.state.x[0, 0] == pytest.approx(20.0, abs=0.05)
