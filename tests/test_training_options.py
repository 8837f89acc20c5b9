"""`train`'s PPO options beyond SB3's own: `--reward` (which SMAC reward the training battles give; the evaluation
battles keep SMAC's default) and `--ent-coef-final` (the entropy coefficient falls linearly over the run)."""

import argparse
import json

import numpy as np
import pytest
import torch
from sb3_contrib import MaskablePPO

from smac_hard_gym.cli import main
from smac_hard_gym.commands.train import add_arguments
from smac_hard_gym.envs import vector
from smac_hard_gym.training import TrainConfig

torch.set_num_threads(1)


def test_reward_is_validated_and_names_the_bad_value():
    with pytest.raises(ValueError, match=r"reward must be one of \('positive', 'signed', 'abs'\), got 'dense'"):
        TrainConfig(reward="dense", out="x")
    with pytest.raises(SystemExit):  # argparse's choices: "invalid choice: 'dense'"
        main(["train", "--map", "3m", "--reward", "dense"])


# The spine crawler off creep loses 1 HP every 0.3332 Normal s and regenerates 0.2734 a Normal second, per game loop
# (16 a Normal second): from full health the first loop has nothing to regenerate. SMAC pays health lost as damage,
# scaled by 20 / 510 (the crawler's 300 health, its death's 10 and the win's 200).
DECAY, REGEN, SCALE = 1 / 0.3332 / 16, 0.2734 / 16, 20 / 510


def _crawler_decay_paid(steps: int) -> float:
    loops = 8 * steps
    return (loops * DECAY - (loops - 1) * REGEN) * SCALE


def test_signed_reward_charges_the_damage_taken():
    # 2s_vs_1sc: the stalkers walk north into the spine crawler's range (7) and never shoot (move, not attack). With
    # SMAC's default reward only the crawler's decay off creep pays; with reward_only_positive=False the crawler's
    # hits also cost reward_negative_scale (0.5) per point of health and shields, scaled as SMAC scales rewards.
    positive, signed = TrainConfig(map_name="2s_vs_1sc", out="x"), TrainConfig(map_name="2s_vs_1sc", reward="signed",
                                                                             out="x")
    assert "reward_only_positive" not in positive.train_env_kwargs()
    assert signed.train_env_kwargs()["reward_only_positive"] is False
    assert signed.env_kwargs() == positive.env_kwargs()  # evaluations: SMAC's default
    totals = {}
    for name, config in (("positive", positive), ("signed", signed)):
        kwargs = config.train_env_kwargs()
        env = vector.NativeVectorEnv(kwargs.pop("map_name"), 2, opponent="smac", **kwargs)
        env.reset(seed=0)
        north = np.full((2, 2), 2)  # action 2: move north, towards the crawler
        totals[name] = sum(env.step(north)[1] for _ in range(12))
        env.close()
    assert totals["positive"] == pytest.approx([_crawler_decay_paid(12)] * 2)
    # Two crawler hits or more per battle in 12 steps (one every 3.7 steps once in range): at least 2 x 30 damage,
    # halved and scaled, on top of the same decay.
    assert (totals["signed"] - totals["positive"] <= -2 * 30 * 0.5 * SCALE + 1e-6).all()


def test_abs_reward_is_given_to_training_battles_only():
    # How abs(damage + kills) pays regeneration is worked by hand in tests/test_rewards.py; here: the training
    # battles get it, the evaluations keep the default, and stalkers that wait are paid the crawler's net decay
    # either way (it loses more than it regenerates, so abs and max(0, .) agree).
    config = TrainConfig(map_name="2s_vs_1sc", reward="abs", out="x")
    assert config.train_env_kwargs()["reward_abs"] is True
    assert "reward_abs" not in config.env_kwargs()
    kwargs = config.train_env_kwargs()
    env = vector.NativeVectorEnv(kwargs.pop("map_name"), 1, opponent="smac", **kwargs)
    env.reset(seed=0)
    stop = np.full((1, 2), 1)
    paid = [float(env.step(stop)[1][0]) for _ in range(3)]
    env.close()
    assert paid == pytest.approx([_crawler_decay_paid(1), 8 * (DECAY - REGEN) * SCALE, 8 * (DECAY - REGEN) * SCALE])


def test_train_gives_the_signed_reward_to_training_battles_only(tmp_path, monkeypatch):
    built = []

    class Recording(vector.NativeVectorEnv):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            built.append((self.num_envs, self.core.features[0].options.reward_only_positive))

    monkeypatch.setattr(vector, "NativeVectorEnv", Recording)
    out = tmp_path / "run"
    assert main(["train", "--map", "3m", "--opponent", "base", "--timesteps", "256", "--num-envs", "4",
                 "--n-steps", "64", "--batch-size", "128", "--epochs", "1", "--eval-every", "256",
                 "--eval-episodes", "2", "--no-progress", "--reward", "signed", "--out", str(out)]) == 0
    assert built == [(4, False), (2, True)]  # the training battles, then the evaluation battles
    assert json.loads((out / "config.json").read_text())["reward"] == "signed"


def test_entropy_schedule_is_validated_and_linear():
    for bad in (-0.1, float("nan"), "0.1", True):
        with pytest.raises(ValueError, match=r"ent_coef_final must be a finite number >= 0, got"):
            TrainConfig(ent_coef_final=bad, out="x")
    with pytest.raises(ValueError, match=r"ent_coef must be a finite number >= 0, got -1"):
        TrainConfig(ent_coef=-1, out="x")
    config = TrainConfig(timesteps=1000, ent_coef=0.2, ent_coef_final=0.0, out="x")
    assert [config.ent_coef_at(t) for t in (0, 250, 500, 1000, 2000)] == pytest.approx([0.2, 0.15, 0.1, 0.0, 0.0])
    assert TrainConfig(timesteps=1000, ent_coef=0.05, out="x").ent_coef_at(700) == 0.05


@pytest.mark.parametrize("final", [None, 0.0])
def test_every_update_uses_the_scheduled_entropy_coefficient(tmp_path, monkeypatch, final):
    # 4 battles x 64 steps = 256 steps a rollout, 1024 steps: four updates, made after 256, 512, 768 and 1024 steps.
    seen = []
    train = MaskablePPO.train

    def recording_train(self):
        seen.append(self.ent_coef)
        return train(self)

    monkeypatch.setattr(MaskablePPO, "train", recording_train)
    out = tmp_path / "run"
    extra = [] if final is None else ["--ent-coef-final", str(final)]
    assert main(["train", "--map", "3m", "--opponent", "base", "--timesteps", "1024", "--num-envs", "4",
                 "--n-steps", "64", "--batch-size", "128", "--epochs", "1", "--eval-every", "1024",
                 "--eval-episodes", "2", "--no-progress", "--ent-coef", "0.2", *extra, "--out", str(out)]) == 0
    expected = [0.2] * 4 if final is None else [0.15, 0.1, 0.05, 0.0]
    assert seen == pytest.approx(expected)
    assert json.loads((out / "config.json").read_text())["ent_coef_final"] == final


# MAPPO's launch scripts (marlbenchmark/on-policy de66d7a, onpolicy/scripts/train_smac_scripts/train_smac_<map>.sh;
# every one runs --n_rollout_threads 8 --episode_length 400): algo, --ppo_epoch, --num_mini_batch, stacked frames.
# rmappo is the recurrent actor; mappo without stacking has no memory.
MAPPO_SCRIPTS = {  # map: (epochs, minibatches, frames our shared policy stands in for its memory with)
    "3s_vs_5z": (15, 1, 4),  # mappo --ppo_epoch 15 --clip_param 0.05 --use_stacked_frames --stacked_frames 4
    "3s_vs_4z": (15, 1, 4),  # mappo --ppo_epoch 15 --use_stacked_frames --stacked_frames 4
    "27m_vs_30m": (5, 1, 1),  # rmappo --ppo_epoch 5; one frame: memory measured to buy nothing there
    "MMM2": (5, 2, 4),  # rmappo --num_mini_batch 2 --ppo_epoch 5 --gain 1
    "corridor": (5, 1, 1),  # mappo --ppo_epoch 5
    "25m": (10, 1, 1),  # rmappo --ppo_epoch 10; one frame: memory measured to buy nothing there
    "5m_vs_6m": (10, 1, 4),  # rmappo --ppo_epoch 10 --clip_param 0.05
    "2s_vs_1sc": (15, 1, 4),  # rmappo --ppo_epoch 15
    "2s3z": (15, 1, 4),  # no script: config.py's defaults (ppo_epoch 15, num_mini_batch 1)
}


MEASURED_CLIP = {"3s_vs_5z": 0.15, "3s_vs_4z": 0.15, "8m_vs_9m": 0.2}
# one frame where the actor reads its unit's state row, which holds the cooldown the frames stood in for: measured
# on 3s_vs_5z (docs/training_results.md)
MEASURED_FRAMES_WITH_STATE = {"3s_vs_5z": 1}


@pytest.mark.parametrize("map_name", sorted(MAPPO_SCRIPTS))
def test_the_shared_policy_defaults_to_mappos_settings_for_the_map(map_name):
    epochs, minibatches, frames = MAPPO_SCRIPTS[map_name]
    shared = TrainConfig(map_name=map_name, policy="shared", num_envs=64)
    assert (shared.obs_mode, shared.n_steps) == ("joint+state", 50)  # 64 x 50 = MAPPO's 8 x 400 samples
    assert shared.actor_state and shared.n_epochs == epochs
    assert shared.frame_stack == MEASURED_FRAMES_WITH_STATE.get(map_name, frames)
    assert TrainConfig(map_name=map_name, policy="shared", actor_state=False).frame_stack == frames
    # SB3 clips the joint ratio (the product over units), not MAPPO's per-agent one: the measured clip for those
    # epochs (docs/training_results.md), 0.05 with 15, 0.2 with fewer; on 3s_vs_5z MAPPO's per-unit 0.05 over its
    # three units, 0.15 (measured there), and 0.15 on 3s_vs_4z too (measured); 0.2 on 8m_vs_9m (measured)
    assert shared.clip_range == MEASURED_CLIP.get(map_name, 0.05 if epochs == 15 else 0.2)
    assert shared.batch_size == 3200 // minibatches
    assert TrainConfig(map_name=map_name, policy="shared", num_envs=8, n_steps=400).batch_size == 3200 // minibatches
    assert TrainConfig(map_name=map_name, policy="shared", num_envs=np.int64(8),
                       n_steps=np.int64(400)).batch_size == 3200 // minibatches


def test_the_shared_policy_on_3m_takes_the_measured_quick_start_settings():
    # MAPPO's 3m script is its defaults (15 epochs, one minibatch); measured for the quick start instead: 10 epochs
    # of 4 minibatches of the 3,200-sample rollout, the joint ratio clipped at 0.2 (docs/training_results.md)
    config = TrainConfig(map_name="3m", policy="shared", num_envs=64)
    assert (config.n_steps, config.n_epochs, config.batch_size, config.clip_range, config.frame_stack) \
        == (50, 10, 800, 0.2, 4)
    assert TrainConfig(map_name="8m", policy="shared", num_envs=64).n_epochs == 15  # MAPPO's, unmeasured


def test_the_shared_policy_on_6h_vs_8z_takes_the_joint_mlps_ppo_settings():
    # MAPPO's 6h_vs_8z script: 5 epochs of one minibatch, no memory; measured instead (docs/training_results.md,
    # "6h_vs_8z on the engine now"): 64 battles x 32 steps in 10 epochs of minibatches of 512, clip 0.2, one frame
    config = TrainConfig(map_name="6h_vs_8z", policy="shared", num_envs=64)
    assert (config.n_steps, config.n_epochs, config.batch_size, config.clip_range, config.frame_stack) \
        == (32, 10, 512, 0.2, 1)
    joint = TrainConfig(map_name="6h_vs_8z", policy="joint", num_envs=64)
    assert (joint.n_steps, joint.n_epochs, joint.batch_size, joint.clip_range) == (32, 10, 512, 0.2)
    assert TrainConfig(map_name="6h_vs_8z", policy="shared", n_steps=50).batch_size == 64 * 50 // 4  # still 4 parts
    assert TrainConfig(map_name="corridor", policy="shared", num_envs=64).n_steps == 50  # MAPPO's, as the others


def _train_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser


def test_train_defaults_to_the_shared_policy():
    # the CLI's default and TrainConfig's are two literals: both must say the same
    assert _train_parser().parse_args([]).policy == TrainConfig(out="x").policy == "shared"


def test_mappos_table_names_every_map_with_a_script_and_only_known_maps():
    from smac_hard_gym.maps import list_maps
    from smac_hard_gym.training.mappo_settings import MAPPO_SMAC

    assert set(MAPPO_SMAC) <= set(list_maps())
    assert set(list_maps()) - set(MAPPO_SMAC) == {"2s3z"}  # on-policy has 22 SMAC scripts; 2s3z has none


def test_the_joint_policy_keeps_the_first_sweeps_settings_and_overrides_are_kept():
    joint = TrainConfig(map_name="27m_vs_30m", policy="joint")  # the first sweep's settings, on every map
    assert (joint.obs_mode, joint.frame_stack, joint.n_steps, joint.batch_size, joint.n_epochs, joint.clip_range) \
        == ("joint", 1, 32, 512, 10, 0.2)
    mine = TrainConfig(map_name="MMM2", policy="shared", frame_stack=1, n_epochs=4, clip_range=0.1, batch_size=256)
    assert (mine.frame_stack, mine.n_epochs, mine.clip_range, mine.batch_size) == (1, 4, 0.1, 256)
    for bad in (0, 1.0, -0.1, True):
        with pytest.raises(ValueError, match="clip_range"):
            TrainConfig(clip_range=bad)


def test_a_run_saved_before_frame_stacking_loads_as_single_frames(tmp_path):
    from smac_hard_gym.training.run_files import load_run_config

    old = {"map_name": "3m", "policy": "shared", "obs_mode": "joint+state", "n_steps": 32, "batch_size": 512,
           "n_epochs": 10, "clip_range": 0.2}
    (tmp_path / "config.json").write_text(json.dumps(old))
    config = load_run_config(tmp_path / "model.zip")
    assert config.frame_stack == 1 and config.env_kwargs()["frame_stack"] == 1


def test_a_run_saved_before_the_policy_option_loads_as_the_joint_mlp(tmp_path):
    # The first sweep's config.json files have no "policy": those runs trained the joint MLP (sb3_policy).
    from smac_hard_gym.training.run_files import load_run_config

    old = {"map_name": "3m", "obs_mode": "joint", "n_steps": 32, "batch_size": 512, "n_epochs": 10, "clip_range": 0.2}
    (tmp_path / "config.json").write_text(json.dumps(old))
    config = load_run_config(tmp_path / "model.zip")
    assert config.policy == "joint" and config.obs_mode == "joint"


def test_max_grad_norm_is_validated_and_names_the_bad_value():
    for bad in (0, -1.0, float("inf"), float("nan"), "10", True):
        with pytest.raises(ValueError, match=r"max_grad_norm must be a finite number > 0, got"):
            TrainConfig(max_grad_norm=bad, out="x")
    assert TrainConfig(out="x").max_grad_norm == 0.5  # SB3's PPO default


@pytest.mark.parametrize("policy, norm", [("joint", None), ("shared", 10.0)])
def test_every_optimiser_step_clips_the_gradient_at_max_grad_norm(tmp_path, monkeypatch, policy, norm):
    # 4 battles x 64 steps, 512 steps: two updates of one epoch over two minibatches of 128, four optimiser steps,
    # each clipping the policy's gradient at the run's norm (SB3's 0.5 unless --max-grad-norm says otherwise)
    import torch

    clips = []
    clip = torch.nn.utils.clip_grad_norm_

    def recording_clip(parameters, max_norm, *args, **kwargs):
        clips.append(max_norm)
        return clip(parameters, max_norm, *args, **kwargs)

    monkeypatch.setattr(torch.nn.utils, "clip_grad_norm_", recording_clip)
    out = tmp_path / "run"
    extra = [] if norm is None else ["--max-grad-norm", str(norm)]
    assert main(["train", "--map", "3m", "--opponent", "base", "--policy", policy, "--timesteps", "512",
                 "--num-envs", "4", "--n-steps", "64", "--batch-size", "128", "--epochs", "1", "--eval-every", "512",
                 "--eval-episodes", "2", "--no-progress", *extra, "--out", str(out)]) == 0
    expected = 0.5 if norm is None else norm
    assert clips == [expected] * 4
    assert json.loads((out / "config.json").read_text())["max_grad_norm"] == expected


def test_actor_state_needs_the_shared_policy_and_the_state():
    # on by default where the shared actor has a state to read it from, off otherwise
    assert TrainConfig(out="x").actor_state is True
    assert TrainConfig(out="x", policy="joint").actor_state is False
    assert TrainConfig(out="x", obs_mode="joint").actor_state is False
    assert TrainConfig(out="x", actor_state=False).ppo_kwargs()["policy_kwargs"].get("own_state_offset") is None
    config = TrainConfig(map_name="3s_vs_5z", out="x", actor_state=True)
    # a stalker's row: health, cooldown, x, y, shield
    assert config.ppo_kwargs()["policy_kwargs"]["own_state_size"] == 5
    with pytest.raises(ValueError, match="actor_state .* needs policy 'shared' and obs_mode 'joint\\+state', got "
                                         "policy 'joint'"):
        TrainConfig(out="x", policy="joint", actor_state=True)
    with pytest.raises(ValueError, match="got policy 'shared' and obs_mode 'joint'"):
        TrainConfig(out="x", obs_mode="joint", actor_state=True)
    with pytest.raises(ValueError, match="actor_state must be True or False, got 1"):
        TrainConfig(out="x", actor_state=1)
    with pytest.raises(SystemExit, match="actor_state"):
        main(["train", "--map", "3m", "--policy", "joint", "--actor-state", "--out", "x"])


def test_actor_state_on_the_command_line_and_in_old_run_configs(tmp_path):
    from smac_hard_gym.training.run_files import load_run_config

    parser = _train_parser()
    assert parser.parse_args([]).actor_state is None
    assert parser.parse_args(["--no-actor-state"]).actor_state is False
    assert parser.parse_args(["--actor-state"]).actor_state is True
    # a shared run saved before the option existed trained without the state row
    (tmp_path / "config.json").write_text(json.dumps({"map_name": "3m", "policy": "shared", "obs_mode": "joint+state"}))
    assert load_run_config(tmp_path / "model.zip").actor_state is False
