"""The B=1 scalar fast paths of built-in scripts give bit for bit the orders and memory of their batched code."""

import copy

import numpy as np
import pytest

from smac_hard_gym.engine.state import BLUE, BattleState
from smac_hard_gym.engine.units import STATS, S
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.opponents.api import SideView
from smac_hard_gym.opponents.helpers import Frame, Orders
from smac_hard_gym.opponents.marines import LineAdvance


def _random_states(map_name, count, seed):
    core = TwoPlayerCore(map_name, batch_size=1, opponent="base")
    core.reset(seed=seed)
    rng = np.random.default_rng(seed)
    base = core.backend.state
    mx, my = core.spec.size
    for _ in range(count):
        state = BattleState(*(np.array(a, copy=True) for a in base))
        state.alive[:] = rng.random(state.alive.shape) < 0.7
        state.x[:] = rng.uniform(0.0, mx, state.x.shape)
        state.y[:] = rng.uniform(0.0, my, state.y.shape)
        if rng.random() < 0.3:  # clustered: contact, ties in distance
            state.x[:] = np.round(state.x[:] / 8.0) * 8.0
        hmax = STATS[state.utype, S["health"]]
        state.health[:] = np.where(rng.random(hmax.shape) < 0.3, hmax, np.round(rng.uniform(0, 1, hmax.shape) * hmax))
        step = np.array([int(rng.integers(0, 40))], dtype=np.int64)
        yield core.spec, state, step, rng


@pytest.mark.parametrize("map_name", ["3m", "8m", "5m_vs_6m", "10m_vs_11m"])
@pytest.mark.parametrize("focus", ["front", "weakest"])
def test_line_advance_scalar_path_matches_batched(map_name, focus):
    fast, slow = LineAdvance(focus), LineAdvance(focus)
    slow.scalar_path = False
    for spec, state, step, rng in _random_states(map_name, 300, seed=len(map_name)):
        view = SideView.of(state, spec, BLUE, step)
        fast.reset(view, np.array([0]), [rng])
        n = view.n_own
        fast.memory.engaged[0] = rng.random() < 0.5
        frac = state.health[0, view.own] / STATS[state.utype[0, view.own], S["health"]]
        fast.memory.last_frac[0] = np.where(rng.random(n) < 0.5, frac, rng.random(n))
        slow.memory = copy.deepcopy(fast.memory)
        plans = []
        for script in (fast, slow):
            frame = Frame(view, np.array([0]))
            orders = Orders(frame)
            script.plan(frame, orders)
            plans.append(orders)
        a, b = plans
        np.testing.assert_array_equal(a.kind, b.kind)
        assert (a._targets, a._points) == (b._targets, b._points)
        if a._targets:
            np.testing.assert_array_equal(a.target, b.target)
        if a._points:
            assert a.x.tobytes() == b.x.tobytes() and a.y.tobytes() == b.y.tobytes()
        np.testing.assert_array_equal(fast.memory.engaged, slow.memory.engaged)
        assert fast.memory.last_frac.tobytes() == slow.memory.last_frac.tobytes()
