"""SMACHardEnv: gymnasium's and SB3's checkers on every id, spaces against SMAC's sizes, masks, invalid actions,
episode ends, info, seeding, rendering."""

import sys
import types
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import smac_hard_gym
from smac_hard_gym.envs.gym_env import SMACHardEnv
from smac_hard_gym.smac.actions import InvalidActionError

# SMAC's default sizes per map: (n_agents, n_actions, obs_size, state_size) (docs/smac_interface.md §4 and §7).
SMAC_SIZES = {
    "3m": (3, 9, 30, 48), "8m": (8, 14, 80, 168), "25m": (25, 31, 250, 950), "5m_vs_6m": (5, 12, 55, 98),
    "8m_vs_9m": (8, 15, 85, 179), "10m_vs_11m": (10, 17, 105, 243), "27m_vs_30m": (27, 36, 285, 1170),
    "MMM": (10, 16, 160, 290), "MMM2": (10, 18, 176, 322), "2s3z": (5, 11, 80, 120), "3s5z": (8, 14, 128, 216),
    "3s5z_vs_3s6z": (8, 15, 136, 230), "3s_vs_3z": (3, 9, 36, 54), "3s_vs_4z": (3, 10, 42, 61),
    "3s_vs_5z": (3, 11, 48, 68), "1c3s5z": (9, 15, 162, 270), "2m_vs_1z": (2, 7, 16, 26),
    "corridor": (6, 30, 156, 282), "6h_vs_8z": (6, 14, 78, 140), "2s_vs_1sc": (2, 7, 17, 27),
    "so_many_baneling": (7, 38, 202, 397), "bane_vs_bane": (24, 30, 336, 984), "2c_vs_64zg": (2, 70, 332, 342),
}


@pytest.mark.parametrize("env_id", smac_hard_gym.ENV_IDS)
def test_gymnasium_and_sb3_checkers_pass_with_the_defaults(env_id):
    # The checkers step with unmasked random actions: the default invalid_action="noop" replaces unavailable ones.
    env = gym.make(env_id)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(env.unwrapped)
    with warnings.catch_warnings():
        # gymnasium's checker warns that it was handed a wrapped env; nothing else may go wrong.
        warnings.filterwarnings("ignore", message=".*is different from the unwrapped version")
        check_env(env, skip_render_check=True)
    env.action_space.seed(0)
    env.reset(seed=0)
    replaced = 0
    for _ in range(20):  # unmasked samples: most pick unavailable actions, which are replaced and counted
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        replaced += info["invalid_actions"]
        if terminated or truncated:
            env.reset()
    assert replaced > 0
    env.close()


def test_checker_with_render_modes_and_other_obs_modes():
    for obs_mode in ("joint+state", "dict"):
        env = gym.make("SMACHard-2s3z-v0", invalid_action="noop", obs_mode=obs_mode, render_mode="rgb_array")
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env.unwrapped)
        env.close()


@pytest.mark.parametrize("name", sorted(SMAC_SIZES))
def test_spaces_match_smac_sizes(name):
    n_agents, n_actions, obs_size, state_size = SMAC_SIZES[name]
    env = SMACHardEnv(name, obs_mode="joint+state")
    assert env.action_space == gym.spaces.MultiDiscrete([n_actions] * n_agents)
    assert env.observation_space.shape == (n_agents * obs_size + state_size,)
    assert env.action_masks().shape == (n_agents * n_actions,)
    env.close()


def _masked_sample(env, mask):
    n = env.unwrapped.n_agents
    return env.action_space.sample(mask=tuple(mask.reshape(n, -1)))


def test_masked_sampling_never_raises_and_masks_agree():
    # invalid_action="raise": one illegal action would end the test with InvalidActionError.
    env = gym.make("SMACHard-MMM-v0", invalid_action="raise")
    env.action_space.seed(0)
    episodes = 0
    obs, info = env.reset(seed=3)
    for _ in range(400):
        mask = info["action_mask"]
        assert mask.dtype == np.int8
        assert np.array_equal(mask, env.unwrapped.action_masks().astype(np.int8))
        assert mask.reshape(10, 16).any(axis=1).all()  # every agent has a legal action
        obs, reward, terminated, truncated, info = env.step(_masked_sample(env, mask))
        if terminated or truncated:
            episodes += 1
            obs, info = env.reset()
    assert episodes >= 2
    env.close()


def test_dead_agents_may_only_no_op():
    env = SMACHardEnv("3m", opponent="base")
    obs, info = env.reset(seed=0)
    rng = np.random.default_rng(0)
    saw_dead = False
    for _ in range(60):
        mask = env.action_masks().reshape(3, 9)
        alive = env.core.state.alive[0, :3]
        for i in range(3):
            if alive[i]:
                assert not mask[i, 0] and mask[i, 1]  # alive: stop always legal, no-op never
            else:
                saw_dead = True
                assert mask[i].tolist() == [True] + [False] * 8
        actions = [rng.choice(np.flatnonzero(row)) for row in mask]
        obs, reward, terminated, truncated, info = env.step(actions)
        if terminated or truncated:
            break
    assert saw_dead
    env.close()


def test_illegal_action_raises_naming_the_agent_and_the_switch():
    env = SMACHardEnv("3m", invalid_action="raise")
    env.reset(seed=0)
    # At the spawn the enemies are far beyond the shooting range: no attack is available.
    with pytest.raises(InvalidActionError, match=r"agent 1: action 7 \(attack enemy 1\) is not available.*"
                                                 r"invalid_action='noop'"):
        env.step([1, 7, 1])
    with pytest.raises(InvalidActionError, match="out of range"):
        env.step([1, 1, 99])
    with pytest.raises(ValueError, match=r"shape \(3,\) \(one action per agent\)"):
        env.step([1, 1])
    env.close()


def test_default_policy_replaces_unavailable_actions_but_rejects_values_outside_the_space():
    env = gym.make("SMACHard-3m-v0")
    assert env.unwrapped.invalid_action == "noop"
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([1, 7, 1]))
    assert info["invalid_actions"] == 1
    for bad, error in (([1, 1, 9], ValueError), ([1, 1, -1], ValueError), ([1, 1, 2.5], TypeError)):
        with pytest.raises(error):
            env.step(bad)
    env.close()


def test_noop_policy_replaces_illegal_actions_with_the_first_legal_one():
    replaced = SMACHardEnv("3m", invalid_action="noop")
    explicit = SMACHardEnv("3m")
    a, _ = replaced.reset(seed=5)
    b, _ = explicit.reset(seed=5)
    for _ in range(3):
        # Alive agents: the first legal action is stop (1); attacks at the spawn are illegal.
        a, ra, _, _, info = replaced.step([6, 7, 8])
        b, rb, _, _, _ = explicit.step([1, 1, 1])
        assert info["invalid_actions"] == 3
        np.testing.assert_array_equal(a, b)
        assert ra == rb
    replaced.close()
    explicit.close()


def test_bad_arguments_name_the_allowed_values():
    with pytest.raises(ValueError, match="obs_mode must be one of"):
        SMACHardEnv("3m", obs_mode="flat")
    with pytest.raises(ValueError, match="invalid_action must be one of"):
        SMACHardEnv("3m", invalid_action="ignore")
    with pytest.raises(ValueError, match="render_mode must be None or one of"):
        SMACHardEnv("3m", render_mode="ansi")
    with pytest.raises(ValueError, match="unknown map"):
        SMACHardEnv("4m")


def test_truncated_at_the_episode_limit_when_nobody_fights():
    # The "stop" script keeps blue still and red only stops: no shot is fired, so the limit (60 on 3m) ends it.
    env = SMACHardEnv("3m", opponent="stop")
    env.reset(seed=0)
    for step in range(1, 61):
        obs, reward, terminated, truncated, info = env.step([1, 1, 1])
        assert type(terminated) is bool and type(truncated) is bool and type(reward) is float
        assert not terminated
        assert truncated == (step == 60)
        assert reward == 0.0
    assert info == {**info, "battle_won": False, "dead_allies": 0, "dead_enemies": 0, "opponent": "stop"}
    with pytest.raises(RuntimeError, match="call reset"):
        env.step([1, 1, 1])
    env.close()


def test_terminated_on_a_battle_result_with_consistent_info():
    env = SMACHardEnv("3m", opponent="base", invalid_action="noop")
    rng = np.random.default_rng(1)
    results = []
    for seed in range(4):
        env.reset(seed=seed)
        terminated = truncated = False
        while not (terminated or truncated):
            mask = env.action_masks().reshape(3, 9)
            obs, reward, terminated, truncated, info = env.step([rng.choice(np.flatnonzero(m)) for m in mask])
        if terminated:
            results.append(info)
            alive = env.core.state.alive[0]
            assert info["dead_allies"] == 3 - alive[:3].sum() and info["dead_enemies"] == 3 - alive[3:].sum()
            assert info["dead_allies"] == 3 or info["dead_enemies"] == 3  # one side is gone
            assert info["battle_won"] == (info["dead_enemies"] == 3 and info["dead_allies"] < 3)
    assert results, "random play should end at least one battle before the limit"
    env.close()


def test_returned_data_is_fresh_every_call():
    env = SMACHardEnv("3m", obs_mode="dict")
    obs0, info0 = env.reset(seed=0)
    obs1, _, _, _, info1 = env.step([1, 1, 1])
    assert not np.shares_memory(obs0["obs"], obs1["obs"])
    assert not np.shares_memory(info0["action_mask"], info1["action_mask"])
    masks = env.action_masks()
    masks[:] = False
    assert env.action_masks().any()
    env.close()


def test_same_seed_same_trajectory_and_opponent_draws():
    def rollout(seed):
        env = SMACHardEnv("8m", opponent="default", invalid_action="noop")
        obs, info = env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        out = [obs, info["opponent"]]
        for _ in range(30):
            obs, reward, terminated, truncated, _ = env.step(rng.integers(0, 14, size=8))
            out += [obs, reward]
            if terminated or truncated:
                break
        env.close()
        return out

    first, again = rollout(11), rollout(11)
    assert all(np.array_equal(x, y) for x, y in zip(first, again, strict=True))
    names = {SMACHardEnv("8m", opponent="default").reset(seed=s)[1]["opponent"] for s in range(12)}
    assert names == {"line_front", "line_weakest", "base"}  # 8m's SMAC-HARD pool, drawn per seed


def test_obs_modes_share_one_encoding():
    joint = SMACHardEnv("2s3z", obs_mode="joint")
    both = SMACHardEnv("2s3z", obs_mode="joint+state")
    parts = SMACHardEnv("2s3z", obs_mode="dict")
    a, _ = joint.reset(seed=2)
    b, _ = both.reset(seed=2)
    c, info = parts.reset(seed=2)
    n = 5 * 80
    np.testing.assert_array_equal(a, b[:n])
    np.testing.assert_array_equal(a, c["obs"].reshape(-1))
    np.testing.assert_array_equal(b[n:], c["state"])
    np.testing.assert_array_equal(c["action_mask"].reshape(-1), info["action_mask"])
    assert joint.observation_space.contains(a) and both.observation_space.contains(b)
    assert parts.observation_space.contains(c)


def test_rgb_array_frames_and_record_video_wrapper(monkeypatch, tmp_path):
    from smac_hard_gym.render import BattleRenderer

    env = gym.make("SMACHard-3m-v0", render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    core = env.unwrapped.core
    expected = BattleRenderer("3m").render(core.state, 0, 0, core.opponent_names()[0])
    assert frame.dtype == np.uint8 and frame.shape == expected.shape and frame.shape[2] == 3
    np.testing.assert_array_equal(frame, expected)
    env.close()

    # gymnasium's RecordVideo needs moviepy to write files; a stand-in receives the frames it would encode.
    written = []

    class FakeClip:
        def __init__(self, frames, fps):
            written.append((list(frames), fps))

        def write_videofile(self, path, logger=None):
            written[-1] += (path,)

    fake = types.ModuleType("moviepy")
    clip_module = types.ModuleType("moviepy.video.io.ImageSequenceClip")
    clip_module.ImageSequenceClip = FakeClip
    for name, module in (("moviepy", fake), ("moviepy.video", types.ModuleType("moviepy.video")),
                         ("moviepy.video.io", types.ModuleType("moviepy.video.io")),
                         ("moviepy.video.io.ImageSequenceClip", clip_module)):
        monkeypatch.setitem(sys.modules, name, module)
    env = gym.wrappers.RecordVideo(gym.make("SMACHard-3m-v0", render_mode="rgb_array", opponent="stop"),
                                   str(tmp_path / "videos"), episode_trigger=lambda episode: True)
    env.reset(seed=0)
    for _ in range(4):
        env.step(np.array([1, 1, 1]))
    env.close()
    frames, fps, path = written[0]
    assert len(frames) == 5 and all(f.shape == expected.shape and f.dtype == np.uint8 for f in frames)
    assert fps == SMACHardEnv.metadata["render_fps"] and path.endswith(".mp4")


def test_render_without_mode_warns_and_returns_none():
    env = SMACHardEnv("3m")
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode=None"):
        assert env.render() is None
    env.close()


def test_step_before_reset_raises_reset_needed():
    env = SMACHardEnv("3m")
    with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before step\(\)"):
        env.step([1, 1, 1])
    env.reset(seed=0)
    env.step([1, 1, 1])
    env.close()
