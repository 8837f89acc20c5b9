"""``train --resume``: a run cut short carries on from its last checkpoint, a finished run trains further, settings
that would make it another run are refused, and the baselines sweep carries its runs on instead of redoing them.

The runs are 3m with 4 battles x 64 steps, so one rollout (and one update of the value normaliser) every 256 steps.
"""

import csv
import json
import shutil
import sys

import pytest
import torch
from sb3_contrib import MaskablePPO
from train_helpers import interrupt_learn_at

from smac_hard_gym.cli import main
from smac_hard_gym.training.baselines import Run, SweepConfig, run_sweep
from smac_hard_gym.training.baselines import sweep as sweep_module
from smac_hard_gym.training.baselines.planning import resumable, run_state

torch.set_num_threads(1)

ROLLOUT = 4 * 64
RUN = ["train", "--map", "3m", "--policy", "shared", "--timesteps", str(4 * ROLLOUT), "--num-envs", "4",
       "--n-steps", "64", "--epochs", "1", "--eval-every", str(2 * ROLLOUT), "--eval-episodes", "2",
       "--checkpoint-every", str(ROLLOUT), "--no-progress"]


def _curve_steps(out):
    with open(out / "curve.csv") as handle:
        return [int(row["timesteps"]) for row in csv.DictReader(handle)]


def _rollouts_learned(out):
    """Rollouts whose returns the saved model's value normaliser has folded in (one per update)."""
    return int(MaskablePPO.load(out / "model.zip", device="cpu").policy.value_normaliser.updates)


def _cut_run(tmp_path, monkeypatch, capsys):
    """A run stopped by Ctrl-C 88 steps into its third rollout: its last checkpoint is at the start of that
    rollout, 512 steps, just after the evaluation there."""
    out = tmp_path / "run"
    with monkeypatch.context() as patch:
        interrupt_learn_at(patch, 2 * ROLLOUT + 88)
        assert main([*RUN, "--out", str(out)]) == 130
    capsys.readouterr()
    assert json.loads((out / "checkpoint.json").read_text())["timesteps"] == 2 * ROLLOUT
    return out


def test_a_run_cut_short_carries_on_from_its_last_checkpoint(tmp_path, monkeypatch, capsys):
    out = _cut_run(tmp_path, monkeypatch, capsys)
    assert main(["train", "--resume", "--out", str(out), "--no-progress"]) == 0
    assert f"from its checkpoint at {2 * ROLLOUT} steps" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is False
    assert summary["timesteps"] == 4 * ROLLOUT  # the run's own --timesteps
    assert summary["resumed_from"] == [2 * ROLLOUT]
    # evaluations every 512 steps and at the end, each once: the steps past the checkpoint were trained again
    assert _curve_steps(out) == [0, 2 * ROLLOUT, 4 * ROLLOUT]
    # the networks and the value normaliser came from the checkpoint: all four rollouts are in it, where a fresh
    # model would hold only the two trained after the resume
    assert _rollouts_learned(out) == 4


def test_a_resume_is_reproducible(tmp_path, monkeypatch, capsys):
    out = _cut_run(tmp_path, monkeypatch, capsys)
    twin = tmp_path / "twin"
    shutil.copytree(out, twin)
    for folder in (out, twin):
        assert main(["train", "--resume", "--out", str(folder), "--no-progress"]) == 0
    first, second = (MaskablePPO.load(f / "model.zip", device="cpu").policy.state_dict() for f in (out, twin))
    assert all(torch.equal(first[k], second[k]) for k in first)


def test_a_finished_run_trains_further_with_more_timesteps(tmp_path, capsys):
    out = tmp_path / "run"
    assert main([*RUN, "--out", str(out)]) == 0
    assert main(["train", "--resume", "--out", str(out), "--timesteps", str(6 * ROLLOUT), "--no-progress"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["timesteps"] == 6 * ROLLOUT and summary["resumed_from"] == [4 * ROLLOUT]
    assert _curve_steps(out) == [0, 2 * ROLLOUT, 4 * ROLLOUT, 6 * ROLLOUT]  # 1024 measured once
    assert _rollouts_learned(out) == 6
    assert json.loads((out / "config.json").read_text())["timesteps"] == 6 * ROLLOUT


def test_a_new_run_in_an_old_runs_folder_drops_the_old_checkpoint(tmp_path, monkeypatch, capsys):
    out = tmp_path / "run"
    assert main([*RUN, "--out", str(out)]) == 0  # finished: checkpoint at 1024
    with monkeypatch.context() as patch:
        interrupt_learn_at(patch, 100)  # the same command again, stopped before its first checkpoint
        assert main([*RUN, "--out", str(out)]) == 130
    assert not (out / "checkpoint.json").exists()
    with pytest.raises(SystemExit, match=r"no checkpoint to resume"):
        main(["train", "--resume", "--out", str(out)])


def test_resume_refuses_what_would_make_it_another_run(tmp_path, capsys):
    out = tmp_path / "run"
    assert main([*RUN, "--out", str(out)]) == 0
    capsys.readouterr()
    with pytest.raises(SystemExit, match=r"--seed cannot be given"):
        main(["train", "--resume", "--out", str(out), "--seed", "3"])
    with pytest.raises(SystemExit, match=r"--lr cannot be given"):
        main(["train", "--resume", "--out", str(out), "--lr", "0.001"])
    with pytest.raises(SystemExit, match=rf"has {4 * ROLLOUT} steps already; pass --timesteps above that"):
        main(["train", "--resume", "--out", str(out), "--timesteps", str(2 * ROLLOUT)])
    with pytest.raises(SystemExit, match=r"name the run's folder with --out"):
        main(["train", "--resume"])
    with pytest.raises(SystemExit, match=r"no run in .*nowhere"):
        main(["train", "--resume", "--out", str(tmp_path / "nowhere")])
    (out / "checkpoint.zip").unlink()
    with pytest.raises(SystemExit, match=r"no checkpoint to resume in .*checkpoint.zip"):
        main(["train", "--resume", "--out", str(out), "--timesteps", str(6 * ROLLOUT)])
    with pytest.raises(SystemExit, match=r"checkpoint_every must be an int >= 0.*-5"):
        main([*RUN, "--out", str(tmp_path / "other"), "--checkpoint-every", "-5"])


def test_the_sweep_carries_a_cut_run_on_from_its_checkpoint(tmp_path, monkeypatch):
    """A run folder with a checkpoint below the sweep's steps is resumed, not deleted and redone."""
    out = tmp_path / "out"
    config = SweepConfig(maps=["3m"], seeds=1, opponents=["default"], out=str(out), timesteps=1000)
    path = Run("3m", "default", 0).path(out)
    path.mkdir(parents=True)
    (path / "checkpoint.zip").write_bytes(b"weights")
    (path / "checkpoint.json").write_text(json.dumps({"timesteps": 600, "rows": [{"timesteps": 0}],
                                                      "next_eval": 1000}))
    assert resumable(path, 1000) and not resumable(path, 600)
    assert run_state(path, 1000) == "resumable" and run_state(path, 600) == run_state(path) == "partial"
    (path / "train.log").write_text("first part\n")
    started = tmp_path / "started.txt"

    def fake(kind):
        def command(run, config):
            code = (f"import json, pathlib; p = pathlib.Path({str(path)!r}); "
                    f"open({str(started)!r}, 'a').write({kind!r}); print('second part'); "
                    f"(p / 'curve.csv').write_text('timesteps,win_rate\\n0,0.0\\n1000,0.5\\n'); "
                    f"(p / 'summary.json').write_text(json.dumps({{'map': '3m', 'opponent': 'default', "
                    f"'timesteps': 1000, 'final_win_rate': 0.5, 'best_win_rate': 0.5, 'interrupted': False}}))")
            return [sys.executable, "-c", code]
        return command

    monkeypatch.setattr(sweep_module, "train_command", fake("train"))
    monkeypatch.setattr(sweep_module, "resume_command", fake("resume"))
    results = run_sweep(config, progress=False, log=lambda _: None)
    assert started.read_text() == "resume"
    assert (path / "checkpoint.zip").is_file()  # kept, not deleted with the folder
    assert (path / "train.log").read_text() == "first part\nsecond part\n"
    assert results["failed"] == [] and [r["final_win_rate"] for r in results["runs"]] == [0.5]


def test_resume_command_names_the_run_folder_and_the_sweeps_steps(tmp_path):
    from smac_hard_gym.training.baselines.planning import resume_command

    config = SweepConfig(maps=["3m"], seeds=1, opponents=["smac"], out=str(tmp_path), timesteps=2000)
    command = resume_command(Run("3m", "smac", 0), config)
    assert command[command.index("--out") + 1] == str(Run("3m", "smac", 0).path(tmp_path))
    assert command[command.index("--timesteps") + 1] == "2000" and "--resume" in command
