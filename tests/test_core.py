"""The two-player core: random play on every map, episode clocks, seeding, the opponent hook and its failures."""

from __future__ import annotations

import numpy as np
import pytest

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.envs.core import SELF_PLAY_NAME, TwoPlayerCore
from smac_hard_gym.maps import SMAC_MAPS
from smac_hard_gym.opponents import Script
from smac_hard_gym.smac.features import RUNNING


def random_available(rng, avail):
    """One uniformly random available action per agent, for a whole batch."""
    return np.argmax(rng.random(avail.shape) * avail, axis=2)


class Idle(Script):
    """Test opponent that never gives an order; ``name_of`` splits battles into two names."""

    name = "idle"

    def __init__(self):
        self.resets: list[list[int]] = []
        self.active: list[np.ndarray] = []

    def reset(self, view, battles, rngs):
        self.resets.append([int(b) for b in battles])

    def act(self, view, commands, active):
        self.active.append(active.copy())

    def name_of(self, battle):
        return "idle_even" if battle % 2 == 0 else "idle_odd"


@pytest.mark.parametrize("name", SMAC_MAPS)
def test_random_play_on_every_map(name):
    """Random available actions, both modes: no error, every chosen action available, sane outputs."""
    rng = np.random.default_rng(1)
    core = TwoPlayerCore(name, 2, seed=3)
    red = core.features[RED]
    episodes = np.zeros(2, dtype=int)
    while episodes.min() < 2:
        avail = core.avail_actions()
        acts = random_available(rng, avail)
        assert avail[np.arange(2)[:, None], np.arange(red.n_agents), acts].all()
        result = core.step(acts)
        assert np.isfinite(result.reward).all() and (result.reward >= 0).all()  # only_positive
        assert not (result.terminated & result.truncated).any()
        obs, state = core.observations(), core.global_state()
        assert obs.shape == (2, red.n_agents, red.obs_size) and state.shape == (2, red.state_size)
        assert np.isfinite(obs).all() and np.isfinite(state).all()
        # Dead agents can only no-op.
        dead = ~core.state.alive[:, red.own]
        new_avail = core.avail_actions()
        assert (new_avail[dead][:, 0]).all() and not new_avail[dead][:, 1:].any()
        finished = np.flatnonzero(result.terminated | result.truncated)
        episodes[finished] += 1
        core.reset(finished)
    assert core.stats()["games"] == episodes.sum()

    core = TwoPlayerCore(name, 2, mode="self-play", seed=4)
    while not core.done.all():
        result = core.step(random_available(rng, core.avail_actions(RED)),
                           random_available(rng, core.avail_actions(BLUE)))
        assert np.isfinite(core.observations(BLUE)).all() and np.isfinite(core.global_state(BLUE)).all()
    assert result.opponent == [SELF_PLAY_NAME] * 2


def _rollout(seed, steps=40):
    core = TwoPlayerCore("2m_vs_1z", 2, seed=seed)  # base picks a random attack-move point per battle
    rng = np.random.default_rng(0)
    trace = []
    for _ in range(steps):
        if core.done.all():
            break
        result = core.step(random_available(rng, core.avail_actions()))
        trace.append((core.observations(), result.reward))
    return trace


def test_same_seed_gives_identical_trajectories():
    first, second, other = _rollout(7), _rollout(7), _rollout(8)
    assert len(first) == len(second)
    for (obs_a, rew_a), (obs_b, rew_b) in zip(first, second, strict=True):
        np.testing.assert_array_equal(obs_a, obs_b)
        np.testing.assert_array_equal(rew_a, rew_b)
    assert any(not np.array_equal(a[0], b[0]) for a, b in zip(first, other, strict=False))


def test_seeds_are_per_battle():
    core = TwoPlayerCore("3m", 3, opponent=Idle(), seed=5)
    assert core.seeds == [5, 6, 7]
    core.reset(seed=10)
    draws = [rng.random() for rng in core.rngs]
    assert draws == [np.random.default_rng(10 + b).random() for b in range(3)]
    core.reset(battles=[2], seed=[42])
    assert core.seeds == [10, 11, 42]
    with pytest.raises(ValueError, match="one int per reset battle"):
        core.reset(battles=[0, 1], seed=[1])
    with pytest.raises(ValueError, match="battle indices must lie in 0..2"):
        core.reset(battles=[3])


def test_episode_limit_truncates_and_finished_battles_freeze():
    opponent = Idle()
    core = TwoPlayerCore("3m", 2, opponent=opponent, seed=0)
    stop = np.ones((2, 3), dtype=int)
    for step in range(1, 61):
        result = core.step(stop)
        assert core.episode_step.tolist() == [step, step]
        assert not result.terminated.any()
        assert result.truncated.all() == (step == 60)  # nobody fights: the 60-step limit ends it
    assert core.done.all()
    stats = core.stats()
    assert (stats["games"], stats["timeouts"], stats["wins"]) == (2, 2, 0)
    assert stats["opponents"] == {
        "idle_even": {"games": 1, "wins": 0, "losses": 0, "draws": 0, "timeouts": 1, "win_rate": 0.0},
        "idle_odd": {"games": 1, "wins": 0, "losses": 0, "draws": 0, "timeouts": 1, "win_rate": 0.0},
    }
    assert result.opponent == ["idle_even", "idle_odd"]
    # A finished battle does not move and pays nothing until it is reset; its actions are not even checked.
    x = core.state.x.copy()
    result = core.step(np.zeros((2, 3), dtype=int))
    assert not result.stepped.any() and (result.reward == 0).all() and (result.outcome == RUNNING).all()
    np.testing.assert_array_equal(core.state.x, x)
    assert not opponent.active[-1].any()
    core.reset([1])
    assert opponent.resets[-1] == [1]
    assert core.episode_step.tolist() == [60, 0] and core.done.tolist() == [True, False]
    result = core.step(stop)
    assert result.stepped.tolist() == [False, True]
    assert core.last_action[RED][1].tolist() == [1, 1, 1]


class Explodes(Script):
    name = "explodes"

    def __init__(self, on_call):
        self.calls = 0
        self.on_call = on_call

    def act(self, view, commands, active):
        self.calls += 1
        if self.calls == self.on_call:
            raise RuntimeError("boom")


def test_an_opponent_error_leaves_the_core_usable_after_reset():
    core = TwoPlayerCore("3m", 2, opponent=Explodes(on_call=3), seed=0)
    stop = np.ones((2, 3), dtype=int)
    core.step(stop)
    core.step(stop)
    before = core.state.x.copy()
    with pytest.raises(Exception, match="boom"):
        core.step(stop)
    np.testing.assert_array_equal(core.state.x, before)  # the failed step did not advance anything
    with pytest.raises(RuntimeError, match="call reset"):
        core.step(stop)
    with pytest.raises(RuntimeError, match="reset\\(\\) every battle"):
        core.reset([0])
    core.reset()
    for _ in range(3):
        result = core.step(stop)
    assert result.stepped.all() and core.episode_step.tolist() == [3, 3]


def test_two_player_core_rejects_the_other_modes_actions_and_options():
    with pytest.raises(ValueError, match="needs blue's actions"):
        TwoPlayerCore("3m", 1, mode="self-play").step([[1, 1, 1]])
    with pytest.raises(ValueError, match="pass red's actions only"):
        TwoPlayerCore("3m", 1).step([[1, 1, 1]], [[1, 1, 1]])
    with pytest.raises(ValueError, match="apply to mode 'script' only"):
        TwoPlayerCore("3m", 1, mode="self-play", opponent="nearest")
    with pytest.raises(ValueError, match="mode must be one of"):
        TwoPlayerCore("3m", 1, mode="league")
    with pytest.raises(ValueError, match="side must be 0"):
        TwoPlayerCore("3m", 1).observations(2)


def test_blue_actions_are_validated_in_self_play():
    core = TwoPlayerCore("3m", 1, mode="self-play")
    with pytest.raises(ValueError, match=r"blue agent 0: action 6 \(attack enemy 0\) is not available"):
        core.step([[1, 1, 1]], [[6, 1, 1]])
    result = core.step([[1, 1, 1]], [[4, 5, 2]])
    assert core.last_action[BLUE][0].tolist() == [4, 5, 2]
    assert result.stepped.all()


def test_odd_action_arrays_step_exactly_as_plain_ones():
    # Once compiled, a step's kernels are called past numba's dispatcher for plain int64 C-contiguous actions. Actions
    # of another layout (strided, Fortran order) must still be typed by the dispatcher and play the same way.
    def play(odd: bool) -> list[np.ndarray]:
        core = TwoPlayerCore("MMM", 2, mode="self-play")
        core.reset(seed=3)
        rng, seen = np.random.default_rng(3), []
        for step in range(30):
            acts = []
            for side in (RED, BLUE):
                avail = core.avail_actions(side)
                acts.append((rng.random(avail.shape) + avail).argmax(axis=2).astype(np.int64))
            red, blue = acts
            checked = step % 2 == 0
            if odd and step % 3 == 1:  # in range and int64 as checked=True asks, but of another array type
                red = np.repeat(red, 2, axis=1)[:, ::2] if step % 2 else np.asfortranarray(red)
                checked = True
            result = core.step(red, blue, checked=checked)
            seen += [result.reward.copy(), result.obs.copy(), result.avail.copy(), core.state.x.copy()]
        return seen

    for plain, odd in zip(play(False), play(True), strict=True):
        np.testing.assert_array_equal(plain, odd)


def test_every_api_validates_actions_once(validation_calls):
    """The env layers validate actions and pass ``checked=True``: the core does not validate them again (blue's
    included, in self-play), while its own callers still get validation."""
    from smac_hard_gym.envs.starcraft2 import StarCraft2Env
    from smac_hard_gym.pettingzoo import parallel_env

    calls = validation_calls
    env = StarCraft2Env("3m", mode="self-play")
    env.reset()
    env.step([[1, 1, 1], [1, 1, 1]])
    zoo = parallel_env("3m", teams="both")
    zoo.reset(seed=0)
    zoo.step({agent: 1 for agent in zoo.agents})
    assert calls == []
    core = TwoPlayerCore("3m", 2, mode="self-play", seed=0)
    core.step(np.ones((2, 3), dtype=np.int64), np.ones((2, 3), dtype=np.int64))
    assert calls == ["red", "blue"]
    env.close(), zoo.close(), core.close()
