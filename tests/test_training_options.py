"""`train`'s PPO options beyond SB3's own: `--reward` (which SMAC reward the training battles give; the evaluation
battles keep SMAC's default) and `--ent-coef-final` (the entropy coefficient falls linearly over the run)."""

import json

import numpy as np
import pytest
import torch
from sb3_contrib import MaskablePPO

from smac_hard_gym.cli import main
from smac_hard_gym.envs import vector
from smac_hard_gym.training import TrainConfig

torch.set_num_threads(1)


def test_reward_is_validated_and_names_the_bad_value():
    with pytest.raises(ValueError, match=r"reward must be one of \('positive', 'signed', 'abs'\), got 'dense'"):
        TrainConfig(reward="dense", out="x")
    with pytest.raises(SystemExit):  # argparse's choices: "invalid choice: 'dense'"
        main(["train", "--map", "3m", "--reward", "dense"])


def test_signed_reward_charges_the_damage_taken():
    # 2s_vs_1sc: the stalkers walk north into the spine crawler's range (7) and never shoot (move, not attack). With
    # SMAC's default reward nothing is dealt, so every step pays 0; with reward_only_positive=False the crawler's
    # hits cost reward_negative_scale (0.5) per point of health and shields, scaled as SMAC scales rewards.
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
    assert totals["positive"].tolist() == [0.0, 0.0]
    # Two crawler hits or more per battle in 12 steps (one every 3.7 steps once in range): at least 2 x 30 damage,
    # scaled by 20 / (300 + 10 + 200) (the crawler's health, its death and the win) and halved.
    assert (totals["signed"] <= -2 * 30 * 0.5 * 20 / 510 + 1e-6).all()


def test_abs_reward_pays_the_crawlers_regeneration():
    # 2s_vs_1sc: the stalkers walk north into range, fire for 4 steps, then walk south out of the spine crawler's
    # reach and stop. The crawler regenerates 0.2734 health per Normal second (Zerg), 0.1367 a step of 8 loops:
    # SMAC v1's abs(damage + kills) pays each step's regeneration as if it were damage (scaled by 20 / 510: the
    # crawler's 300 health, its death's 10 and the win's 200); smac-hard-gym's default pays nothing for it.
    north, attack, south, stop = 2, 6, 3, 1
    plan = [north] * 4 + [attack] * 4 + [south] * 6
    totals = {}
    for reward in ("positive", "abs"):
        kwargs = TrainConfig(map_name="2s_vs_1sc", reward=reward, out="x").train_env_kwargs()
        env = vector.NativeVectorEnv(kwargs.pop("map_name"), 1, opponent="smac", **kwargs)
        env.reset(seed=0)
        for action in plan:
            env.step(np.full((1, 2), action))
        crawler = env.core.backend.state.health[0, 2]
        assert 250 < crawler < 300  # hit, not dead: it has something to regenerate
        totals[reward] = sum(float(env.step(np.full((1, 2), stop))[1][0]) for _ in range(16))
        env.close()
    assert totals["positive"] == 0.0
    assert totals["abs"] == pytest.approx(16 * 0.2734 / 2 * 20 / 510, rel=1e-3)


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
