"""The PettingZoo parallel env: PettingZoo's own conformance and seed tests on every map, agent removal, the same
trajectories as ``StarCraft2Env``, errors, and a light ``import smac_hard_gym``."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

pytest.importorskip("pettingzoo", reason="the [pettingzoo] extra is not installed")

with warnings.catch_warnings():  # pettingzoo.test imports its deprecated classic envs, which warn
    warnings.simplefilter("ignore")
    from pettingzoo.test import parallel_api_test, parallel_seed_test, seed_test

from smac_hard_gym import StarCraft2Env
from smac_hard_gym.maps import list_maps
from smac_hard_gym.pettingzoo import env as aec_env
from smac_hard_gym.pettingzoo import parallel_env
from smac_hard_gym.smac.actions import InvalidActionError, ResetNeededError

MAPS = list_maps()


def masked_actions(env, observations, rng):
    """A legal random action for every live agent."""
    return {agent: int(rng.choice(np.flatnonzero(observations[agent]["action_mask"]))) for agent in env.agents}


@pytest.mark.parametrize("map_name", MAPS)
def test_pettingzoo_api_and_seed_tests(map_name):
    """PettingZoo's parallel_api_test, parallel_seed_test and (AEC) seed_test, script opponent and self-play, with
    every warning an error (parallel_api_test reports soft violations as warnings)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for teams in ("red", "both"):
            env = parallel_env(map_name, teams=teams)
            parallel_api_test(env, num_cycles=1000)  # whole episodes: the map's limit ends them first
            env.close()
            parallel_seed_test(lambda teams=teams: parallel_env(map_name, teams=teams), num_cycles=50)
            seed_test(lambda teams=teams: aec_env(map_name, teams=teams), num_cycles=20)


@pytest.mark.parametrize("teams", ["red", "both"])
def test_spaces_agents_and_state(teams):
    env = parallel_env("3s5z_vs_3s6z", teams=teams)
    red = [f"red_{i}" for i in range(8)]
    blue = [f"blue_{j}" for j in range(9)]
    assert env.possible_agents == (red + blue if teams == "both" else red)
    observations, infos = env.reset(seed=3)
    assert env.agents == env.possible_agents and set(observations) == set(infos) == set(env.agents)
    assert env.observation_space("red_0") is env.observation_space("red_0")
    assert env.action_space("red_0") is env.action_space("red_0")
    assert env.action_space("red_0") is not env.action_space("red_1")  # seeding one agent's leaves the others
    assert env.action_space("red_0").n == 6 + 9
    for agent in env.agents:
        assert env.observation_space(agent).contains(observations[agent]), agent
    if teams == "both":
        assert env.action_space("blue_0").n == 6 + 8
        assert env.opponent_name() == "self-play"
    state = env.state()
    assert state.dtype == np.float32 and env.state_space.contains(state)
    ref = StarCraft2Env("3s5z_vs_3s6z", mode="self-play")
    ref.reset(seed=3)
    np.testing.assert_array_equal(env.team_state("red"), ref.get_state(0))
    if teams == "both":
        np.testing.assert_array_equal(state, np.concatenate([ref.get_state(0), ref.get_state(1)]))
        np.testing.assert_array_equal(env.team_state("blue"), ref.get_state(1))
        assert env.state_sizes == (ref.get_state_size(0), ref.get_state_size(1))
    else:
        np.testing.assert_array_equal(state, ref.get_state(0))
        with pytest.raises(ValueError, match="team must be one of \\['red'\\]"):
            env.team_state("blue")



def _rollout_against_reference(teams, map_name, seed, steps):
    """Step the PZ env and StarCraft2Env side by side with the same legal random actions; every observation,
    mask, reward and state must match, until the episode ends."""
    rng = np.random.default_rng(seed)
    env = parallel_env(map_name, teams=teams, opponent="default") if teams == "red" else parallel_env(
        map_name, teams=teams)
    ref = StarCraft2Env(map_name, opponent="default") if teams == "red" else StarCraft2Env(map_name, mode="self-play")
    sides = ("red", "blue") if teams == "both" else ("red",)
    observations, _ = env.reset(seed=seed)
    ref.reset(seed=seed)
    for _ in range(steps):
        for p, side in enumerate(sides):
            ref_obs, ref_avail = ref.get_obs(p), ref.get_avail_actions(p)
            for i, (o, m) in enumerate(zip(ref_obs, ref_avail, strict=True)):
                agent = f"{side}_{i}"
                if agent in env.agents:
                    np.testing.assert_array_equal(observations[agent]["observation"], o)
                    np.testing.assert_array_equal(observations[agent]["action_mask"], m)
        np.testing.assert_array_equal(env.state(), np.concatenate([ref.get_state(p) for p in range(len(sides))]))
        actions = masked_actions(env, observations, rng)
        joint = [[actions.get(f"{side}_{i}", 0) for i in range(len(ref.get_obs(p)))] for p, side in enumerate(sides)]
        reward, done, info = ref.step(joint if teams == "both" else joint[0])
        observations, rewards, terms, truncs, infos = env.step(actions)
        rewards_ref = reward if teams == "both" else [reward]
        for p, side in enumerate(sides):
            for agent, value in rewards.items():
                if agent.startswith(side):
                    assert value == pytest.approx(rewards_ref[p], abs=0)
                    won = info["battle_won"][p] if teams == "both" else info["battle_won"]
                    assert infos[agent]["battle_won"] == won
        if (done[0] if teams == "both" else done):
            assert not env.agents and all(terms[a] or truncs[a] for a in terms)
            return True
        assert env.agents
    return False


@pytest.mark.parametrize("teams", ["red", "both"])
def test_same_trajectory_as_starcraft2env(teams):
    ended = [_rollout_against_reference(teams, map_name, seed, 200)
             for map_name, seed in (("3m", 0), ("MMM", 1), ("2s3z", 2))]
    assert all(ended)



@pytest.mark.parametrize("teams", ["red", "both"])
def test_state_first_asked_mid_episode_is_the_reference_state(teams):
    # Steps skip the state until state() is first called; a first call after some steps must still be exact.
    env = parallel_env("MMM", teams=teams, opponent="default") if teams == "red" else parallel_env("MMM", teams=teams)
    ref = StarCraft2Env("MMM", opponent="default") if teams == "red" else StarCraft2Env("MMM", mode="self-play")
    sides = range(2 if teams == "both" else 1)
    observations, _ = env.reset(seed=4)
    ref.reset(seed=4)
    rng = np.random.default_rng(4)
    for step in range(12):
        if step in (7, 8, 11):  # the first call (not encoded with the step), then encoded ones
            np.testing.assert_array_equal(env.state(), np.concatenate([ref.get_state(p) for p in sides]))
        actions = masked_actions(env, observations, rng)
        joint = [[actions.get(f"{('red', 'blue')[p]}_{i}", 0) for i in range(len(ref.get_obs(p)))] for p in sides]
        ref.step(joint if teams == "both" else joint[0])
        observations, *_ = env.step(actions)
    assert env.agents  # still mid-episode


def test_dead_agents_get_a_final_step_then_leave():
    env = parallel_env("8m", teams="both")
    rng = np.random.default_rng(0)
    seen_removal = False
    for episode in range(20):
        observations, _ = env.reset(seed=episode)
        removed: set[str] = set()
        while env.agents:
            before = list(env.agents)
            actions = masked_actions(env, observations, rng)
            actions.update({agent: 0 for agent in removed})  # entries for removed agents are ignored
            observations, rewards, terms, truncs, infos = env.step(actions)
            assert set(observations) == set(rewards) == set(terms) == set(truncs) == set(infos) == set(before)
            assert not removed & set(observations)
            done = {agent for agent in before if terms[agent] or truncs[agent]}
            assert env.agents == [agent for agent in before if agent not in done]
            if env.agents and done:  # a unit died while the battle goes on
                seen_removal = True
                assert all(terms[agent] and not truncs[agent] for agent in done)
                for agent in done:
                    assert observations[agent]["action_mask"].tolist()[0] == 1  # dead: no-op only
            removed |= done
            red = [rewards[a] for a in before if a.startswith("red")]
            blue = [rewards[a] for a in before if a.startswith("blue")]
            assert len(set(red)) <= 1 and len(set(blue)) <= 1  # one team reward per team
    assert seen_removal
    with pytest.raises(ResetNeededError):
        env.step({})


def test_invalid_actions_noop_and_raise():
    env = parallel_env("3m", teams="both")
    observations, _ = env.reset(seed=0)
    # Attack on enemy 0 is out of range at the start: unavailable for everyone.
    attack = {agent: 6 for agent in env.agents}
    assert all(observations[agent]["action_mask"][6] == 0 for agent in env.agents)
    _, _, _, _, infos = env.step(attack)
    assert infos["red_0"]["invalid_actions"] == 3 and infos["blue_0"]["invalid_actions"] == 3
    strict = parallel_env("3m", teams="both", invalid_action="raise")
    strict.reset(seed=0)
    with pytest.raises(InvalidActionError, match="blue agent 0: action 6 .* is not available"):
        strict.step(attack)
    with pytest.raises(InvalidActionError, match="red agent 0: action 6 .* is not available"):
        strict.step({**attack, **{f"blue_{j}": 1 for j in range(3)}})
    assert strict.core.episode_step[0] == 0  # rejected steps changed nothing


def test_bad_arguments_and_step_before_reset_raise_clear_errors():
    with pytest.raises(ValueError, match="teams must be one of \\('red', 'both'\\), got 'blue'"):
        parallel_env("3m", teams="blue")
    with pytest.raises(ValueError, match="invalid_action must be one of"):
        parallel_env("3m", invalid_action="ignore")
    with pytest.raises(ValueError, match="teams='both' has no opponent script"):
        parallel_env("3m", teams="both", opponent="base")
    with pytest.raises(TypeError, match="unknown keyword\\(s\\) \\['reward_sparce'\\]"):
        parallel_env("3m", reward_sparce=True)
    with pytest.raises(ValueError, match="seed must be a non-negative int"):
        parallel_env("3m", seed=-1)
    env = parallel_env("3m")
    with pytest.raises(ResetNeededError):
        env.step({"red_0": 0})
    env.reset(seed=0)
    with pytest.raises(ValueError, match="unknown agent 'blue_0'"):
        env.action_space("blue_0")
    with pytest.raises(ValueError, match="no entry for live agent\\(s\\) \\['red_2'\\]"):
        env.step({"red_0": 1, "red_1": 1})
    with pytest.raises(ValueError, match="unknown agent\\(s\\) \\['red_7'\\]"):
        env.step({"red_0": 1, "red_1": 1, "red_2": 1, "red_7": 1})
    with pytest.raises(InvalidActionError, match="out of range|0..8"):
        env.step({"red_0": 1, "red_1": 1, "red_2": 99})
    with pytest.raises(TypeError):
        env.step({"red_0": "stop", "red_1": 1, "red_2": 1})
    with pytest.raises(TypeError, match="actions must be a dict"):
        env.step([1, 1, 1])
    env.step({"red_0": np.int64(1), "red_1": 1.0, "red_2": np.array(1)})  # numpy and integral values are fine


def test_smac_options_size_the_spaces_and_rgb_render_gives_a_frame():
    env = parallel_env("3m", obs_last_action=True, state_last_action=False, render_mode="rgb_array")
    ref = StarCraft2Env("3m", obs_last_action=True, state_last_action=False)
    assert env.observation_space("red_0")["observation"].shape == (ref.get_obs_size(),)
    assert env.state_space.shape == (ref.get_state_size(),)
    env.reset(seed=0)
    frame = env.render()
    assert frame.ndim == 3 and frame.dtype == np.uint8
    env.close()
    env.close()  # idempotent


def test_import_stays_light():
    code = "import sys, smac_hard_gym; assert 'pettingzoo' not in sys.modules; print('ok')"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "ok"


BAD_ACTIONS = [True, False, np.bool_(True), np.array(True), "1", None, 1.5, float("nan"), float("inf"), -1, 9, 2**70,
               [1], np.array([1])]


def _same_step(a, b):
    """Two step results (parallel API) are equal, arrays compared by value."""
    for x, y in zip(a, b, strict=True):
        assert x.keys() == y.keys()
        for key in x:
            if isinstance(x[key], dict):
                for k in x[key]:
                    np.testing.assert_array_equal(x[key][k], y[key][k])
            else:
                assert x[key] == y[key]


@pytest.mark.parametrize("teams", ["red", "both"])
@pytest.mark.parametrize("bad", BAD_ACTIONS, ids=repr)
def test_each_agent_action_is_checked_on_its_own_and_a_rejection_changes_nothing(teams, bad):
    env, twin = parallel_env("3m", teams=teams), parallel_env("3m", teams=teams)
    env.reset(seed=4)
    twin.reset(seed=4)
    valid = {agent: 1 for agent in env.agents}
    victim = env.agents[-1]  # the last agent: every other one is a plain valid int (or float) before it
    for mix in ({**valid, victim: bad}, {**{a: 1.0 for a in env.agents}, victim: bad},
                {**{a: np.int64(1) for a in env.agents}, victim: bad}, {**valid, env.agents[0]: bad}):
        name = next(a for a in mix if mix[a] is bad)
        with pytest.raises((TypeError, InvalidActionError)) as info:
            env.step(mix)
        message = str(info.value)
        assert message.startswith(f"{name}:"), message
        shown = repr(bad.item() if isinstance(bad, np.generic) or (isinstance(bad, np.ndarray) and bad.ndim == 0)
                     else bad)
        assert shown in message or repr(bad) in message, message
    assert env.core.episode_step[0] == 0
    for _ in range(3):  # afterwards the env plays exactly as one that never saw the bad actions
        _same_step(env.step(valid), twin.step(valid))


def test_mixed_bools_are_rejected_exactly_as_reported():
    env, twin = parallel_env("3m"), parallel_env("3m")
    env.reset(seed=0)
    twin.reset(seed=0)
    with pytest.raises(TypeError, match="red_0: action True is a bool; actions are ints 0..8"):
        env.step({"red_0": True, "red_1": 1, "red_2": 1})
    with pytest.raises(TypeError, match="red_1: action True is a bool"):
        env.step({"red_0": 1.0, "red_1": True, "red_2": 1})
    _same_step(env.step({"red_0": 1, "red_1": 1, "red_2": 1}), twin.step({"red_0": 1, "red_1": 1, "red_2": 1}))


@pytest.mark.parametrize("bad", [True, np.bool_(False), "1", None, 2.5, float("nan"), 99, -1], ids=repr)
def test_aec_checks_each_action_when_given_and_keeps_its_turn(bad):
    env, twin = aec_env("3m", teams="both"), aec_env("3m", teams="both")
    env.reset(seed=2)
    twin.reset(seed=2)
    env.step(1)
    twin.step(1)
    turn = env.agent_selection
    with pytest.raises((TypeError, InvalidActionError), match=f"^{turn}: action"):
        env.step(bad)
    assert env.agent_selection == turn  # still this agent's turn, nothing collected
    for _ in range(2 * len(env.possible_agents)):
        env.step(1)
        twin.step(1)
        assert env.agent_selection == twin.agent_selection
        np.testing.assert_array_equal(env.observe(env.agent_selection)["observation"],
                                      twin.observe(twin.agent_selection)["observation"])
        assert env.last()[1:4] == twin.last()[1:4]
