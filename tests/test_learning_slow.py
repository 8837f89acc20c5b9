"""Slow learning checks (``pytest -m slow``; excluded from the default run): MaskablePPO, as `smac-hard-gym train`
runs it, learns what the game says it should and no more (docs/training_results.md has the full-length curves).

- 3m against `base`: a marine side learns to win (>= 0.8 within 102,400 steps; the full run is 1.00 from 20,480);
- 2m_vs_1z against `smac`: alternating aggro pays off against SC2's zealot (>= 0.8; 1.00 from 51,200);
- 2m_vs_1z against `weakest_each`, SMAC-HARD's focus-fire zealot: the same budget does not find the kiting that beats
  it (<= 0.2; the paper reports 0.00 for every algorithm, our 1M-step run stays at 0.00).
"""

from __future__ import annotations

import pytest

pytest.importorskip("sb3_contrib")

from smac_hard_gym.training import TrainConfig, train  # noqa: E402

pytestmark = pytest.mark.slow


def _final_win_rate(tmp_path, map_name: str, opponent: str, timesteps: int = 102_400) -> float:
    config = TrainConfig(map_name=map_name, opponent=opponent, policy="joint", timesteps=timesteps, num_envs=64,
                         n_steps=32, eval_every=timesteps, eval_episodes=32, seed=0, out=str(tmp_path / "run"),
                         progress=False)
    summary = train(config, log=lambda _: None)
    assert not summary["interrupted"]
    return summary["final_win_rate"]


def test_3m_learns_to_beat_base(tmp_path):
    assert _final_win_rate(tmp_path, "3m", "base") >= 0.8


def test_2m_vs_1z_learns_alternating_aggro_against_smac(tmp_path):
    assert _final_win_rate(tmp_path, "2m_vs_1z", "smac") >= 0.8


def test_2m_vs_1z_focus_fire_zealot_is_not_beaten_at_the_same_budget(tmp_path):
    assert _final_win_rate(tmp_path, "2m_vs_1z", "weakest_each") <= 0.2
