"""``StarCraft2Env``: SMAC's API and return values, SMAC-HARD's spellings, self-play."""

from __future__ import annotations

import subprocess
import sys

import gymnasium
import numpy as np
import pytest

from smac_hard_gym.envs.starcraft2 import StarCraft2Env
from smac_hard_gym.opponents import Script
from smac_hard_gym.smac.actions import InvalidActionError, ResetNeededError

ENV_INFO_KEYS = {"state_shape", "obs_shape", "n_actions", "n_agents", "episode_limit", "agent_features",
                 "enemy_features"}


class Idle(Script):
    name = "idle"

    def act(self, view, commands, active):
        pass


def pymarl_episode(env, rng, cur_stats=None):
    """The loop of pymarl's episode runner, written against SMAC's API only."""
    cur_stats = {} if cur_stats is None else cur_stats
    env_info = env.get_env_info()
    env.reset()
    terminated, episode_return, steps = False, 0.0, 0
    while not terminated:
        state = env.get_state()
        avail_actions = env.get_avail_actions()
        obs = env.get_obs()
        assert len(state) == env_info["state_shape"]
        assert len(obs) == env_info["n_agents"] and all(len(o) == env_info["obs_shape"] for o in obs)
        assert len(avail_actions) == env_info["n_agents"]
        assert all(len(a) == env_info["n_actions"] for a in avail_actions)
        actions = [int(rng.choice(np.flatnonzero(a))) for a in avail_actions]
        reward, terminated, info = env.step(actions)
        episode_return += reward
        steps += 1
        assert isinstance(reward, float) and isinstance(terminated, bool)
        assert steps <= env_info["episode_limit"]
    # pymarl sums every info value over episodes: they must all be numbers.
    cur_stats.update({k: cur_stats.get(k, 0) + info.get(k, 0) for k in set(cur_stats) | set(info)})
    return episode_return, info


def test_pymarl_style_loop_gives_smac_env_info_and_bounded_returns():
    env = StarCraft2Env(map_name="3m", seed=1)
    info = env.get_env_info()
    assert set(info) == ENV_INFO_KEYS
    assert (info["n_agents"], info["n_actions"], info["obs_shape"], info["state_shape"], info["episode_limit"]) \
        == (3, 9, 30, 48, 60)
    assert info["agent_features"] == ["health", "energy/cooldown", "rel_x", "rel_y"]
    assert info["enemy_features"] == ["health", "rel_x", "rel_y"]
    rng = np.random.default_rng(0)
    cur_stats = {}
    for _ in range(2):
        episode_return, step_info = pymarl_episode(env, rng, cur_stats)
        assert set(step_info) == {"battle_won", "dead_allies", "dead_enemies"}
        assert env.get_opponent_name() == "smac"  # the drop-in's default: SMAC's own opponent
        assert 0.0 <= episode_return <= 20.0 + 1e-4
    assert cur_stats["dead_allies"] + cur_stats["dead_enemies"] > 0
    stats = env.get_stats()
    assert stats["battles_game"] == 2
    assert {"battles_won", "battles_game", "battles_draw", "win_rate", "timeouts", "restarts"} <= set(stats)
    assert stats["opponents"]["smac"]["games"] == 2
    env.close()
    env.close()


def test_reset_and_query_return_types():
    env = StarCraft2Env(map_name="2s3z")
    obs, state = env.reset()
    assert len(obs) == 5 and all(o.dtype == np.float32 and o.shape == (80,) for o in obs)
    assert state.dtype == np.float32 and state.shape == (120,)
    np.testing.assert_array_equal(env.get_obs_agent(3), obs[3])
    assert env.get_avail_agent_actions(0) == env.get_avail_actions()[0]
    assert all(isinstance(v, int) for v in env.get_avail_agent_actions(0))
    assert env.get_total_actions() == 11 and env.get_obs_size() == 80 and env.get_state_size() == 120
    assert env.get_obs_move_feats_size() == 4
    assert env.get_obs_enemy_feats_size() == (5, 8) and env.get_obs_ally_feats_size() == (4, 8)
    assert env.get_obs_own_feats_size() == 4
    assert env.get_ally_num_attributes() == 7 and env.get_enemy_num_attributes() == 6
    assert len(env.get_obs_feature_names()) == 80 and len(env.get_state_feature_names()) == 120
    parts = env.get_state_dict()
    assert parts["allies"].shape == (5, 7) and parts["enemies"].shape == (5, 6)
    assert parts["last_action"].shape == (5, 11)
    vis = env.get_visibility_matrix()
    assert vis.shape == (5, 10) and vis.dtype == bool
    assert env.n_agents == 5 and env.n_enemies == 5 and env.episode_limit == 120
    assert env.max_reward == 5 * 10 + 200 + 2 * 160 + 3 * 150
    # Returned arrays are copies: changing them does not change the env.
    obs[0][:] = 99
    assert env.get_obs()[0][0] != 99


def test_last_action_appears_in_the_state():
    env = StarCraft2Env(map_name="3m")
    env.reset()
    env.step([1, 2, 3])
    state = env.get_state()
    last = state[-27:].reshape(3, 9)
    np.testing.assert_array_equal(last.argmax(axis=1), [1, 2, 3])
    np.testing.assert_array_equal(env.last_action, last)


def test_invalid_and_dead_agent_actions_raise():
    env = StarCraft2Env(map_name="3m")
    env.reset()
    with pytest.raises(InvalidActionError, match=r"red agent 0: action 0 \(no-op\) is not available"):
        env.step([0, 1, 1])
    with pytest.raises(ValueError, match="one action per agent"):
        env.step([1, 1])
    env.step(np.array([1, 1, 1]))  # numpy (and tensor-like) action containers work like lists
    # Red stands still under SMAC's default opponent until an agent dies.
    dead = []
    while not dead:
        avail = env.get_avail_actions()
        _, terminated, info = env.step([0 if a[0] else 1 for a in avail])
        assert not terminated
        dead = [i for i, a in enumerate(env.get_avail_actions()) if a[0]]
    i = dead[0]
    assert env.get_avail_agent_actions(i) == [1] + [0] * 8
    assert env.get_obs_agent(i).sum() == 0.0
    actions = [0 if a[0] else 1 for a in env.get_avail_actions()]
    actions[i] = 1
    with pytest.raises(InvalidActionError, match=rf"red agent {i}: action 1 \(stop\) is not available"):
        env.step(actions)


def test_timeout_counts_and_continuing_episode():
    env = StarCraft2Env(map_name="3m", opponent=Idle(), continuing_episode=True)
    env.reset()
    for _ in range(60):
        reward, terminated, info = env.step([1, 1, 1])
    assert terminated and info["episode_limit"] is True and info["battle_won"] is False
    with pytest.raises(RuntimeError, match="call reset"):
        env.step([1, 1, 1])
    stats = env.get_stats()
    assert (stats["timeouts"], stats["battles_draw"], stats["battles_game"]) == (1, 1, 1)
    env = StarCraft2Env(map_name="3m", opponent=Idle())
    env.reset()
    for _ in range(60):
        _, terminated, info = env.step([1, 1, 1])
    assert terminated and "episode_limit" not in info


def test_observation_options_reach_the_arrays():
    env = StarCraft2Env(map_name="3m", obs_timestep_number=True, state_timestep_number=True,
                        obs_instead_of_state=False, obs_last_action=True)
    env.reset()
    env.step([1, 1, 1])
    obs = env.get_obs()
    assert len(obs[0]) == env.get_obs_size() == 30 + 2 * 9 + 1  # SMAC's obs would be one longer
    assert obs[0][-1] == pytest.approx(1 / 60)
    assert env.get_state()[-1] == pytest.approx(1 / 60)
    env = StarCraft2Env(map_name="3m", obs_instead_of_state=True)
    obs, state = env.reset()
    np.testing.assert_array_equal(state, np.concatenate(obs))
    with pytest.raises(ValueError, match="obs_instead_of_state"):
        env.get_state_dict()


def test_sparse_rewards_through_the_env():
    env = StarCraft2Env(map_name="3m", reward_sparse=True, reward_scale=False, seed=2)
    rng = np.random.default_rng(5)
    env.reset()
    rewards, terminated = [], False
    while not terminated:
        actions = [int(rng.choice(np.flatnonzero(a))) for a in env.get_avail_actions()]
        reward, terminated, info = env.step(actions)
        rewards.append(reward)
    assert set(rewards[:-1]) <= {0.0}
    expected = 1.0 if info["battle_won"] else (-1.0 if info["dead_allies"] == 3 and info["dead_enemies"] < 3 else 0.0)
    assert rewards[-1] == expected


def test_same_seed_same_episode():
    def returns(seed):
        env = StarCraft2Env(map_name="2m_vs_1z", seed=seed)
        assert env.seed() == seed
        rng = np.random.default_rng(3)
        return [pymarl_episode(env, rng)[0] for _ in range(2)]

    assert returns(11) == returns(11)


def test_self_play_mode_gives_each_team_its_obs_state_and_rewards():
    env = StarCraft2Env(map_name="2m_vs_1z", mode="self-play")
    (obs_red, obs_blue), (state_red, state_blue) = env.reset()
    infos = env.get_env_info()
    assert isinstance(infos, list) and len(infos) == 2
    assert (infos[0]["n_agents"], infos[0]["n_actions"]) == (2, 7)
    assert (infos[1]["n_agents"], infos[1]["n_actions"]) == (1, 8)
    assert len(obs_red) == 2 and len(obs_blue) == 1
    assert len(obs_blue[0]) == env.get_obs_size(1) == infos[1]["obs_shape"]
    assert len(state_blue) == env.get_state_size(1) == infos[1]["state_shape"]
    assert env.get_avail_agent_actions(0, player_id=1) == env.get_avail_actions(1)[0]
    rewards, terminated, info = env.step([[1, 1], [1]])
    assert isinstance(rewards, list) and len(rewards) == 2 and terminated == [False, False]
    assert info["battle_won"] == [False, False] and info["dead_allies"] == [0, 0]
    assert env.get_opponent_name() == "self-play"
    with pytest.raises(ValueError, match=r"\[red_actions, blue_actions\]"):
        env.step([1, 1])
    with pytest.raises(ValueError, match="player_id must be 0"):
        env.get_obs(2)


def test_smac_hard_mode_spellings_map_to_ours_and_conflicts_raise():
    env = StarCraft2Env(map_name="3m", mode="multi")
    assert env.mode == "self-play"
    assert StarCraft2Env(map_name="3m", mode="single").mode == "script"
    assert env.n_agents_list == [3, 3] and env.n_actions_list == [9, 9]
    with pytest.raises(ValueError, match="mode must be one of"):
        StarCraft2Env(map_name="3m", mode="duel")
    with pytest.raises(ValueError, match="either opponent_probs or SMAC-HARD's strategy_prob"):
        StarCraft2Env(map_name="3m", strategy_prob=[0.5, 0.5], opponent_probs=[0.5, 0.5])
    with pytest.raises(ValueError, match="self-play' has no opponent script"):
        StarCraft2Env(map_name="3m", mode="multi", opponent="nearest")
    with pytest.raises(ValueError, match="heuristic_ai"):
        StarCraft2Env(map_name="3m", heuristic_ai=True)


def test_strategy_prob_weights_the_default_pool(monkeypatch):
    import smac_hard_gym.envs.core as core_module

    seen = {}

    def fake_make_opponent(spec, opponent, opponent_probs=None, isolation=None):
        seen.update(opponent=opponent, probs=opponent_probs)
        return Idle()

    monkeypatch.setattr(core_module, "make_opponent", fake_make_opponent)
    StarCraft2Env(map_name="3m", strategy_prob=[0.25, 0.75])
    assert seen == {"opponent": "default", "probs": [0.25, 0.75]}


def test_render_rgb_array_gives_a_frame_and_rejects_other_modes():
    env = StarCraft2Env(map_name="3m")
    env.reset()
    frame = env.render("rgb_array")
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    with pytest.raises(ValueError, match="render_mode must be"):
        env.render("ascii")
    env.close()


def test_import_stays_light_and_exports_the_env():
    code = ("import sys, smac_hard_gym; assert 'smac_hard_gym.envs.starcraft2' not in sys.modules; "
            "from smac_hard_gym import StarCraft2Env; "
            "assert StarCraft2Env.__module__ == 'smac_hard_gym.envs.starcraft2'")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


@pytest.mark.parametrize("mode", ["script", "self-play"])
def test_step_before_reset_raises_reset_needed(mode):
    env = StarCraft2Env(map_name="2m_vs_1z", mode=mode)
    actions = [[1, 1], [1]] if mode == "self-play" else [1, 1]
    with pytest.raises(ResetNeededError, match=r"call reset\(\) before step\(\): the episode has not started"):
        env.step(actions)
    assert issubclass(ResetNeededError, (gymnasium.error.ResetNeeded, RuntimeError))
    env.reset()
    env.step(actions)


def test_actions_are_ints_named_as_passed():
    env = StarCraft2Env(map_name="3m")
    env.reset()
    with pytest.raises(TypeError, match="red agent 2: action 3.5 is not a whole number"):
        env.step([1, 1, 3.5])
    with pytest.raises(TypeError, match="action True is a bool"):
        env.step([1, True, 1])
    with pytest.raises(InvalidActionError, match=r"action 1e\+19 is out of range"):
        env.step([1, 1, 1e19])
    with pytest.raises(InvalidActionError, match=f"action {2**70} is out of range"):
        env.step([1, 1, 2**70])
    env.step([1.0, 1, np.int8(1)])  # integral floats and numpy ints are actions


def test_torch_actions_as_pymarl_passes_them():
    torch = pytest.importorskip("torch")
    env = StarCraft2Env(map_name="3m")
    env.reset()
    env.step(torch.tensor([1, 1, 1]))  # pymarl: env.step(actions[0]) with a tensor row
    env.step([torch.tensor(1)] * 3)  # 0-d int tensors are integers (__index__)
    with pytest.raises(TypeError, match="is of type Tensor"):
        env.step([torch.tensor(1.5), 1, 1])
