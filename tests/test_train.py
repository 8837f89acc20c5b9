"""Training and evaluation: the CLI end to end on a tiny budget, exact episode counting of the evaluation, opponent
pools, and MaskablePPO on the subprocess env."""

import csv
import json
import tempfile

import numpy as np
import pytest
import torch
from sb3_contrib import MaskablePPO
from stable_baselines3.common.vec_env import VecMonitor

from smac_hard_gym.cli import main
from smac_hard_gym.envs.subproc import make_subproc_env
from smac_hard_gym.envs.vector import NativeVectorEnv
from smac_hard_gym.training import CURVE_COLUMNS, evaluate, resolve_opponents
from smac_hard_gym.wrappers.sb3 import SB3VecEnv

torch.set_num_threads(1)


class StopPolicy:
    """Every living agent stops (action 1), dead ones no-op (0): the first legal action of each agent."""

    def predict(self, obs, action_masks=None, deterministic=True):
        masks = np.asarray(action_masks)
        return masks.reshape(len(masks), -1, 9).argmax(axis=2), None


def test_evaluation_counts_exactly_the_asked_episodes():
    # Against the "stop" script nobody shoots: every 3m episode times out after SMAC's 60 steps, unwon.
    env = NativeVectorEnv("3m", 2, autoreset_mode="SameStep", opponent="stop")
    result = evaluate(StopPolicy(), env, 5, seed=0)
    assert (result.episodes, result.wins, result.win_rate) == (5, 0, 0.0)
    assert result.mean_length == 60.0 and result.mean_return == 0.0
    assert result.per_opponent == {"stop": {"episodes": 5, "wins": 0, "win_rate": 0.0}}
    with pytest.raises(ValueError, match="episodes must be >= 1"):
        evaluate(StopPolicy(), env, 0)
    env.close()


def test_opponent_sets_for_evaluation():
    # 3m's SMAC-HARD pool is its marine-line script plus base (docs/smac_hard_reference.md §3); blackbox drops base.
    assert resolve_opponents("3m", "default")[0] == ["line_front", "base"]
    names, weights = resolve_opponents("3m", "blackbox")
    assert names == ["line_front"] and weights.tolist() == [1.0]
    names, weights = resolve_opponents("3m", "all")
    assert {"base", "line_front", "stop"} <= set(names) and np.isclose(weights.sum(), 1.0)
    assert resolve_opponents("3m", "base,stop") == (["base", "stop"], pytest.approx([0.5, 0.5]))
    with pytest.raises(ValueError, match="unknown opponent"):
        resolve_opponents("3m", "nobody")


def test_train_and_eval_commands_end_to_end(tmp_path, capsys, monkeypatch):
    from torch.distributions import Distribution

    out = tmp_path / "run"
    temp = tmp_path / "temp"  # SB3's default logger would leave an empty SB3-<time> folder here
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    validate = Distribution._validate_args  # another library may have switched it off already
    Distribution.set_default_validate_args(True)
    try:
        code = main(["train", "--map", "3m", "--opponent", "default", "--timesteps", "2048", "--num-envs", "4",
                     "--n-steps", "64", "--batch-size", "128", "--epochs", "2", "--eval-every", "1024",
                     "--eval-episodes", "4", "--seed", "3", "--out", str(out), "--no-progress"])
        assert Distribution._validate_args  # switched off while training only
    finally:
        Distribution.set_default_validate_args(validate)
    assert code == 0
    assert list(temp.glob("SB3-*")) == []
    printed = capsys.readouterr().out
    assert printed.startswith("config:") and "map_name        3m" in printed
    assert "time inside the env (step + masks)" in printed and "win rate (masked" in printed
    for name in ("model.zip", "config.json", "curve.csv", "curve.png", "summary.json"):
        assert (out / name).is_file(), name
    with open(out / "curve.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == CURVE_COLUMNS
    assert [int(r["timesteps"]) for r in rows] == [0, 1024, 2048]
    assert all(int(r["episodes"]) == 4 and 0.0 <= float(r["win_rate"]) <= 1.0 for r in rows)
    assert 0.0 < float(rows[-1]["env_fraction"]) < 1.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["timesteps"] == 2048 and summary["map"] == "3m"

    code = main(["eval", "--model", str(out / "model.zip"), "--opponent", "all", "--episodes", "2",
                 "--num-envs", "2"])
    assert code == 0
    results = json.loads((out / "eval_3m_all.json").read_text())
    scripts = results["scripts"]
    assert set(scripts) == set(resolve_opponents("3m", "all")[0])
    assert all(row["episodes"] == 2 for row in scripts.values())
    mean = sum(row["win_rate"] for row in scripts.values()) / len(scripts)  # equal weights
    assert results["mixture"]["win_rate"] == pytest.approx(mean)
    assert "all (mixture)" in capsys.readouterr().out


def test_cli_rejects_bad_input():
    with pytest.raises(SystemExit, match="unknown map"):
        main(["train", "--map", "4m"])
    with pytest.raises(SystemExit, match="unknown opponent"):
        main(["train", "--opponent", "nobody"])
    with pytest.raises(SystemExit, match="num_envs must be a positive int"):
        main(["train", "--num-envs", "0"])
    with pytest.raises(SystemExit, match="no model at"):
        main(["eval", "--model", "/nonexistent/model.zip"])


_SMALL_RUN = ["--map", "3m", "--timesteps", "2048", "--num-envs", "4", "--n-steps", "64", "--batch-size", "128",
              "--epochs", "1", "--eval-every", "2048", "--eval-episodes", "2", "--no-progress"]


def test_ctrl_c_during_training_keeps_model_curve_and_summary(tmp_path, capsys, monkeypatch):
    def interrupted_learn(self, *args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(MaskablePPO, "learn", interrupted_learn)
    out = tmp_path / "run"
    assert main(["train", *_SMALL_RUN, "--out", str(out)]) == 130
    assert "interrupted after 0 steps: model, curve and summary saved in" in capsys.readouterr().out
    for name in ("model.zip", "curve.csv", "summary.json"):
        assert (out / name).is_file(), name
    assert json.loads((out / "summary.json").read_text())["interrupted"] is True


def test_eval_names_the_map_a_model_was_trained_on(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["train", *_SMALL_RUN, "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["eval", "--model", str(out / "model.zip"), "--map", "8m", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "trained on 3m" in err and "8m needs" in err


def test_commands_print_one_line_errors_and_take_comma_lists(capsys):
    assert main(["duel", "--map", "3m", "--red", "base", "--blue", "missing_script.py", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and "missing_script.py" in err and "Traceback" not in err
    assert main(["duel", "--map", "3m", "--red", "base", "--blue", "line_front,nearest", "--episodes", "4",
                 "--no-progress"]) == 0
    out = capsys.readouterr().out  # the mixture's draw per episode follows the seed: 4 episodes play both scripts
    assert "base vs line_front" in out and "base vs nearest" in out


def test_tensorboard_logging(tmp_path):
    board = tmp_path / "tb"
    args = ["train", *_SMALL_RUN, "--out", str(tmp_path / "run"), "--tensorboard", str(board)]
    try:
        import tensorboard  # noqa: F401
    except ImportError:  # not in any extra: the option says what to install
        with pytest.raises(SystemExit, match="pip install tensorboard"):
            main(args)
        return
    assert main(args) == 0
    assert list(board.rglob("events.out.tfevents.*"))


def test_maskable_ppo_learns_on_the_subprocess_env():
    sub = make_subproc_env("3m", 2, 2, autoreset_mode="SameStep", opponent="default")
    try:
        venv = VecMonitor(SB3VecEnv(sub))
        model = MaskablePPO("MlpPolicy", venv, n_steps=256, batch_size=256, n_epochs=2, seed=0, device="cpu")
        model.learn(2048)
        assert model.num_timesteps == 2048 and len(model.ep_info_buffer) > 0
    finally:
        sub.close()


def test_kernel_cache_is_warm_once_an_env_has_stepped():
    from smac_hard_gym.kernel_cache import kernels_cached

    env = NativeVectorEnv("3m", 16, autoreset_mode="SameStep")  # 16 battles: the parallel step kernel
    env.reset(seed=0)
    env.step(np.ones((16, 3), dtype=np.int64))
    env.close()
    assert kernels_cached() is True  # compiled (or loaded) in this process, so on disk now
    # Kernels compiled per unit count share numba's index with the generic ones: a count never compiled is not cached.
    assert kernels_cached(997) is False
