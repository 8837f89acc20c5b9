"""MAPPO's per-unit policy loss for MaskablePPO (wrappers/sb3_unit_ppo.py): the surrogate worked by hand, the old
per-unit log-probabilities against the rollout's recorded joint ones, save/load as a plain MaskablePPO model, the
train options that select it, and a short learning check."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

pytest.importorskip("sb3_contrib")

from sb3_contrib import MaskablePPO  # noqa: E402
from stable_baselines3.common.vec_env import VecMonitor  # noqa: E402

from smac_hard_gym.envs.vector import NativeVectorEnv  # noqa: E402
from smac_hard_gym.training import TEST_SEED_BASE, TrainConfig, distribution_checks_off, evaluate  # noqa: E402
from smac_hard_gym.wrappers.sb3 import SB3VecEnv  # noqa: E402
from smac_hard_gym.wrappers.sb3_shared import (  # noqa: E402
    SharedUnitPolicy,
    SharedUnitRolloutBuffer,
    shared_policy_kwargs,
)
from smac_hard_gym.wrappers.sb3_unit_ppo import UnitRatioMaskablePPO, unit_clipped_surrogate  # noqa: E402

torch.set_num_threads(1)


def _venv(map_name="3m", n=4, opponent="smac"):
    return VecMonitor(SB3VecEnv(NativeVectorEnv(map_name, n, autoreset_mode="SameStep", opponent=opponent,
                                                obs_mode="joint+state")))


def _model(venv, **kwargs):
    settings = {"n_steps": 16, "batch_size": 64, "n_epochs": 2, "seed": 0, "device": "cpu", **kwargs}
    return UnitRatioMaskablePPO(SharedUnitPolicy, venv, rollout_buffer_class=SharedUnitRolloutBuffer,
                                policy_kwargs=shared_policy_kwargs(venv), **settings)


# ---------------------------------------------------------------------------------------------------------------
# The loss, by hand.


def _case():
    """Two battle-steps of two units. Step 0: advantage +1, unit 0 living with ratio 1.5, unit 1 dead (its ratio, 3,
    must not count). Step 1: advantage -2, unit 0 ratio 0.5, unit 1 ratio 1.1."""
    ratios = torch.tensor([[1.5, 3.0], [0.5, 1.1]], dtype=torch.float64)
    log_prob = ratios.log().requires_grad_(True)
    old = torch.zeros(2, 2, dtype=torch.float64)
    living = torch.tensor([[True, False], [True, True]])
    return log_prob, old, torch.tensor([1.0, -2.0], dtype=torch.float64), living


def test_the_surrogate_clips_each_living_units_ratio_by_hand():
    # min(r A, clip(r, 0.8, 1.2) A) per living unit: 1.5 * 1 -> 1.2 (clipped); 0.5 * -2 = -1.0 against
    # 0.8 * -2 = -1.6 -> -1.6 (clipped); 1.1 * -2 = -2.2 (inside). Loss = -(1.2 - 1.6 - 2.2) / 3 = 0.8667.
    log_prob, old, adv, living = _case()
    out = unit_clipped_surrogate(log_prob, old, adv, living, 0.2, normalize_advantage=False)
    assert out.loss.item() == pytest.approx(2.6 / 3)
    assert out.clip_fraction == pytest.approx(2 / 3)  # 1.5 and 0.5 left [0.8, 1.2]; 1.1 did not
    # (r - 1) - log r over the living units: 0.5 - log 1.5, -0.5 - log 0.5, 0.1 - log 1.1
    kl = (0.5 - math.log(1.5) - 0.5 - math.log(0.5) + 0.1 - math.log(1.1)) / 3
    assert out.approx_kl == pytest.approx(kl)
    out.loss.backward()
    # only the unclipped unit moves the policy: d/dlogp of -(r A) / 3 = -(1.1 * -2) / 3; the dead unit gets nothing
    expected = torch.tensor([[0.0, 0.0], [0.0, 2.2 / 3]], dtype=torch.float64)
    torch.testing.assert_close(log_prob.grad, expected)


def test_the_joint_ratio_would_have_clipped_all_of_step_one():
    """Why the per-unit loss differs: SB3's joint ratio at step 1 is 0.5 * 1.1 = 0.55, clipped to 0.8, so its
    gradient there is zero, where the per-unit loss still moves unit 1 (above)."""
    log_prob, old, adv, living = _case()
    joint = (log_prob * living).sum(dim=1)
    ratio = joint.exp()
    loss = -torch.min(adv * ratio, adv * ratio.clamp(0.8, 1.2)).mean()
    loss.backward()
    assert log_prob.grad[1].abs().sum().item() == 0.0


def test_advantages_are_normalised_over_the_living_units_rows():
    # living rows' advantages: step 0 unit 0 -> 1, step 1 both units -> -2: mean -1, std sqrt((4 + 1 + 1) / 3)
    log_prob, old, adv, living = _case()
    ones = torch.zeros_like(log_prob, requires_grad=True)  # every ratio 1: the loss is minus the mean advantage
    out = unit_clipped_surrogate(ones, old, adv, living, 0.2)
    assert out.loss.item() == pytest.approx(0.0, abs=1e-9)  # normalised advantages average to 0 over those rows
    out.loss.backward()
    std = math.sqrt(2.0)
    expected = -torch.tensor([[2.0 / std, 0.0], [-1.0 / std, -1.0 / std]], dtype=torch.float64) / 3
    torch.testing.assert_close(ones.grad, expected)


# ---------------------------------------------------------------------------------------------------------------
# The algorithm.


def _rollout(model):
    """Collect one rollout into the model's buffer (as learn() does first) without training on it."""
    from stable_baselines3.common.callbacks import CallbackList

    total, callback = model._setup_learn(model.n_steps * model.n_envs, CallbackList([]))
    callback.on_training_start(locals(), globals())
    with distribution_checks_off():
        model.collect_rollouts(model.env, callback, model.rollout_buffer, model.n_steps)


def test_old_unit_log_probs_sum_to_the_recorded_joint_ones():
    venv = _venv("3m", 4)
    model = _model(venv)
    _rollout(model)
    next(model.rollout_buffer.get(None))
    old = model._old_unit_log_probs(chunk=7)  # chunks that do not divide the 64 rows
    recorded = torch.as_tensor(model.rollout_buffer.log_probs.reshape(-1))
    torch.testing.assert_close(old.sum(dim=1), recorded.to(old.dtype), rtol=0, atol=1e-4)
    masks = model.rollout_buffer.action_masks.reshape(len(old), 3, -1)
    dead = ~masks[:, :, 1:].any(axis=2)
    assert (old[torch.as_tensor(dead)] == 0).all()
    venv.close()


@pytest.mark.parametrize("batch_size", [None, 24])  # the whole rollout in order, and shuffled minibatches
def test_without_a_step_every_ratio_stays_one(batch_size):
    """With learning rate 0 the policy never changes, so every minibatch's per-unit ratios are 1: the old
    log-probabilities line up with the rows they are paired with (shuffled or not)."""
    venv = _venv("3m", 4)
    model = _model(venv, learning_rate=0.0, batch_size=batch_size or 64, n_epochs=3)
    _rollout(model)
    seen = []
    original = unit_clipped_surrogate

    def spy(log_prob, old, *args):
        seen.append((log_prob - old).abs().max().item())
        return original(log_prob, old, *args)

    import smac_hard_gym.wrappers.sb3_unit_ppo as module

    module.unit_clipped_surrogate = spy
    try:
        with distribution_checks_off():
            model.train()
    finally:
        module.unit_clipped_surrogate = original
    assert len(seen) == 3 * (1 if batch_size is None else math.ceil(64 / batch_size))
    assert max(seen) < 1e-5
    venv.close()


def test_a_model_it_trains_loads_as_a_plain_maskable_ppo_model(tmp_path):
    venv = _venv("3m", 4)
    model = _model(venv)
    with distribution_checks_off():
        model.learn(128)
    model.save(tmp_path / "model.zip")
    loaded = MaskablePPO.load(tmp_path / "model.zip", device="cpu")
    obs = venv.reset()
    masks = np.stack(venv.env_method("action_masks"))
    mine, _ = model.predict(obs, action_masks=masks, deterministic=True)
    theirs, _ = loaded.predict(obs, action_masks=masks, deterministic=True)
    np.testing.assert_array_equal(mine, theirs)
    venv.close()


def test_the_joint_mlp_is_refused():
    from smac_hard_gym.wrappers.sb3_policy import MaskableJointPolicy

    venv = _venv("3m", 4)
    model = UnitRatioMaskablePPO(MaskableJointPolicy, venv, n_steps=16, batch_size=64, device="cpu")
    with pytest.raises(TypeError, match="per-unit log-probabilities"), distribution_checks_off():
        model.learn(64)
    venv.close()


# ---------------------------------------------------------------------------------------------------------------
# train's options.


# MAPPO's --clip_param per map (marlbenchmark/on-policy de66d7a, train_smac_<map>.sh; config.py's default 0.2)
MAPPO_CLIP = {"3s_vs_5z": 0.05, "5m_vs_6m": 0.05, "8m_vs_9m": 0.05, "25m": 0.2, "27m_vs_30m": 0.2, "2s3z": 0.2,
              "2s_vs_1sc": 0.2, "MMM2": 0.2}


@pytest.mark.parametrize("map_name", sorted(MAPPO_CLIP))
def test_ratio_unit_takes_mappos_clip_for_the_map(map_name):
    unit = TrainConfig(map_name=map_name, policy="shared", ratio="unit")
    joint = TrainConfig(map_name=map_name, policy="shared")
    assert unit.clip_range == MAPPO_CLIP[map_name]
    assert (unit.n_epochs, unit.frame_stack, unit.batch_size) == (joint.n_epochs, joint.frame_stack,
                                                                  joint.batch_size)
    assert TrainConfig(map_name=map_name, policy="shared", ratio="unit", clip_range=0.3).clip_range == 0.3


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"ratio": "units", "policy": "shared"}, "ratio must be one of"),
    ({"ratio": "unit", "policy": "joint"}, "only the shared policy"),
])
def test_bad_ratio_settings_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        TrainConfig(map_name="3m", **kwargs)


@pytest.mark.long  # about a minute on a quiet 2-core machine
def test_the_per_unit_loss_learns_3m_against_a_standing_enemy():
    """As the shared policy's learning check (tests/test_sb3_shared.py), with MAPPO's loss: a random legal policy
    wins none of 32 test battles against "stop"; 40k steps of training win most of them."""
    eval_env = NativeVectorEnv("3m", 16, autoreset_mode="SameStep", opponent="stop", obs_mode="joint+state")
    venv = _venv("3m", 16, opponent="stop")
    model = _model(venv, n_steps=32, batch_size=256, n_epochs=5, learning_rate=5e-4, clip_range=0.2)
    with distribution_checks_off():
        model.learn(40_960)
    rate = evaluate(model, eval_env, 32, seed=TEST_SEED_BASE).win_rate
    venv.close()
    eval_env.close()
    assert rate >= 0.5, rate
