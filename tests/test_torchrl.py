"""TorchRL's ``PettingZooWrapper`` over the PettingZoo parallel env: a rollout runs, one group per team."""

from __future__ import annotations

import warnings

import pytest

pytest.importorskip("pettingzoo", reason="the [pettingzoo] extra is not installed")
pytest.importorskip("torchrl", reason="torchrl is not installed (pip install 'torchrl>=0.14,<0.15')")

from torchrl.envs import PettingZooWrapper  # noqa: E402

from smac_hard_gym.pettingzoo import parallel_env  # noqa: E402


@pytest.mark.parametrize("teams", ["red", "both"])
def test_torchrl_pettingzoo_wrapper_rollout(teams):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # torchrl names the PettingZoo version it was tested with
        env = PettingZooWrapper(parallel_env("3m", teams=teams), use_mask=True, categorical_actions=True, seed=0)
    groups = ["red", "blue"] if teams == "both" else ["red"]
    assert sorted(env.group_map) == sorted(groups)
    rollout = env.rollout(100, break_when_any_done=True)
    steps = rollout.batch_size[0]
    assert 1 <= steps <= 60  # 3m's episode limit
    for group in groups:
        assert rollout[group, "observation", "observation"].shape == (steps, 3, 30)
        assert rollout[group, "action_mask"].shape == (steps, 3, 9)
        assert rollout["next", group, "reward"].shape == (steps, 3, 1)
    assert rollout["next", "done"][-1].all()
    env.close()
