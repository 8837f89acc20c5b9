"""The SB3 VecEnv adapter: terminal observations, TimeLimit.truncated, masks without round trips, autoreset modes,
VecMonitor, MaskablePPO and MaskableEvalCallback."""

import warnings

import gymnasium as gym
import numpy as np
import pytest
import torch
from gymnasium.vector import AutoresetMode
from sb3_contrib import MaskablePPO
from sb3_contrib.common.maskable.callbacks import MaskableEvalCallback
from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import VecMonitor

import smac_hard_gym  # noqa: F401  (registers the ids)
from smac_hard_gym.envs.subproc import make_subproc_env
from smac_hard_gym.envs.vector import NativeVectorEnv
from smac_hard_gym.wrappers.sb3 import SB3VecEnv

torch.set_num_threads(1)


def _pinned(mode, n=2):
    # Nobody fights and episodes end by truncation after 3 steps; the timestep column tells the step.
    env = NativeVectorEnv("3m", n, autoreset_mode=mode, opponent="stop", max_episode_steps=3,
                          obs_timestep_number=True)
    column = env.core.features[0].obs_feature_names().index("own_timestep")
    return env, (lambda obs: np.rint(np.asarray(obs)[..., column] * 60).astype(int).tolist())


@pytest.mark.parametrize("mode", [AutoresetMode.SAME_STEP, AutoresetMode.DISABLED])
def test_terminal_observation_and_time_limit_flag(mode):
    env, steps_of = _pinned(mode)
    venv = SB3VecEnv(env)
    obs = venv.reset()
    assert steps_of(obs) == [0, 0]
    stop = np.ones((2, 3), dtype=np.int64)
    for _ in range(2):
        obs, rewards, dones, infos = venv.step(stop)
        assert not dones.any() and "terminal_observation" not in infos[0]
    obs, rewards, dones, infos = venv.step(stop)
    assert dones.tolist() == [True, True] and rewards.dtype == np.float32
    assert steps_of(obs) == [0, 0]  # SB3 wants the next episode's first observation back
    for info in infos:
        assert steps_of(info["terminal_observation"]) == 3
        assert info["TimeLimit.truncated"] is True  # truncated, not terminated: PPO bootstraps
        assert info["is_success"] is False and info["opponent"] == "stop" and info["dead_allies"] == 0
    assert venv.reset_infos[0]["opponent"] == "stop"
    venv.close()


def test_a_battle_result_is_terminal_not_truncated():
    # Blue's "stop" script waits: red's marines walk up and attack, and one side is destroyed before the limit.
    venv = SB3VecEnv(NativeVectorEnv("3m", 1, autoreset_mode="SameStep", opponent="stop"))
    venv.reset()
    for _ in range(60):
        mask = venv.env_method("action_masks")[0].reshape(3, 9)
        attack = mask[:, 6:]
        # attack, else move east, else (dead) the only legal action
        actions = np.where(attack.any(axis=1), 6 + attack.argmax(axis=1), np.where(mask[:, 4], 4, mask.argmax(1)))
        obs, rewards, dones, infos = venv.step(actions[None])
        if dones[0]:
            break
    assert dones[0] and infos[0]["TimeLimit.truncated"] is False
    assert infos[0]["is_success"] == infos[0]["battle_won"]
    venv.close()


def test_next_step_vector_envs_are_refused_with_the_fix():
    with pytest.raises(ValueError, match="autoreset_mode='SameStep'"):
        SB3VecEnv(gym.make_vec("SMACHard-3m-v0", num_envs=2))
    with pytest.raises(TypeError, match="gymnasium.vector.VectorEnv"):
        SB3VecEnv(gym.make("SMACHard-3m-v0"))


def test_masks_are_served_without_a_round_trip_to_the_workers(monkeypatch):
    sub = make_subproc_env("3m", 2, 2, autoreset_mode="SameStep", opponent="base")
    try:
        venv = SB3VecEnv(sub)
        venv.reset()
        sent = []
        monkeypatch.setattr(type(sub), "_send", lambda self, *args: sent.append(args) or True)
        masks = get_action_masks(venv)
        assert sent == [] and masks.shape == (4, 27) and is_masking_supported(venv)
        np.testing.assert_array_equal(masks, sub.action_masks())
        monkeypatch.undo()
        rng = np.random.default_rng(0)
        for _ in range(30):
            masks = get_action_masks(venv).reshape(4, 3, 9)
            actions = np.array([[rng.choice(np.flatnonzero(m)) for m in row] for row in masks])
            venv.step(actions)  # an illegal action would raise: the served masks are the current ones
    finally:
        sub.close()


def test_adapter_over_a_sync_vector_env_of_single_envs():
    sync = gym.make_vec("SMACHard-3m-v0", num_envs=2, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": AutoresetMode.SAME_STEP}, wrappers=[Monitor])
    venv = SB3VecEnv(sync)
    venv.reset()
    assert venv.env_is_wrapped(Monitor) == [True, True]
    assert venv.get_attr("render_mode") == [None, None]
    np.testing.assert_array_equal(np.stack(venv.env_method("action_masks")),
                                  np.stack([e.unwrapped.action_masks() for e in sync.envs]))
    venv.close()
    native = SB3VecEnv(NativeVectorEnv("3m", 2, autoreset_mode="SameStep"))
    assert native.env_is_wrapped(Monitor) == [False, False]
    native.close()


def test_maskable_ppo_and_eval_callback_run_without_warnings(tmp_path):
    train_env = VecMonitor(SB3VecEnv(gym.make_vec("SMACHard-3m-v0", num_envs=4, autoreset_mode="SameStep",
                                                  opponent="base")))
    eval_env = VecMonitor(SB3VecEnv(gym.make_vec("SMACHard-3m-v0", num_envs=2, autoreset_mode="SameStep",
                                                 opponent="base")))
    # eval_freq counts vector steps: 512 env steps over 4 envs are 128 calls, so two evaluations.
    callback = MaskableEvalCallback(eval_env, n_eval_episodes=2, eval_freq=64, log_path=str(tmp_path), verbose=0)
    model = MaskablePPO("MlpPolicy", train_env, n_steps=64, batch_size=128, n_epochs=2, seed=0, device="cpu")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.learn(512, callback=callback)
    assert model.num_timesteps == 512
    assert len(model.ep_info_buffer) > 0  # VecMonitor saw whole episodes
    assert len(callback.evaluations_results) == 2 and len(callback.evaluations_successes[0]) == 2
    train_env.close()
    eval_env.close()


# the masks applied after proba_distribution: MaskablePPO applies them once (or never); None lifts them
MASKINGS = {"masked": ["masks"], "never": [], "lifted": [None], "masked-then-lifted": ["masks", None],
            "lifted-then-masked": [None, "masks"], "masked-twice": ["masks", "masks"]}


@pytest.mark.parametrize("masking", MASKINGS)
def test_batched_joint_distribution_matches_sb3_contribs_multicategorical(masking):
    from sb3_contrib.common.maskable.distributions import MaskableMultiCategoricalDistribution

    from smac_hard_gym.wrappers.sb3_policy import BatchedMaskableMultiCategorical

    dims, batch = [9] * 5, 64
    gen = torch.Generator().manual_seed(0)
    logits = torch.randn(batch, sum(dims), generator=gen, requires_grad=True)
    masks = torch.rand(batch, sum(dims), generator=gen) < 0.6
    masks.view(batch, 5, 9)[:, :, 1] = True  # every unit has a legal action (stop), as in SMAC
    stock, ours = MaskableMultiCategoricalDistribution(dims), BatchedMaskableMultiCategorical(dims)
    for dist in (stock, ours):
        dist.proba_distribution(logits)
        for mask in MASKINGS[masking]:
            dist.apply_masking(None if mask is None else masks.numpy())
    torch.manual_seed(3)
    sampled = stock.sample()
    torch.manual_seed(3)
    assert torch.equal(ours.sample(), sampled)  # the same random numbers pick the same actions
    if MASKINGS[masking][-1:] == ["masks"]:
        assert masks.view(batch, 5, 9).gather(2, sampled.unsqueeze(-1)).all()  # never a masked action
    assert torch.equal(ours.mode(), stock.mode())
    assert torch.equal(ours.log_prob(sampled), stock.log_prob(sampled))
    assert torch.equal(ours.entropy(), stock.entropy())
    grads = [torch.autograd.grad((d.log_prob(sampled) + 0.01 * d.entropy()).sum(), logits)[0] for d in (stock, ours)]
    assert torch.equal(grads[0], grads[1])
    with pytest.raises(ValueError, match=r"action_dims must all be equal.*\[9, 8\]"):
        BatchedMaskableMultiCategorical([9, 8])


@pytest.mark.parametrize("obs_mode", ["joint", "dict"])
def test_joint_policies_and_buffers_train_the_same_weights_as_sb3_contribs(obs_mode):
    from smac_hard_gym.wrappers.sb3_buffers import MaskableJointDictRolloutBuffer, MaskableJointRolloutBuffer
    from smac_hard_gym.wrappers.sb3_policy import MaskableJointMultiInputPolicy, MaskableJointPolicy

    ours = MaskableJointPolicy if obs_mode == "joint" else MaskableJointMultiInputPolicy
    our_buffer = MaskableJointRolloutBuffer if obs_mode == "joint" else MaskableJointDictRolloutBuffer
    stock = "MlpPolicy" if obs_mode == "joint" else "MultiInputPolicy"
    weights = []
    for policy, buffer in ((stock, None), (ours, our_buffer)):
        venv = VecMonitor(SB3VecEnv(NativeVectorEnv("3m", 4, autoreset_mode="SameStep", opponent="smac",
                                                    obs_mode=obs_mode)))
        model = MaskablePPO(policy, venv, n_steps=64, batch_size=128, n_epochs=2, seed=7, device="cpu",
                            rollout_buffer_class=buffer)
        model.learn(512)
        weights.append([p.detach().clone() for p in model.policy.parameters()])
        venv.close()
    assert all(torch.equal(a, b) for a, b in zip(*weights, strict=True))
    assert not all(torch.equal(a, b) for a, b in zip(weights[0], _fresh_weights(stock, obs_mode), strict=True))


def _filled_buffers(n_steps, n_envs, seed):
    # sb3-contrib's buffer and ours over one 3m rollout of random numbers (3 units x 9 actions, 30 features)
    from sb3_contrib.common.maskable.buffers import MaskableRolloutBuffer

    from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer

    obs_space = gym.spaces.Box(-1, 1, (30,), np.float32)
    act_space = gym.spaces.MultiDiscrete([9, 9, 9])
    buffers = [cls(n_steps, obs_space, act_space, n_envs=n_envs) for cls in (MaskableRolloutBuffer,
                                                                                MaskableJointRolloutBuffer)]
    rng = np.random.default_rng(seed)
    for _ in range(n_steps):
        step = dict(obs=rng.standard_normal((n_envs, 30)).astype(np.float32),
                    action=rng.integers(0, 9, (n_envs, 3)), reward=rng.standard_normal(n_envs),
                    episode_start=rng.random(n_envs) < 0.1, value=torch.randn(n_envs, 1),
                    log_prob=torch.randn(n_envs), action_masks=rng.random((n_envs, 27)) < 0.7)
        for buffer in buffers:
            buffer.add(**step)
    last = torch.randn(n_envs, 1)
    for buffer in buffers:
        buffer.compute_returns_and_advantage(last, np.zeros(n_envs, dtype=bool))
    return buffers


@pytest.mark.parametrize("batch_size", [None, 48, 1000])
def test_a_whole_rollout_minibatch_holds_sb3s_samples_in_rollout_order(batch_size):
    # 8 steps x 6 battles = 48 samples: None, 48 and 1000 are one minibatch of all of them; SB3 draws them in a
    # permutation of the global numpy RNG, ours in the rollout's own order (battle-major, as SB3 flattens), once.
    stock, ours = _filled_buffers(8, 6, seed=1)
    np.random.seed(5)
    permutation = np.random.permutation(48)
    np.random.seed(5)
    [sb3] = list(stock.get(batch_size))
    first_epoch, second_epoch = list(ours.get(batch_size)), list(ours.get(batch_size))
    assert len(first_epoch) == 1 and second_epoch[0] is first_epoch[0]  # built once per update
    whole = first_epoch[0]
    for name in whole._fields:
        assert torch.equal(getattr(whole, name)[permutation], getattr(sb3, name)), name
    ours.reset()  # a new rollout: the old samples are gone
    assert ours._whole is None


def test_smaller_minibatches_are_sb3s_own():
    stock, ours = _filled_buffers(8, 6, seed=2)
    batches = []
    for buffer in (stock, ours):
        np.random.seed(9)
        batches.append(list(buffer.get(16)))
    assert len(batches[1]) == 3
    for a, b in zip(*batches, strict=True):
        assert all(torch.equal(x, y) for x, y in zip(a, b, strict=True))


def test_one_minibatch_training_agrees_with_sb3_contribs_to_float_rounding():
    # The same losses summed in another order: equal weights up to rounding, after 4 updates of 3 epochs.
    from sb3_contrib.common.maskable.buffers import MaskableRolloutBuffer

    from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer

    weights = []
    for buffer in (MaskableRolloutBuffer, MaskableJointRolloutBuffer):
        venv = VecMonitor(SB3VecEnv(NativeVectorEnv("3m", 4, autoreset_mode="SameStep", opponent="smac")))
        model = MaskablePPO("MlpPolicy", venv, n_steps=64, batch_size=None, n_epochs=3, seed=7, device="cpu",
                            rollout_buffer_class=buffer)
        model.learn(1024)
        weights.append([p.detach().clone() for p in model.policy.parameters()])
        venv.close()
    assert all(torch.allclose(a, b, rtol=0, atol=1e-5) for a, b in zip(*weights, strict=True))
    assert not all(torch.allclose(a, b, rtol=0, atol=1e-5)
                   for a, b in zip(weights[0], _fresh_weights("MlpPolicy", "joint"), strict=True))


def _fresh_weights(policy, obs_mode):
    venv = SB3VecEnv(NativeVectorEnv("3m", 4, autoreset_mode="SameStep", opponent="smac", obs_mode=obs_mode))
    model = MaskablePPO(policy, venv, n_steps=64, batch_size=128, seed=7, device="cpu")
    return [p.detach().clone() for p in model.policy.parameters()]
