"""SMAC's reward for hand-computed kill sequences, per side (docs/smac_interface.md §5,
docs/smac_hard_reference.md §6-§7)."""

from __future__ import annotations

import numpy as np
import pytest

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.opponents import Script
from smac_hard_gym.smac.features import BLUE_WON, DRAW, RED_WON, RUNNING, SmacOptions

MAX_REWARD_3M = 3 * 10 + 200 + 3 * 45  # kills + win + enemy health: 365
DIVISOR_3M = MAX_REWARD_3M / 20  # 18.25


class HandBackend:
    """The native backend with its simulation replaced by hand: ``step`` applies ``pending`` and nothing else, so a
    core step's outcome and rewards follow from hand-set health, shields and deaths."""

    def __init__(self, inner):
        self.inner = inner
        self.spec, self.batch_size, self.step_mul = inner.spec, inner.batch_size, inner.step_mul
        self.n_red, self.n_blue = inner.n_red, inner.n_blue
        self.pending = {}

    @property
    def state(self):
        return self.inner.state

    def reset(self, battles=None, seeds=None):
        self.inner.reset(battles, seeds)

    def step(self, commands, active):
        """Apply {"u<slot>": health} (0 = dies) or {"u<slot>": (health, shield)} to battle 0."""
        state = self.state
        for key, value in self.pending.items():
            slot = int(key[1:])
            health, shield = value if isinstance(value, tuple) else (value, state.shield[0, slot])
            state.health[0, slot] = health
            state.shield[0, slot] = shield
            if health <= 0:
                state.alive[0, slot] = False
                state.health[0, slot] = state.shield[0, slot] = 0.0
        self.pending = {}

    def close(self):
        self.inner.close()


class Snapshots:
    """One battle of a self-play core whose steps change health by hand: the rewards come from the core's own step
    (the production path: outcome, rewards and counters in one kernel), for hand-computed kill sequences."""

    def __init__(self, name="3m", **options):
        self.core = TwoPlayerCore(name, 1, mode="self-play", options=SmacOptions(**options), seed=0)
        self.core.backend = HandBackend(self.core.backend)
        self.reward = self.core.rewards

    def step(self, **changes):
        """Apply the changes during one core step (both sides stop, or no-op when dead); the (red, blue) rewards."""
        self.core.backend.pending = changes
        red, blue = (self.core.avail_actions(side).argmax(axis=2) for side in (RED, BLUE))
        result = self.core.step(red, blue)
        self.outcome = int(result.outcome[0])
        return tuple(float(v) for v in result.reward[0])


def test_max_reward_per_side():
    snap = Snapshots("2m_vs_1z")
    # Red faces one zealot (100 HP + 50 shields); blue faces two marines (2 x 45).
    assert snap.reward.max_reward[RED] == 1 * 10 + 200 + 150
    assert snap.reward.max_reward[BLUE] == 2 * 10 + 200 + 90


def test_perfect_3m_win_by_hand_sums_to_reward_scale_rate():
    snap = Snapshots()
    r1 = snap.step(u3=39.0)  # enemy 0 loses 6
    r2 = snap.step(u3=0.0)  # enemy 0 dies from 39: 39 + 10
    r3 = snap.step(u4=0.0, u5=0.0)  # two kills from full (2 x 55) and the win (200)
    assert snap.outcome == RED_WON
    assert r1 == pytest.approx((6 / DIVISOR_3M, 0.0))
    assert r2 == pytest.approx((49 / DIVISOR_3M, 0.0))
    assert r3 == pytest.approx((310 / DIVISOR_3M, 0.0))
    assert r1[0] + r2[0] + r3[0] == pytest.approx(20.0)


def test_only_positive_ignores_own_losses_and_the_other_side_is_credited():
    snap = Snapshots()
    red, blue = snap.step(u0=35.0, u3=40.0)  # red loses 10, blue loses 5
    assert red == pytest.approx(5 / DIVISOR_3M)
    assert blue == pytest.approx(10 / DIVISOR_3M)
    red, blue = snap.step(u0=0.0)  # blue kills a red marine that had 35 left
    assert red == 0.0
    assert blue == pytest.approx((35 + 10) / DIVISOR_3M)


def test_negative_terms_when_not_only_positive():
    snap = Snapshots(reward_only_positive=False, reward_scale=False)
    red, blue = snap.step(u0=35.0, u3=40.0)
    assert red == pytest.approx(5 - 0.5 * 10)
    assert blue == pytest.approx(10 - 0.5 * 5)
    red, _ = snap.step(u0=0.0)  # own death: -10 * 0.5 and -0.5 * 35
    assert red == pytest.approx(-5 - 17.5)


def test_regeneration_pays_nothing_with_only_positive():
    snap = Snapshots("3s_vs_3z", reward_scale=False)
    snap.step(u3=(100.0, 40.0))  # a zealot loses 10 shields
    red, _ = snap.step(u3=(100.0, 42.0))  # it regenerates 2: SMAC's abs() would pay 2; SMAC-HARD pays 0
    assert red == 0.0
    snap = Snapshots("3s_vs_3z", reward_scale=False, reward_only_positive=False)
    snap.step(u3=(100.0, 40.0))
    red, _ = snap.step(u3=(100.0, 42.0))
    assert red == pytest.approx(-2.0)


def test_reward_abs_pays_enemy_regeneration_as_smac_v1_does():
    # SMAC v1 (and pymarl2's copy): r = abs(delta_enemy + delta_deaths), "# shield regeneration".
    snap = Snapshots("3s_vs_3z", reward_scale=False, reward_abs=True)
    red, _ = snap.step(u3=(100.0, 40.0))  # a zealot loses 10 shields
    assert red == pytest.approx(10.0)
    red, _ = snap.step(u3=(100.0, 42.0))  # it regenerates 2: paid like 2 damage
    assert red == pytest.approx(2.0)
    red, _ = snap.step(u3=(100.0, 39.0), u4=(99.0, 50.0))  # 3 shields and 1 health lost at once: 4
    assert red == pytest.approx(4.0)
    red, _ = snap.step(u3=(100.0, 40.0), u4=(98.0, 50.0))  # +1 regenerated and -1 dealt cancel
    assert red == 0.0
    # the medivac's healing on MMM: an enemy marine healed by 9 pays 9, scaled by MMM's divisor
    snap = Snapshots("MMM", reward_abs=True)
    spec = snap.core.spec
    marine = spec.n_red + spec.blue_unit_names.index("Marine")  # blue's slots follow red's
    snap.step(**{f"u{marine}": 30.0})
    red, _ = snap.step(**{f"u{marine}": 39.0})
    assert red == pytest.approx(9.0 / (snap.reward.max_reward[RED] / 20.0))


def test_reward_abs_is_validated():
    with pytest.raises(TypeError, match="reward_abs"):
        SmacOptions(reward_abs="yes")


def test_terminal_bonuses_draws_and_sparse_rewards():
    every_red = {"u0": 0.0, "u1": 0.0, "u2": 0.0}
    every_blue = {"u3": 0.0, "u4": 0.0, "u5": 0.0}
    snap = Snapshots(reward_scale=False, reward_defeat=-7)
    # Blue wins: red earns the defeat term; blue its three kills from full (3 x (45 + 10)) and the win.
    assert snap.step(**every_red) == pytest.approx((-7.0, 365.0))
    assert snap.outcome == BLUE_WON
    draw = Snapshots(reward_scale=False, reward_defeat=-7)
    assert draw.step(**every_red, **every_blue) == pytest.approx((165.0, 165.0))  # kills only: no bonus either way
    assert draw.outcome == DRAW
    sparse = Snapshots(reward_sparse=True, reward_scale=False)
    assert sparse.step(u3=10.0) == (0.0, 0.0)
    assert sparse.outcome == RUNNING
    assert sparse.step(**every_blue) == (1.0, -1.0)
    # SMAC scales sparse rewards too (by max_reward / reward_scale_rate).
    scaled = Snapshots(reward_sparse=True)
    assert scaled.step(**every_blue)[0] == pytest.approx(1 / DIVISOR_3M)


# ---------------------------------------------------------------------------------------------------------------
# Through the core and the engine.


class Harmless(Script):
    """Test opponent whose weapons never come off cooldown (it writes the live state, so it must run unguarded)."""

    name = "harmless"

    def act(self, view, commands, active):
        view.state.cooldown[:, view.own] = 1e6


def _focus_fire(avail):
    """Attack the lowest-index enemy in range, else walk east, per agent; dead agents no-op."""
    acts = np.zeros(avail.shape[:2], dtype=np.int64)
    for b, i in np.ndindex(*acts.shape):
        targets = np.flatnonzero(avail[b, i, 6:])
        acts[b, i] = 6 + targets[0] if len(targets) else (4 if avail[b, i, 4] else int(np.argmax(avail[b, i])))
    return acts


def test_perfect_3m_win_in_the_engine_sums_to_20():
    core = TwoPlayerCore("3m", 1, opponent=Harmless(), seed=0)
    core.opponent = Harmless()  # bare: the guard hands user scripts a read-only copy, and this one writes the state
    total = 0.0
    for _ in range(core.spec.episode_limit):
        result = core.step(_focus_fire(core.avail_actions()))
        total += float(result.reward[0, RED])
        assert result.reward[0, BLUE] == 0.0  # blue never damaged anyone
        if result.terminated[0]:
            break
    assert result.outcome[0] == RED_WON
    assert total == pytest.approx(20.0, abs=1e-4)


def _place(core, slot, **values):
    for name, value in values.items():
        getattr(core.state, name)[0, slot] = value
    core.invalidate()


def test_self_play_credits_each_side_its_own_kills():
    """SMAC-HARD's shared death tracker gives blue nothing for a kill and can drop red's later kills."""
    core = TwoPlayerCore("3m", 1, mode="self-play", seed=0)
    _place(core, 0, x=10.0, y=16.0, health=1.0)  # red 0: one hit from death
    _place(core, 3, x=13.0, y=16.0)  # blue 0 in range of it
    for slot, (x, y) in {1: (2.0, 9.0), 2: (2.0, 11.0), 4: (30.0, 22.0), 5: (30.0, 20.0)}.items():
        _place(core, slot, x=x, y=y)  # everyone else far apart
    stop = 1
    result = core.step([[stop, stop, stop]], [[6 + 0, stop, stop]])  # blue 0 shoots red 0
    assert result.dead_red[0] == 1 and result.dead_blue[0] == 0
    assert result.reward[0, BLUE] == pytest.approx((1 + 10) / DIVISOR_3M)
    assert result.reward[0, RED] == 0.0

    _place(core, 4, x=4.0, y=9.0, health=1.0, cooldown=100.0)  # blue 1 next to red 1, unable to fire back
    result = core.step([[0, 6 + 1, stop]], [[stop, stop, stop]])  # red 1 shoots blue 1
    assert result.dead_blue[0] == 1
    assert result.reward[0, RED] == pytest.approx((1 + 10) / DIVISOR_3M)
    assert result.reward[0, BLUE] == 0.0

    _place(core, 5, x=2.0, y=13.0, health=2.0, cooldown=100.0)  # blue 2 next to red 2: red's second kill
    result = core.step([[0, stop, 6 + 2]], [[stop, 0, stop]])
    assert result.dead_blue[0] == 2
    assert result.reward[0, RED] == pytest.approx((2 + 10) / DIVISOR_3M)
