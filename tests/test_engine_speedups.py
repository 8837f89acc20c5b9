"""The engine's speed mechanisms against slow references: the x-sorted sweep that finds overlapping pairs, the
dynamic hand-out of battles to threads, and the batch bookkeeping kernels.

The separation reference is the mechanic as the engine documents it, written here from scratch for an open map:
two alive units of the same plane whose circles overlap by ``depth`` move apart along the line between their
centres, half each, or all of it on the movable one when the other holds or is rooted; dead units take no part.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine_helpers import battle_rows_of, engine_with, on_grid
from numba import njit, prange

import smac_hard_gym.engine.battle as battle_module
from smac_hard_gym.engine import BattleEngine, Commands
from smac_hard_gym.engine.batch_ops import count_alive
from smac_hard_gym.engine.kernels import _FEW_UNITS, _separation, _sort_by_x, step_kernels_for
from smac_hard_gym.engine.scheduling import fetch_add
from smac_hard_gym.engine.state import CMD_ATTACK, CMD_MOVE, ORDER_HOLD, ORDER_IDLE, BattleState
from smac_hard_gym.engine.units import STATS, S, unit_index

RADIUS = {"marine": 0.375, "zealot": 0.5, "stalker": 0.625, "colossus": 1.0, "medivac": 0.75, "spine_crawler": 1.125}
PLANE = {"marine": 0, "zealot": 0, "stalker": 0, "spine_crawler": 0, "colossus": 1, "medivac": 2}  # ground, cliff, air
ROOTED = {"spine_crawler"}


def test_sort_by_x_orders_slots_by_position_then_slot():
    rng = np.random.default_rng(0)
    for n in (1, 2, 6, 57):
        x = rng.choice([1.0, 2.5, 2.5, 3.0, 7.25], size=n) + rng.choice([0.0, 0.5], size=n)  # many ties
        by_x = rng.permutation(n).astype(np.int32)
        key = np.zeros(n)
        _sort_by_x(n, by_x, key, x)
        expected = np.lexsort((np.arange(n), x))
        assert by_x.tolist() == expected.tolist()
        assert key.tolist() == x[expected].tolist()


def _reference_pass(names, alive, hold, x0, y0):
    """One separation pass by the documented rule: every push read from the positions when the pass began."""
    x, y = x0.copy(), y0.copy()
    deepest = 0.0
    n = len(names)
    for i in range(n):
        for j in range(i + 1, n):
            if not (alive[i] and alive[j]) or PLANE[names[i]] != PLANE[names[j]]:
                continue
            dist = math.hypot(x0[j] - x0[i], y0[j] - y0[i])
            depth = RADIUS[names[i]] + RADIUS[names[j]] - dist
            free_i = not hold[i] and names[i] not in ROOTED
            free_j = not hold[j] and names[j] not in ROOTED
            if depth <= 0 or not (free_i or free_j):
                continue
            ux, uy = (x0[j] - x0[i]) / dist, (y0[j] - y0[i]) / dist
            share_i = depth * (0.5 if free_j else 1.0) if free_i else 0.0
            share_j = depth - share_i
            x[i], y[i] = x[i] - ux * share_i, y[i] - uy * share_i
            x[j], y[j] = x[j] + ux * share_j, y[j] + uy * share_j
            deepest = max(deepest, depth)
    return x, y, deepest


def _scattered_pairs(rng, n_groups):
    """Pairs and loners on a grid of well-separated sites; a pair overlaps, touches nearly, or lies on two planes."""
    names, x, y, alive, hold = [], [], [], [], []
    kinds = list(RADIUS)
    sites = rng.permutation([(sx, sy) for sx in range(4, 124, 8) for sy in range(4, 124, 8)])[:n_groups]
    for sx, sy in sites:
        first, second = rng.choice(kinds, size=2)
        if rng.random() < 0.2:  # a loner
            members = [first]
        else:
            members = [first, second]
        angle = rng.uniform(0, 2 * math.pi)
        depth = rng.choice([rng.uniform(0.01, 0.6), -rng.uniform(0, 0.05)])  # overlapping or a near miss
        dist = RADIUS[first] + RADIUS[second] - depth
        offsets = [(0.0, 0.0), (dist * math.cos(angle), dist * math.sin(angle))]
        for name, (dx, dy) in zip(members, offsets, strict=False):
            names.append(str(name))
            x.append(sx + rng.uniform(-0.5, 0.5) + dx)
            y.append(sy + rng.uniform(-0.5, 0.5) + dy)
            alive.append(rng.random() > 0.1)
            hold.append(rng.random() < 0.2)
    order = rng.permutation(len(names))  # slots in no particular order of position
    pick = [names[k] for k in order]
    return (pick, np.array(alive)[order], np.array(hold)[order], np.array(x)[order], np.array(y)[order])


# 120 groups: the sorted sweep; 10 groups (at most 20 units): the pair test that lets a few units skip a pass (seeds
# whose small scene has a push in it).
@pytest.mark.parametrize("seed,n_groups", [(seed, 120) for seed in range(5)] + [(seed, 10) for seed in (0, 3, 4, 5, 6)])
def test_sweep_pass_pushes_every_overlapping_pair_like_the_all_pairs_rule(seed, n_groups):
    rng = np.random.default_rng(seed)
    names, alive, hold, x, y = _scattered_pairs(rng, n_groups=n_groups)
    assert (len(names) <= _FEW_UNITS) == (n_groups == 10)
    slot_stats = np.ascontiguousarray(STATS[[unit_index(name) for name in names]])
    walk = np.ones((2, 128, 128), dtype=np.uint8)
    order = np.where(hold, ORDER_HOLD, ORDER_IDLE).astype(np.int8)
    expected_x, expected_y, expected_worst = _reference_pass(names, alive, hold, x, y)
    # A pushed unit lands on SC2's position grid (1/4096, half to even); one left alone stays where it was.
    moved = (expected_x != x) | (expected_y != y)
    expected_x = np.where(moved, on_grid(expected_x), x)
    expected_y = np.where(moved, on_grid(expected_y), y)
    rows = battle_rows_of(x, y, alive, order)
    worst = _separation(len(names), rows, slot_stats, walk, slot_stats[:, S["radius"]].max())
    np.testing.assert_allclose(rows.x, expected_x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rows.y, expected_y, rtol=0, atol=1e-12)
    assert worst == pytest.approx(expected_worst, abs=1e-12)
    assert expected_worst > 0.01  # the scene did contain pushes


def test_a_few_units_that_do_not_overlap_are_left_where_they_are():
    # Six marines in a row 0.76 apart centre to centre (edges 0.01 apart: no overlap) and a medivac right above one
    # of them (another plane): the pass pushes nobody and reports no overlap.
    x = np.array([10.0 + 0.76 * k for k in range(6)] + [11.52])
    y = np.full(7, 10.0)
    slot_stats = np.ascontiguousarray(STATS[[unit_index("marine")] * 6 + [unit_index("medivac")]])
    walk = np.ones((2, 32, 32), dtype=np.uint8)
    rows = battle_rows_of(x.copy(), y.copy(), np.ones(7, dtype=bool))
    assert _separation(7, rows, slot_stats, walk, 0.75) == 0.0
    assert rows.x.tolist() == x.tolist() and rows.y.tolist() == y.tolist()
    rows.x[1] = 10.5  # marines 0 and 1 now 0.5 apart: each is pushed 0.125 away from the other
    assert _separation(7, rows, slot_stats, walk, 0.75) == pytest.approx(0.25)
    assert rows.x[0] == pytest.approx(9.875, abs=1e-3) and rows.x[1] == pytest.approx(10.625, abs=1e-3)


def test_sweep_passes_clear_a_dense_crowd():
    # 57 marines dropped into a 5x5 box overlap a lot; repeated passes must leave no overlap, as all-pairs passes do.
    # A pair the sweep failed to look at would stay overlapped forever.
    rng = np.random.default_rng(3)
    n = 57
    x, y = rng.uniform(30, 35, n), rng.uniform(30, 35, n)
    slot_stats = np.ascontiguousarray(STATS[[unit_index("marine")] * n])
    walk = np.ones((2, 64, 64), dtype=np.uint8)
    rows = battle_rows_of(x, y, np.ones(n, dtype=bool))
    for _ in range(400):
        if _separation(n, rows, slot_stats, walk, 0.375) < 1e-6:
            break
    x, y = rows.x, rows.y
    dist = np.hypot(x[:, None] - x[None, :], y[:, None] - y[None, :]) + np.eye(n) * 10
    # Positions on SC2's 1/4096 grid leave slivers a push cannot round away (about 1e-3 here); a pair the sweep
    # missed would keep its overlap, up to 0.75.
    assert dist.min() > 0.75 - 0.005


@pytest.mark.parametrize("dead_x", [10.3, 9.7])  # the dead unit after or before the living one in x order
def test_dead_units_are_not_pushed_and_push_nobody(dead_x):
    engine = engine_with(["Marine_RL", "Marine_RL"], ["Marine"], {0: (dead_x, 10.0), 1: (10.0, 10.0), 2: (30.0, 30.0)})
    engine.place(0, 0, alive=False, health=0.0)
    engine.step()
    assert (engine.state.x[0, 0], engine.state.y[0, 0]) == (dead_x, 10.0)
    assert (engine.state.x[0, 1], engine.state.y[0, 1]) == (10.0, 10.0)


def _random_commands(engine: BattleEngine, rng: np.random.Generator) -> Commands:
    b, u = engine.batch_size, engine.n_units
    cmd = Commands.empty(b, u)
    cmd.kind[:] = np.where(rng.random((b, u)) < 0.5, CMD_ATTACK, CMD_MOVE)
    cmd.target[:] = rng.integers(0, u, size=(b, u))
    cmd.x[:] = engine.state.x + rng.uniform(-6, 6, size=(b, u))
    cmd.y[:] = engine.state.y + rng.uniform(-6, 6, size=(b, u))
    return cmd


def test_parallel_step_equals_serial_step_and_skips_inactive_battles(monkeypatch):
    batch = 100  # not a multiple of the chunk size: the last chunk is short
    parallel, serial = BattleEngine("2s3z", batch_size=batch), BattleEngine("2s3z", batch_size=batch)
    rng = np.random.default_rng(5)
    threshold = battle_module.PARALLEL_MIN_BATCH
    assert batch >= threshold
    for step in range(30):
        cmd = _random_commands(parallel, rng)
        active = rng.random(batch) < 0.8
        before = [a.copy() for a in parallel.state]
        parallel.step(cmd, active)
        monkeypatch.setattr(battle_module, "PARALLEL_MIN_BATCH", batch + 1)
        serial.step(cmd, active)
        monkeypatch.setattr(battle_module, "PARALLEL_MIN_BATCH", threshold)
        for name, p, s, old in zip(BattleState._fields, parallel.state, serial.state, before, strict=True):
            assert np.array_equal(p, s), (step, name)
            assert np.array_equal(p[~active], old[~active]), (step, name)



def test_a_callers_commands_step_exactly_as_the_engines_own_buffer():
    rng = np.random.default_rng(8)
    own, users = BattleEngine("MMM", batch_size=3), BattleEngine("MMM", batch_size=3)
    for step in range(60):
        cmd = _random_commands(own, rng)
        active = rng.random(3) < 0.9
        for name in Commands._fields:
            getattr(own.commands, name)[:] = getattr(cmd, name)
        own.step(None, active.copy())
        users.step(Commands(*(a.copy() for a in cmd)), active.copy())
        for name, a, b in zip(BattleState._fields, own.state, users.state, strict=True):
            assert np.array_equal(a, b), (step, name)
    assert (~own.state.alive).any()  # the comparison covered deaths


def test_only_plain_commands_and_active_skip_numbas_dispatcher():
    # After its first serial step the engine calls the compiled step directly, which trusts its arguments' types:
    # commands and ``active`` of any other array type (another dtype, Fortran order, read-only) must go
    # through the dispatcher, which types them (and compiles for them).
    engine = BattleEngine("3m", batch_size=2)
    engine.step()
    calls = []
    engine._direct_serial = lambda *args: calls.append("direct")
    engine._step_battles = lambda *args: calls.append("dispatcher")

    def user(**changes: np.ndarray) -> Commands:
        return Commands(*(changes.get(name, getattr(engine.commands, name).copy()) for name in Commands._fields))

    read_only = engine.commands.x.copy()
    read_only.flags.writeable = False
    active = np.ones(4, dtype=bool)
    frozen = np.ones(2, dtype=bool)
    frozen.flags.writeable = False
    cases = {
        "own buffer": (None, None, "direct"),
        "caller's plain arrays": (user(), np.ones(2, dtype=bool), "direct"),
        "int64 kinds": (user(kind=engine.commands.kind.astype(np.int64)), None, "dispatcher"),
        "Fortran-order targets": (user(target=np.asfortranarray(engine.commands.target)), None, "dispatcher"),
        "read-only x": (user(x=read_only), None, "dispatcher"),
        "strided active (the engine copies it)": (None, active[::2], "direct"),
        "read-only active": (None, frozen, "dispatcher"),
    }
    for name, (cmd, act, path) in cases.items():
        calls.clear()
        engine.step(cmd, act)
        assert calls == [path], name


def test_kernels_compiled_for_the_unit_count_step_exactly_as_the_generic_ones():
    # MMM: medivac heals, marauder bonus damage, deaths within 40 random steps; 20 units per battle.
    batch = 40
    special = BattleEngine("MMM", batch_size=batch, specialize=True)
    generic = BattleEngine("MMM", batch_size=batch, specialize=False)
    assert special.specialized and not generic.specialized
    rng = np.random.default_rng(11)
    for step in range(40):
        cmd = _random_commands(special, rng)
        special.step(cmd)
        generic.step(cmd)
        for name, a, b in zip(BattleState._fields, special.state, generic.state, strict=True):
            assert np.array_equal(a, b), (step, name)
    assert (~special.state.alive).any()  # the comparison covered deaths


def test_big_batches_specialize_by_default_and_bad_choices_are_named():
    assert BattleEngine("3m", batch_size=battle_module.SPECIALIZE_MIN_BATCH).specialized
    assert not BattleEngine("3m", batch_size=battle_module.SPECIALIZE_MIN_BATCH - 1).specialized
    with pytest.raises(ValueError, match="specialize must be True, False or None.*'yes'"):
        BattleEngine("3m", specialize="yes")
    with pytest.raises(ValueError, match="n_units must be a positive int.*0"):
        step_kernels_for(0)


@njit(parallel=True)
def _claim_all(n_items, chunk, claims, counter, workers):
    for _ in prange(workers):
        while True:
            start = fetch_add(counter, chunk)
            if start >= n_items:
                break
            for k in range(start, min(start + chunk, n_items)):
                claims[k] += 1


def test_fetch_add_hands_out_every_item_exactly_once():
    for n_items, chunk in ((1, 1), (1000, 7), (4096, 64)):
        claims, counter = np.zeros(n_items, dtype=np.int64), np.zeros(1, dtype=np.int64)
        _claim_all(n_items, chunk, claims, counter, 4)
        assert (claims == 1).all()
    counter = np.array([5], dtype=np.int64)
    assert fetch_add(counter, 3) == 5 and counter[0] == 8  # also without the JIT


def test_count_alive_and_masked_reset_match_numpy_and_a_fresh_engine():
    engine = BattleEngine("3s5z", batch_size=12)
    rng = np.random.default_rng(2)
    for _ in range(40):
        engine.step(_random_commands(engine, rng))
    red, blue = count_alive(engine.state.alive, engine.n_red)
    assert red.tolist() == engine.state.alive[:, :engine.n_red].sum(axis=1).tolist()
    assert blue.tolist() == engine.state.alive[:, engine.n_red:].sum(axis=1).tolist()
    mask = rng.random(12) < 0.5
    before = [a.copy() for a in engine.state]
    engine.reset(mask)
    fresh = BattleEngine("3s5z", batch_size=1).state
    for name, now, old, new in zip(BattleState._fields, engine.state, before, fresh, strict=True):
        if name != "rng":
            assert np.array_equal(now[mask], np.repeat(new, mask.sum(), axis=0)), name
        assert np.array_equal(now[~mask], old[~mask]), name


def test_bad_reset_mask_and_fixed_unit_types_are_refused():
    engine = BattleEngine("3m", batch_size=4)
    with pytest.raises(ValueError, match=r"shape \(4,\).*\(3,\)"):
        engine.reset(np.ones(3, dtype=bool))
    with pytest.raises(ValueError, match="slot 0 is 'marine_rl'"):
        engine.place(0, 0, utype=1)
