"""Training and evaluation: the CLI end to end on a tiny budget, exact episode counting of the evaluation, opponent
pools, and MaskablePPO on the subprocess env."""

import csv
import json
import re
import shutil
import tempfile

import numpy as np
import pytest
import torch
from sb3_contrib import MaskablePPO
from stable_baselines3.common.vec_env import VecMonitor
from train_helpers import interrupt_learn_at

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
    assert printed.startswith("config:") and re.search(r"\n  map_name +3m\n", printed)
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
    assert results["actions"] == "deterministic"

    # Sampled actions: the barely trained policy is close to uniform, so the games a script gets depend on where
    # torch's generator stands; seeded with the test battles' seed before each script, `smac` plays the same games
    # alone and after another script.
    sampled = []
    for k, pool in enumerate(("smac", "base,smac")):
        assert main(["eval", "--model", str(out / "model.zip"), "--opponent", pool, "--episodes", "4",
                     "--num-envs", "2", "--sample-actions", "--json", str(tmp_path / f"sampled{k}.json")]) == 0
        sampled.append(json.loads((tmp_path / f"sampled{k}.json").read_text()))
    assert "sampled actions" in capsys.readouterr().out
    assert [s["actions"] for s in sampled] == ["sampled", "sampled"]
    assert list(sampled[1]["scripts"]) == ["base", "smac"]
    assert sampled[0]["scripts"]["smac"] == sampled[1]["scripts"]["smac"]
    assert main(["eval", "--model", str(out / "model.zip"), "--opponent", "smac", "--episodes", "4", "--num-envs",
                 "2", "--sample-actions", "--seed", "7"]) == 0
    assert (out / "eval_3m_smac_sampled.json").is_file()  # beside the model, apart from the deterministic file
    from smac_hard_gym.training.evaluation import evaluate_against
    from smac_hard_gym.training.run_files import load_trained

    model, config, options = load_trained(out / "model.zip")
    assert config.map_name == "3m" and "map_name" not in options
    before = torch.get_rng_state()
    evaluate_against(model, config.map_name, "smac", 2, 2, 0, options, deterministic=False)
    assert torch.equal(torch.get_rng_state(), before)  # the caller's generator is left as it was
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copy(out / "model.zip", alone / "model.zip")
    with pytest.raises(FileNotFoundError, match="no config.json next to"):
        load_trained(alone / "model.zip")


def test_train_with_the_shared_policy_and_eval_it(tmp_path, capsys):
    from smac_hard_gym.training import TrainConfig, load_model
    from smac_hard_gym.wrappers.sb3_shared import SharedUnitPolicy

    out = tmp_path / "shared"
    assert main(["train", *_SMALL_RUN, "--policy", "shared", "--out", str(out)]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["policy"] == "shared" and config["obs_mode"] == "joint+state"
    model = load_model(out / "model.zip")
    assert type(model.policy) is SharedUnitPolicy and int(model.policy.value_normaliser.updates) > 0
    assert main(["eval", "--model", str(out / "model.zip"), "--opponent", "smac", "--episodes", "2",
                 "--num-envs", "2"]) == 0
    with pytest.raises(ValueError, match="shared policy reads the joint view"):
        TrainConfig(policy="shared", obs_mode="dict", out="x")
    with pytest.raises(ValueError, match="policy must be one of"):
        TrainConfig(policy="mlp", out="x")


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
    assert "interrupted after 0 steps (last test win rate" in capsys.readouterr().out
    for name in ("model.zip", "curve.csv", "summary.json"):
        assert (out / name).is_file(), name
    assert json.loads((out / "summary.json").read_text())["interrupted"] is True


@pytest.mark.parametrize(("eval_every", "rate_at"), [(1024, None), (256, 256)])
def test_ctrl_c_mid_run_reports_the_real_steps_and_the_last_measured_rate(tmp_path, capsys, monkeypatch,
                                                                          eval_every, rate_at):
    import gc

    interrupt_learn_at(monkeypatch, 300)  # 4 envs x 75 steps: past the first rollout of 256
    out = tmp_path / "run"
    argv = ["train", "--map", "3m", "--timesteps", "2048", "--num-envs", "4", "--n-steps", "64", "--batch-size",
            "128", "--epochs", "1", "--eval-every", str(eval_every), "--eval-episodes", "2", "--out", str(out)]
    assert main(argv) == 130  # with the progress bar on
    captured = capsys.readouterr()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True
    assert summary["timesteps"] == summary["timesteps_trained"] == 300
    with open(out / "curve.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert [int(r["timesteps"]) for r in rows] == ([0] if rate_at is None else [0, rate_at])
    assert summary["final_win_rate_at"] == rate_at
    if rate_at is None:
        assert summary["final_win_rate"] is None  # nothing measured since training began
        assert "interrupted after 300 steps (no test win rate measured since training began" in captured.out
    else:
        assert summary["final_win_rate"] == pytest.approx(float(rows[-1]["win_rate"]))
        assert f"interrupted after 300 steps (last test win rate {summary['final_win_rate']:.3f} at {rate_at} " \
               "steps)" in captured.out
    assert "train:" in captured.err  # the bar was drawn while training ...
    gc.collect()
    assert capsys.readouterr().err == ""  # ... and closed before the message: nothing draws it again afterwards
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".")) == []


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


def test_tensorboard_option_writes_event_files_or_names_the_package(tmp_path):
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


@pytest.mark.long  # trains 81,920 steps in worker processes: a few minutes of CPU
def test_maskable_ppo_on_the_subprocess_env_learns_to_beat_base_on_3m():
    # train's PPO settings (TrainConfig's defaults, seed 0) on 64 battles of 3m against `base`, stepped in 2 worker
    # processes, evaluated on the 32 test battles before and after 81,920 steps. In process, the same settings win
    # 1.00 from 20,480 steps (tests/test_learning_slow.py); in workers this run won 0.00 at 20,480 and 1.00 at 30,720
    # and 40,960 on a Xeon, but 0.125 at 40,960, 0.66 at 61,440 and 1.00 at 81,920 on an AMD EPYC (its float
    # rounding sends the same seeded run elsewhere), so it trains four times the in-process budget.
    # Generous margins: <= 0.25 before, >= 0.6 after.
    from stable_baselines3.common.logger import Logger

    from smac_hard_gym.training import TEST_SEED_BASE, TrainConfig
    from smac_hard_gym.training.evaluation import evaluate_against
    from smac_hard_gym.wrappers.sb3_buffers import MaskableJointRolloutBuffer
    from smac_hard_gym.wrappers.sb3_policy import MaskableJointPolicy

    config = TrainConfig(map_name="3m", opponent="base", seed=0, policy="joint")
    sub = make_subproc_env("3m", 2, config.num_envs // 2, autoreset_mode="SameStep", opponent="base")
    try:
        venv = VecMonitor(SB3VecEnv(sub))
        model = MaskablePPO(MaskableJointPolicy, venv, rollout_buffer_class=MaskableJointRolloutBuffer,
                            **config.ppo_kwargs())
        model.set_logger(Logger(folder=None, output_formats=[]))  # SB3's default makes a /tmp/SB3-<time> folder
        before = evaluate_against(model, "3m", "base", 32, 16, TEST_SEED_BASE, None).win_rate
        model.learn(81_920)
        assert model.num_timesteps == 81_920 and len(model.ep_info_buffer) > 0
    finally:
        sub.close()
    after = evaluate_against(model, "3m", "base", 32, 16, TEST_SEED_BASE, None).win_rate
    assert before <= 0.25 and after >= 0.6, (before, after)


def test_kernel_cache_is_warm_once_an_env_has_stepped():
    from smac_hard_gym.kernel_cache import kernels_cached

    env = NativeVectorEnv("3m", 16, autoreset_mode="SameStep")  # 16 battles: the parallel step kernel
    env.reset(seed=0)
    env.step(np.ones((16, 3), dtype=np.int64))
    env.close()
    assert kernels_cached() is True  # compiled (or loaded) in this process, so on disk now
    # Kernels compiled per unit count share numba's index with the generic ones: a count never compiled is not cached.
    assert kernels_cached(997) is False


@pytest.mark.parametrize("content", [b"", b"PK\x03\x04 truncated", bytes(range(256)) * 8, b"not a zip at all"],
                         ids=["empty", "truncated-zip", "random", "text"])
def test_eval_on_a_malformed_model_is_one_line(tmp_path, capsys, content):
    model = tmp_path / "model.zip"
    model.write_bytes(content)
    assert main(["eval", "--model", str(model), "--map", "3m", "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("smac-hard-gym eval: error: ") and err.count("\n") == 1, err
    assert "not a saved MaskablePPO model" in err and str(model) in err and "Traceback" not in err


@pytest.mark.parametrize("config", [b"{broken", b"\xff\xfe", b"[1, 2]", b'{"timesteps": -3}', b'{"map_name": 5}'])
def test_eval_with_a_malformed_run_config_is_one_line(tmp_path, capsys, config):
    (tmp_path / "model.zip").write_bytes(b"PK")
    (tmp_path / "config.json").write_bytes(config)
    assert main(["eval", "--model", str(tmp_path / "model.zip"), "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "config.json" in err and "Traceback" not in err, err


def test_train_and_eval_share_the_test_battles_and_never_reuse_training_seeds(tmp_path, capsys, monkeypatch):
    """One evaluation protocol: train's final test evaluation and `eval` with its defaults play the same test
    battles (TEST_SEED_BASE + b) and give the same win rate; no test battle is seeded like a training battle."""
    from smac_hard_gym.training import TEST_SEED_BASE, eval_seeds, training_seeds

    seeds_by_env: dict[int, list[int]] = {}
    order: list[int] = []
    sizes: dict[int, int] = {}
    reset_battles = NativeVectorEnv._reset_battles

    def recording(self, rows, seeds, in_place=False):
        if id(self) not in seeds_by_env:
            order.append(id(self))
            sizes[id(self)] = self.num_envs
            seeds_by_env[id(self)] = []
        seeds_by_env[id(self)] += [s for s in (seeds or []) if s is not None]
        return reset_battles(self, rows, seeds, in_place)

    monkeypatch.setattr(NativeVectorEnv, "_reset_battles", recording)
    out = tmp_path / "run"
    assert main(["train", "--map", "3m", "--opponent", "base", "--timesteps", "2048", "--num-envs", "4",
                 "--n-steps", "64", "--batch-size", "128", "--epochs", "1", "--eval-every", "2048", "--seed", "5",
                 "--out", str(out), "--no-progress"]) == 0
    printed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    train_env, test_env = sorted(order[:2], key=sizes.get)  # 4 training battles, 16 test battles
    assert set(seeds_by_env[train_env]) == set(training_seeds(5, 4)) == {5, 6, 7, 8}
    assert set(seeds_by_env[test_env]) == set(eval_seeds(16)) == set(range(TEST_SEED_BASE, TEST_SEED_BASE + 16))
    assert summary["test_seeds"] == eval_seeds(16) and summary["training_seeds"] == [5, 8]
    assert summary["eval_episodes"] == 32 and summary["final_win_rate_stderr"] is not None
    low, high = summary["final_win_rate_ci95"]
    assert low <= summary["final_win_rate"] <= high
    assert "test evaluation at 2048 steps:" in printed and "95% Wilson interval" in printed

    assert main(["eval", "--model", str(out / "model.zip"), "--opponent", "base"]) == 0  # defaults otherwise
    printed = capsys.readouterr().out
    eval_env = order[2]
    assert set(seeds_by_env[eval_env]) == set(eval_seeds(16))
    assert not set(seeds_by_env[eval_env]) & set(seeds_by_env[train_env])
    row = json.loads((out / "eval_3m_base.json").read_text())["scripts"]["base"]
    assert row["episodes"] == 32 and row["win_rate"] == summary["final_win_rate"]
    assert row["stderr"] == pytest.approx(summary["final_win_rate_stderr"])
    with open(out / "curve.csv") as handle:
        final = list(csv.DictReader(handle))[-1]
    assert row["mean_return"] == pytest.approx(float(final["mean_return"]), abs=1e-4)  # the same episodes
    assert "warning" not in printed and "stderr" in printed


def test_training_seeds_stay_below_the_test_seeds():
    from smac_hard_gym.training import TEST_SEED_BASE, TrainConfig, eval_seeds, training_seeds, win_rate_spread

    TrainConfig(seed=TEST_SEED_BASE - 64, num_envs=64, out="x")
    for seed in (-1, TEST_SEED_BASE - 63, TEST_SEED_BASE):
        with pytest.raises(ValueError, match="seed must be an int"):
            TrainConfig(seed=seed, num_envs=64, out="x")
    for seed, num_envs in ((0, 64), (TEST_SEED_BASE - 1024, 1024), (12345, 7)):
        assert not set(training_seeds(seed, num_envs)) & set(eval_seeds(1024))
    spread = win_rate_spread(30, 32)
    assert spread["episodes"] == 32 and spread["stderr"] == pytest.approx((30 / 32 * 2 / 32 / 32) ** 0.5)
    assert spread["ci95"][0] < 30 / 32 < spread["ci95"][1] <= 1.0
    assert win_rate_spread(0, 32)["ci95"][0] == 0.0 and win_rate_spread(0, 32)["ci95"][1] > 0.0
