"""NativeVectorEnv: equivalence with a SyncVectorEnv of single envs, autoreset modes pinned step by step, masks,
rendering and argument checks."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import smac_hard_gym  # noqa: F401  (registers the ids)
from smac_hard_gym.envs.gym_env import SMACHardEnv
from smac_hard_gym.envs.vector import NativeVectorEnv


def assert_same(a, b, path="data"):
    """Exact equality of nested gymnasium data: dicts, object arrays of observations, arrays, scalars."""
    if isinstance(a, dict):
        assert set(a) == set(b), (path, sorted(a), sorted(b))
        for key in a:
            assert_same(a[key], b[key], f"{path}.{key}")
    elif isinstance(a, np.ndarray) and a.dtype == object:
        assert a.shape == b.shape, path
        for x, y in zip(a, b, strict=True):
            assert_same(x, y, path + "[]")
    elif isinstance(a, np.ndarray):
        assert (a.dtype, a.shape) == (b.dtype, b.shape), (path, a.dtype, b.dtype, a.shape, b.shape)
        np.testing.assert_array_equal(a, b, err_msg=path)
    else:
        assert a == b, (path, a, b)


@pytest.mark.parametrize("mode", list(AutoresetMode))
@pytest.mark.parametrize("obs_mode", ["joint", "dict"])
def test_same_seeds_give_the_trajectories_of_single_envs(mode, obs_mode):
    n = 3
    kwargs = {"opponent": "default", "invalid_action": "noop", "max_episode_steps": 15, "obs_mode": obs_mode}
    native = gym.make_vec("SMACHard-3m-v0", num_envs=n, autoreset_mode=mode, **kwargs)
    sync = gym.make_vec("SMACHard-3m-v0", num_envs=n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kwargs)
    for got, want in zip(native.reset(seed=7), sync.reset(seed=7), strict=True):
        assert_same(got, want)
    rng = np.random.default_rng(0)
    ended = 0
    for t in range(45):
        masks = native.action_masks().reshape(n, 3, 9)
        actions = np.array([[rng.choice(np.flatnonzero(m)) for m in row] for row in masks])
        if t % 5 == 0:
            actions[t % n, 0] = 8  # often illegal: both sides replace it the same way
        got, want = native.step(actions), sync.step(actions)
        for name, x, y in zip(("obs", "reward", "terminated", "truncated", "infos"), got, want, strict=True):
            assert_same(x, y, name)
        done = got[2] | got[3]
        ended += done.sum()
        if mode == AutoresetMode.DISABLED and done.any():
            for x, y in zip(native.reset(options={"reset_mask": done}),
                            sync.reset(options={"reset_mask": done.copy()}), strict=True):
                assert_same(x, y, "reset")
    assert ended >= 2 * n  # episodes ended (by the battle or the 15-step limit) and were restarted
    native.close()
    sync.close()


def _pinned_env(mode):
    # Nobody fights (blue's "stop" script, red only stops) and episodes last 3 steps: every end is a truncation
    # at a known step. The observation's timestep column is episode_step / 60 (3m's SMAC limit).
    env = NativeVectorEnv("3m", 2, autoreset_mode=mode, opponent="stop", max_episode_steps=3,
                          obs_timestep_number=True)
    column = env.core.features[0].obs_feature_names().index("own_timestep")
    return env, (lambda obs: np.rint(np.asarray(obs)[..., column] * 60).astype(int).tolist())


STOP = np.ones((2, 3), dtype=np.int64)


def _desync(env, steps_of):
    obs, _ = env.reset(seed=0)
    assert steps_of(obs) == [0, 0]
    obs, *_ = env.step(STOP)
    assert steps_of(obs) == [1, 1]
    obs, infos = env.reset(options={"reset_mask": np.array([True, False])})
    assert steps_of(obs) == [0, 1]
    assert infos["_action_mask"].tolist() == [True, False] and infos["opponent"].tolist() == ["stop", None]
    obs, *_ = env.step(STOP)
    assert steps_of(obs) == [1, 2]


def test_next_step_autoreset_pinned():
    env, steps_of = _pinned_env(AutoresetMode.NEXT_STEP)
    _desync(env, steps_of)
    obs, reward, terminated, truncated, infos = env.step(STOP)
    assert steps_of(obs) == [2, 3]  # battle 1 returns its terminal observation
    assert truncated.tolist() == [False, True] and not terminated.any()
    obs, reward, terminated, truncated, infos = env.step(STOP)
    assert steps_of(obs) == [3, 0]  # battle 1's action was ignored: it restarted
    assert truncated.tolist() == [True, False] and reward.tolist() == [0.0, 0.0]
    assert infos["_battle_won"].tolist() == [True, False]  # step info only for the battle that stepped
    assert infos["_action_mask"].tolist() == [True, True]  # a new episode's info for the other
    obs, *_ = env.step(STOP)
    assert steps_of(obs) == [0, 1]
    env.close()


def test_same_step_autoreset_pinned():
    env, steps_of = _pinned_env(AutoresetMode.SAME_STEP)
    _desync(env, steps_of)
    obs, reward, terminated, truncated, infos = env.step(STOP)
    assert truncated.tolist() == [False, True]
    assert steps_of(obs) == [2, 0]  # battle 1 already started its next episode
    assert infos["_final_obs"].tolist() == [False, True] and infos["final_obs"][0] is None
    assert steps_of(infos["final_obs"][1]) == 3
    final = infos["final_info"]
    assert final["_battle_won"].tolist() == [False, True] and final["dead_allies"][1] == 0
    assert infos["_battle_won"].tolist() == [True, False]  # battle 1's step info lives in final_info
    assert infos["_opponent"].tolist() == [True, True]
    np.testing.assert_array_equal(infos["action_mask"] != 0, env.action_masks())
    obs, reward, terminated, truncated, infos = env.step(STOP)
    assert truncated.tolist() == [True, False] and steps_of(obs) == [0, 1]
    env.close()


def test_disabled_autoreset_needs_a_reset_mask_after_an_episode_ends():
    env, steps_of = _pinned_env(AutoresetMode.DISABLED)
    _desync(env, steps_of)
    obs, reward, terminated, truncated, infos = env.step(STOP)
    assert truncated.tolist() == [False, True] and steps_of(obs) == [2, 3]
    assert "final_obs" not in infos
    with pytest.raises(RuntimeError, match=r"battles \[1\] ended .*reset_mask"):
        env.step(STOP)
    obs, _ = env.reset(options={"reset_mask": np.array([False, True])})
    assert steps_of(obs) == [2, 0]
    obs, reward, terminated, truncated, infos = env.step(STOP)
    assert steps_of(obs) == [3, 1] and truncated.tolist() == [True, False]
    env.close()


def test_masks_batched_and_in_infos():
    env = NativeVectorEnv("MMM", 4, autoreset_mode="SameStep", opponent="base")
    obs, infos = env.reset(seed=0)
    masks = env.action_masks()
    assert masks.shape == (4, 10 * 16) and masks.dtype == bool
    np.testing.assert_array_equal(infos["action_mask"] != 0, masks)
    assert masks.reshape(4, 10, 16).any(axis=2).all()
    rng = np.random.default_rng(0)
    for _ in range(20):
        rows = masks.reshape(4, 10, 16)
        actions = np.array([[rng.choice(np.flatnonzero(m)) for m in battle] for battle in rows])
        obs, reward, terminated, truncated, infos = env.step(actions)
        masks = env.action_masks()
        np.testing.assert_array_equal(infos["action_mask"] != 0, masks)
    env.close()


def test_rendering_one_battle_or_a_grid():
    env = NativeVectorEnv("3m", 3, render_mode="rgb_array", render_battles=1, opponent="base")
    single = SMACHardEnv("3m", render_mode="rgb_array", opponent="base")
    env.reset(seed=4)
    single.reset(seed=5)  # battle 1 of a batch seeded 4 plays like a single env seeded 5
    for _ in range(3):
        env.step(np.ones((3, 3), dtype=np.int64))
        single.step([1, 1, 1])
    np.testing.assert_array_equal(env.render(), single.render())
    grid = NativeVectorEnv("3m", 3, render_mode="rgb_array", render_battles="all")
    grid.reset(seed=0)
    frame = grid.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.size > 2 * single.render().size
    for e in (env, single, grid):
        e.close()


def test_repr_and_bad_arguments():
    env = gym.make_vec("SMACHard-3m-v0", num_envs=2)
    assert repr(env) == "NativeVectorEnv(SMACHard-3m-v0, num_envs=2, autoreset_mode=NextStep)"
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions must have shape \(2, 3\)"):
        env.step(np.ones((3, 3), dtype=np.int64))
    with pytest.raises(ValueError, match="reset_mask"):
        env.reset(options={"reset_mask": np.array([1, 0])})
    with pytest.raises(ValueError, match="seed must be"):
        env.reset(seed=[1])
    env.close()
    with pytest.raises(ValueError, match="num_envs must be a positive int"):
        NativeVectorEnv("3m", 0)
    with pytest.raises(ValueError, match="autoreset_mode must be an AutoresetMode or one of"):
        NativeVectorEnv("3m", 2, autoreset_mode="sometimes")
    with pytest.raises(ValueError, match="render_battles must"):
        NativeVectorEnv("3m", 2, render_battles=5)
    with pytest.raises(ValueError, match="max_episode_steps"):
        NativeVectorEnv("3m", 2, max_episode_steps=0)


def test_step_before_reset_and_malformed_actions_raise_and_change_nothing():
    env = NativeVectorEnv("3m", 2, opponent="base")
    assert env.invalid_action == "noop"  # the single env's default
    with pytest.raises(gym.error.ResetNeeded, match=r"call reset\(\) before step\(\)"):
        env.step(np.ones((2, 3), dtype=np.int64))
    env.reset(seed=0)
    x = env.core.state.x.copy()
    for actions, error in (([[1, 1, 1], [1, 1, 2.5]], TypeError), ([[1, 1, 1], [1, True, 1]], TypeError),
                           (np.array([[1, 1, 1], [1, 1, 1e19]]), ValueError), ([[1, 1, 1], [-1, 1, 1]], ValueError)):
        with pytest.raises(error, match="battle 1, red agent"):
            env.step(actions)
    np.testing.assert_array_equal(env.core.state.x, x)
    assert env.core.episode_step.tolist() == [0, 0]
    _, _, _, _, infos = env.step([[1, 1, 1], [6, 1, 1]])  # an unavailable attack is replaced, and counted
    assert infos["invalid_actions"].tolist() == [0, 1]
    env.close()


@pytest.mark.parametrize("mode", ["SameStep", "NextStep"])
def test_returned_observations_are_never_changed_by_later_resets(mode):
    # The core splices restarted battles into the arrays of the step it just made (in place, for speed): arrays the
    # env has already returned must stay as they were, through autoresets and a user's partial reset.
    env = NativeVectorEnv("3m", 4, autoreset_mode=mode, max_episode_steps=3, obs_mode="dict")
    obs, _ = env.reset(seed=0)
    kept = []
    for _ in range(7):
        kept.append((obs, {key: value.copy() for key, value in obs.items()}))
        masks = env.action_masks().reshape(4, 3, -1)
        obs, *_ = env.step(masks.argmax(axis=2))
    kept.append((obs, {key: value.copy() for key, value in obs.items()}))
    env.reset(options={"reset_mask": np.array([True, False, True, False])})
    for returned, copy in kept:
        for key in copy:
            np.testing.assert_array_equal(returned[key], copy[key])
    env.close()
