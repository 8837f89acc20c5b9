"""Stacked frames (``frame_stack``): each agent's last k SMAC observations, newest first, zeros before the episode's
first step; the same in the single env, the vector env (every autoreset mode), a policy opponent and a saved model."""

from __future__ import annotations

import numpy as np
import pytest

from smac_hard_gym.envs.gym_env import SMACHardEnv
from smac_hard_gym.envs.vector import NativeVectorEnv
from smac_hard_gym.smac.frame_stack import UnitFrames

N, ACTIONS = 3, 9  # 3m: three marines, nine actions each


def _random_legal(masks, rng):
    masks = masks.reshape(len(masks), N, ACTIONS)
    return np.array([[rng.choice(np.flatnonzero(unit)) for unit in row] for row in masks])


def test_unit_frames_keep_each_agents_last_k_observations_newest_first():
    frames = UnitFrames(2, 2, 3, k=3)
    first = np.arange(12, dtype=np.float32).reshape(2, 2, 3)
    frames.push(np.array([True, True]), first)
    out = frames.stacked()
    assert out.shape == (2, 2, 9)
    np.testing.assert_array_equal(out[1, 0], [6, 7, 8, 0, 0, 0, 0, 0, 0])  # battle 1, agent 0: one frame so far
    frames.push(np.array([1]), first[1:] + 100)  # only battle 1 moves on
    np.testing.assert_array_equal(frames.stacked()[1, 1], [109, 110, 111, 9, 10, 11, 0, 0, 0])
    np.testing.assert_array_equal(frames.stacked()[0], out[0])  # battle 0 untouched
    frames.clear(np.array([True, False]))
    assert not frames.stacked()[0].any() and frames.stacked()[1].any()


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "4", 65])
def test_bad_frame_stack_is_refused_naming_the_value(bad):
    pattern = r"frame_stack must be an int in 1\.\.64.*got " + repr(bad).replace(".", r"\.")
    with pytest.raises(ValueError, match=pattern):
        NativeVectorEnv("3m", 1, frame_stack=bad)


@pytest.mark.parametrize("mode", ["SameStep", "NextStep"])
def test_vector_env_stacks_each_battles_own_history_across_episode_ends(mode):
    """Step stacked (k=3) and plain battles with the same seeds and actions: the stacked block's frame j is the plain
    observation j steps back in the same episode, zeros before the episode's first; the state is not stacked."""
    k, battles = 3, 4
    stacked = NativeVectorEnv("3m", battles, autoreset_mode=mode, opponent="smac", obs_mode="joint+state",
                              frame_stack=k)
    plain = NativeVectorEnv("3m", battles, autoreset_mode=mode, opponent="smac", obs_mode="joint+state")
    d = plain.view.obs_size
    assert stacked.single_observation_space.shape == (N * k * d + plain.view.state_size,)
    obs_k, _ = stacked.reset(seed=3)
    obs_1, _ = plain.reset(seed=3)
    history = [[obs_1[b, :N * d].reshape(N, d)] for b in range(battles)]  # plain observations of the episode so far
    restart_next = np.zeros(battles, dtype=bool)  # NextStep: the step after an end returns a new episode's first
    rng = np.random.default_rng(0)
    ends = 0

    def expected(frames):
        return np.stack((frames[::-1] + [np.zeros((N, d), np.float32)] * k)[:k], axis=1)

    for _ in range(150):
        actions = _random_legal(plain.action_masks(), rng)
        obs_k, rew_k, term_k, trunc_k, info_k = stacked.step(actions)
        obs_1, rew_1, term_1, trunc_1, info_1 = plain.step(actions)
        np.testing.assert_array_equal(rew_k, rew_1)
        np.testing.assert_array_equal(term_k | trunc_k, term_1 | trunc_1)
        np.testing.assert_array_equal(obs_k[:, N * k * d:], obs_1[:, N * d:])  # the state, once, at the end
        for b in range(battles):
            done = bool(term_1[b] or trunc_1[b])
            current = obs_1[b, :N * d].reshape(N, d)
            if restart_next[b]:
                history[b], restart_next[b] = [], False
            if done and mode == "SameStep":  # the terminal frames continue the old episode; then a new one starts
                terminal = info_1["final_obs"][b][:N * d].reshape(N, d)
                np.testing.assert_array_equal(info_k["final_obs"][b][:N * k * d].reshape(N, k, d),
                                              expected(history[b] + [terminal]))
                history[b] = []
            history[b].append(current)
            np.testing.assert_array_equal(obs_k[b, :N * k * d].reshape(N, k, d), expected(history[b]))
            if done:
                ends += 1
                restart_next[b] = mode == "NextStep"
    assert ends >= 4  # several episodes ended, so resets were crossed
    stacked.close()
    plain.close()


def test_single_env_and_dict_mode_stack_like_the_vector_env():
    k = 2
    single = SMACHardEnv("3m", opponent="smac", frame_stack=k)
    vector = NativeVectorEnv("3m", 1, autoreset_mode="SameStep", opponent="smac", obs_mode="dict", frame_stack=k)
    assert vector.single_observation_space["obs"].shape == (N, k * vector.core.features[0].obs_size)
    obs_s, _ = single.reset(seed=7)
    obs_v, _ = vector.reset(seed=7)
    rng = np.random.default_rng(1)
    for _ in range(20):
        np.testing.assert_array_equal(obs_s, obs_v["obs"][0].reshape(-1))
        actions = _random_legal(vector.action_masks(), rng)
        obs_s, _, term, trunc, _ = single.step(actions[0])
        obs_v, *_ = vector.step(actions)
        if term or trunc:
            break
    single.close()
    vector.close()


class _Recorder:
    """A policy that stands still and records what it is given; ``frame_stack`` says it reads two frames."""

    frame_stack = 2

    def __init__(self):
        self.seen = []

    def __call__(self, obs, masks):
        self.seen.append(obs.copy())
        return np.zeros(masks.shape[:2], dtype=np.int64) + 1  # stop


def test_a_policy_opponent_gets_its_own_sides_stacked_frames():
    from smac_hard_gym.opponents.policy import PolicyScript
    from smac_hard_gym.smac.features import SideFeatures

    recorder = _Recorder()
    script = PolicyScript(recorder, name="recorder")
    assert script.frame_stack == 2
    env = NativeVectorEnv("3m", 2, autoreset_mode="SameStep", opponent=script)
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.ones((2, N), dtype=np.int64))  # red stops too: nothing dies
    d = SideFeatures(env.core.spec, 1, script.options).obs_size
    first, second = recorder.seen[0], recorder.seen[1]
    assert first.shape == (2, N, 2 * d)
    assert not first[:, :, d:].any()  # before the episode's first step: zeros
    np.testing.assert_array_equal(second[:, :, d:], first[:, :, :d])  # the older frame is the last call's newest
    env.close()


def test_a_model_trained_on_stacked_frames_records_them_and_plays_as_an_opponent(tmp_path):
    pytest.importorskip("sb3_contrib")
    from smac_hard_gym.opponents.policy import PolicyScript
    from smac_hard_gym.training import TrainConfig
    from smac_hard_gym.training.league import snapshot
    from smac_hard_gym.training.loop import train
    from smac_hard_gym.training.run_files import load_model, load_run_config

    for policy in ("shared", "joint"):
        out = tmp_path / policy
        config = TrainConfig(map_name="3m", opponent="smac", policy=policy, frame_stack=3, timesteps=256,
                             num_envs=4, n_steps=32, batch_size=64, n_epochs=1, eval_episodes=2, eval_envs=2,
                             out=str(out), progress=False)
        train(config, log=lambda _: None)
        model = load_model(out / "model.zip")
        assert model.policy.frame_stack == 3
        assert load_run_config(out / "model.zip").env_kwargs()["frame_stack"] == 3
        script = PolicyScript.load(out / "model.zip")
        assert script.frame_stack == 3
        assert snapshot(model, "league member").frame_stack == 3  # a league snapshot reads the frames too
        env = NativeVectorEnv("3m", 2, autoreset_mode="SameStep", opponent=script)
        env.reset(seed=0)
        for _ in range(5):
            env.step(np.ones((2, N), dtype=np.int64))
        env.close()


def test_subprocess_workers_stack_frames_as_the_native_env_does():
    from smac_hard_gym.envs.subproc import make_subproc_env

    kwargs = {"opponent": "smac", "obs_mode": "joint+state", "frame_stack": 2, "max_episode_steps": 10}
    native = NativeVectorEnv("3m", 4, autoreset_mode="SameStep", **kwargs)
    workers = make_subproc_env("3m", 2, 2, autoreset_mode="SameStep", **kwargs)
    try:
        assert workers.single_observation_space == native.single_observation_space
        np.testing.assert_array_equal(workers.reset(seed=4)[0], native.reset(seed=4)[0])
        rng = np.random.default_rng(2)
        for _ in range(25):  # episodes of 10 steps: resets crossed
            actions = _random_legal(native.action_masks(), rng)
            got, want = workers.step(actions), native.step(actions)
            np.testing.assert_array_equal(got[0], want[0])
            for b in np.flatnonzero(want[2] | want[3]):
                np.testing.assert_array_equal(got[4]["final_obs"][b], want[4]["final_obs"][b])
    finally:
        workers.close()
        native.close()
