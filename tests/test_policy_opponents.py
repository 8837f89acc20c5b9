"""Trained policies as opponents (opponents/policy.py) and the self-play league (opponents/league.py)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.opponents import make_opponent
from smac_hard_gym.opponents.api import ScriptError
from smac_hard_gym.opponents.league import League
from smac_hard_gym.opponents.policy import PolicyScript


def attack_first(obs: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """Each agent attacks the first enemy it may attack, else moves east (else its first legal action)."""
    attacks = masks[:, :, 6:]
    east = np.where(masks[:, :, 4], 4, masks.argmax(axis=2))
    return np.where(attacks.any(axis=2), 6 + attacks.argmax(axis=2), east)


def _play(core: TwoPlayerCore, blue_policy=None, steps: int = 60) -> list[tuple]:
    """Rewards and outcomes of battle 0 over ``steps`` steps, red playing attack_first."""
    trace = []
    for _ in range(steps):
        red = attack_first(None, core.encode(RED)[0])
        if blue_policy is None:
            result = core.step(red)
        else:
            blue_masks = core.encode(BLUE)[0]
            result = core.step(red, blue_policy(None, blue_masks))
        trace.append((result.reward.tolist(), result.outcome.tolist(), result.dead_red.tolist(),
                      result.dead_blue.tolist()))
        if result.terminated.all() or result.truncated.all():
            break
    return trace


@pytest.mark.parametrize("map_name", ["3m", "MMM", "2s3z"])
def test_a_policy_opponent_plays_exactly_as_the_same_policy_in_self_play(map_name):
    # Self-play decodes blue's SMAC actions in the core; the policy opponent encodes blue's side itself and decodes
    # them into commands: the two paths must give the same battles, step for step.
    scripted = TwoPlayerCore(map_name, 2, opponent=PolicyScript(attack_first, "attack_first"), seed=5)
    selfplay = TwoPlayerCore(map_name, 2, mode="self-play", seed=5)
    assert _play(scripted) == _play(selfplay, attack_first)
    assert scripted.opponent_names() == ["attack_first", "attack_first"]


def test_the_policy_sees_its_own_side_with_its_own_last_actions():
    seen = []

    def record(obs, masks):
        seen.append(obs.copy())
        return masks.argmax(axis=2)

    core = TwoPlayerCore("3m", 1, opponent=PolicyScript(record, "record"), seed=0,
                         options=None)
    core.step(np.ones((1, 3), dtype=np.int64))
    core.step(np.ones((1, 3), dtype=np.int64))
    feats = core.features[BLUE]
    last = core.opponent.last_action
    # Its first observation is blue's own view of the start: what the core encodes for blue then.
    fresh = TwoPlayerCore("3m", 1, opponent="stop", seed=0)
    np.testing.assert_array_equal(seen[0], fresh.encode(BLUE)[1])
    assert seen[0].shape == (1, feats.n_agents, feats.obs_size)
    assert last.shape == (1, 3) and (last >= 0).all()  # actions recorded for the last-action features


def test_unavailable_policy_actions_are_replaced_by_the_first_legal_one():
    core = TwoPlayerCore("3m", 4, opponent=PolicyScript(lambda obs, masks: np.full(masks.shape[:2], 8), "stubborn"),
                         seed=0)
    for _ in range(5):
        core.step(np.ones((4, 3), dtype=np.int64))
    # Enemy 2 is out of range at the start: every blue agent played its first legal action, stop (1).
    np.testing.assert_array_equal(core.opponent.last_action, np.ones((4, 3)))


def test_policies_mix_with_scripts_and_bad_policies_are_named():
    opponent = make_opponent("3m", ["base", attack_first], [0.5, 0.5])
    core = TwoPlayerCore("3m", 64, opponent=opponent, seed=1)
    assert set(core.opponent_names()) == {"base", "attack_first"}
    bad = TwoPlayerCore("3m", 1, opponent=PolicyScript(lambda obs, masks: np.zeros(5), "bad"), seed=0)
    with pytest.raises(ScriptError, match=r"'bad' .*invalid actions: blue actions must have shape \(1, 3\)"):
        bad.step(np.ones((1, 3), dtype=np.int64))
    with pytest.raises(TypeError, match="a policy is a function"):
        PolicyScript(42)
    with pytest.raises(FileNotFoundError, match="no saved model"):
        make_opponent("3m", "missing/model.zip")


def test_a_torch_module_plays_its_masked_argmax():
    torch = pytest.importorskip("torch")

    class PreferLast(torch.nn.Module):
        def forward(self, joint):  # logits rising with the action id: the last legal action wins
            return torch.arange(9, dtype=torch.float32).repeat(joint.shape[0], 3)

    core = TwoPlayerCore("3m", 2, opponent=PolicyScript(PreferLast(), "prefer_last"), seed=0)
    core.step(np.ones((2, 3), dtype=np.int64))
    masks = TwoPlayerCore("3m", 2, opponent="stop", seed=0).encode(BLUE)[0]
    expected = masks.shape[2] - 1 - np.argmax(masks[:, :, ::-1], axis=2)
    np.testing.assert_array_equal(core.opponent.last_action, expected)


def test_prioritized_league_weights_follow_the_learners_losses():
    scripts = make_opponent("3m", ["base", "focus_fire", "stop"]).scripts
    league = League(scripts, weighting="prioritized", power=2.0)
    np.testing.assert_allclose(league.probs, [1 / 3] * 3)  # nothing met yet: all unbeaten
    league.update({"base": 0.0, "focus_fire": 0.5, "stop": 1.0})
    weights = np.array([1.0, 0.25, 0.05])  # (1 - w)^2, the beaten one floored at 5% of the heaviest
    np.testing.assert_allclose(league.probs, weights / weights.sum())
    league.add(PolicyScript(attack_first, "snapshot-1"))
    assert league.names[-1] == "snapshot-1" and league.probs[-1] == pytest.approx(1.0 / (weights.sum() + 1.0))
    uniform = League(scripts)
    uniform.update({"base": 1.0})
    np.testing.assert_allclose(uniform.probs, [1 / 3] * 3)
    with pytest.raises(ValueError, match="weighting must be one of"):
        League(scripts, weighting="elo")
    with pytest.raises(ValueError, match="already has a member named"):
        league.add(PolicyScript(attack_first, "base"))


@pytest.mark.long  # two PPO training runs: 37 s at load 8
def test_train_against_a_saved_model_in_league_mode(tmp_path):
    pytest.importorskip("sb3_contrib")
    common = ["--map", "3m", "--num-envs", "8", "--n-steps", "16", "--batch-size", "64", "--epochs", "1",
              "--eval-episodes", "4", "--no-progress"]
    run = subprocess.run([sys.executable, "-m", "smac_hard_gym.cli", "train", *common, "--timesteps", "128",
                          "--out", str(tmp_path / "blue")], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    model = tmp_path / "blue" / "model.zip"
    run = subprocess.run([sys.executable, "-m", "smac_hard_gym.cli", "train", *common, "--timesteps", "512",
                          "--opponent", str(model), "--league", "--league-every", "128", "--out",
                          str(tmp_path / "red")], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    summary = json.loads((tmp_path / "red" / "summary.json").read_text())
    members = summary["league"]["members"]
    assert "model:model" in members  # the frozen blue model the league started from
    snapshots = [name for name in members if name.startswith("snapshot-")]
    assert len(snapshots) >= 2
    for row in members.values():
        assert 0.0 <= row["win_rate"] <= 1.0 and 0.0 < row["prob"] <= 1.0
    assert "league (uniform weighting)" in run.stdout and "vs snapshot-" in run.stdout
