"""Atomic writes (smac_hard_gym/files.py) and every writer that uses them: a failure in the middle of a write leaves
the old target whole and no temporary file behind."""

from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest

from smac_hard_gym import files
from smac_hard_gym.files import atomic_path, atomic_write, write_json, write_text


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


def _fail_fsync(monkeypatch):
    """Make every atomic_write fail after its data was written to the temporary file, before the replace."""
    def fsync(fd):
        raise OSError("disk died")

    monkeypatch.setattr(files.os, "fsync", fsync)


def test_atomic_write_replaces_only_when_complete(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError, match="midway"), atomic_write(target) as handle:
        handle.write("half of the new")
        raise RuntimeError("midway")
    assert target.read_text() == "old" and _names(tmp_path) == ["out.txt"]
    with atomic_write(target) as handle:
        handle.write("new")
        assert target.read_text() == "old"  # not replaced before the block ends
    assert target.read_text() == "new" and _names(tmp_path) == ["out.txt"]
    with atomic_write(tmp_path / "data.bin", "wb") as handle:
        handle.write(b"\x00\x01")
    assert (tmp_path / "data.bin").read_bytes() == b"\x00\x01"
    with pytest.raises(ValueError, match="mode must be"):
        with atomic_write(target, "a"):
            pass


def test_keyboard_interrupt_during_a_write_leaves_the_old_file(tmp_path):
    target = tmp_path / "summary.json"
    target.write_text('{"old": true}')
    with pytest.raises(KeyboardInterrupt), atomic_write(target) as handle:
        handle.write('{"new": ')
        raise KeyboardInterrupt
    assert json.loads(target.read_text()) == {"old": True} and _names(tmp_path) == ["summary.json"]


def test_permissions_are_those_of_a_plain_write(tmp_path):
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    write_text(tmp_path / "atomic.txt", "x")
    assert stat.S_IMODE(os.stat(tmp_path / "atomic.txt").st_mode) == stat.S_IMODE(os.stat(plain).st_mode)
    os.chmod(plain, 0o640)
    write_text(plain, "y")  # an existing file keeps its mode
    assert stat.S_IMODE(os.stat(plain).st_mode) == 0o640 and plain.read_text() == "y"


def test_atomic_path_keeps_the_suffix_and_replaces_when_written(tmp_path):
    target = tmp_path / "curve.png"
    target.write_bytes(b"old png")
    with atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".png" and tmp != target
        tmp.write_bytes(b"new png")
    assert target.read_bytes() == b"new png" and _names(tmp_path) == ["curve.png"]
    with pytest.raises(OSError, match="disk full"), atomic_path(target) as tmp:
        tmp.write_bytes(b"half")
        raise OSError("disk full")
    assert target.read_bytes() == b"new png" and _names(tmp_path) == ["curve.png"]
    with pytest.raises(OSError, match="nothing was written"), atomic_path(target):
        pass
    assert target.read_bytes() == b"new png" and _names(tmp_path) == ["curve.png"]


def test_write_json_leaves_the_old_file_on_unstorable_data(tmp_path):
    target = write_json(tmp_path / "results.json", {"a": 1})
    with pytest.raises(TypeError):
        write_json(target, {"a": object()})
    assert json.loads(target.read_text()) == {"a": 1} and _names(tmp_path) == ["results.json"]


# ---------------------------------------------------------------------------------------------------------------
# The writers.


def test_training_curve_and_plot_writers(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from smac_hard_gym.training import run_files

    row = {c: 0.5 for c in run_files.CURVE_COLUMNS} | {"timesteps": 0, "episodes": 2, "train_episodes": 0}
    run_files.write_curve(tmp_path / "curve.csv", [row])
    assert run_files.plot_curve(tmp_path / "curve.png", [row], "t")
    csv_before, png_before = (tmp_path / "curve.csv").read_bytes(), (tmp_path / "curve.png").read_bytes()
    assert png_before.startswith(b"\x89PNG")

    def half_savefig(self, path, **kwargs):
        with open(path, "wb") as handle:
            handle.write(b"\x89PNG half")
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", half_savefig)
    with pytest.raises(OSError, match="disk full"):
        run_files.plot_curve(tmp_path / "curve.png", [row, row], "t")
    _fail_fsync(monkeypatch)
    with pytest.raises(OSError, match="disk died"):
        run_files.write_curve(tmp_path / "curve.csv", [row, row])
    assert (tmp_path / "curve.csv").read_bytes() == csv_before
    assert (tmp_path / "curve.png").read_bytes() == png_before
    assert _names(tmp_path) == ["curve.csv", "curve.png"]


def test_model_save_and_summary_are_atomic_in_train(tmp_path, monkeypatch):
    pytest.importorskip("sb3_contrib")
    from sb3_contrib import MaskablePPO

    from smac_hard_gym.cli import main

    def interrupted_learn(self, *args, **kwargs):
        raise KeyboardInterrupt

    def half_save(self, path, *args, **kwargs):
        with open(path, "wb") as handle:
            handle.write(b"PK\x03\x04 half a model")
        raise OSError("disk full")

    monkeypatch.setattr(MaskablePPO, "learn", interrupted_learn)
    monkeypatch.setattr(MaskablePPO, "save", half_save)
    out = tmp_path / "run"
    out.mkdir()
    (out / "model.zip").write_bytes(b"the old model")
    argv = ["train", "--map", "3m", "--timesteps", "256", "--num-envs", "2", "--n-steps", "64", "--batch-size",
            "64", "--epochs", "1", "--eval-episodes", "2", "--no-progress", "--out", str(out)]
    with pytest.raises(OSError, match="disk full"):
        main(argv)
    assert (out / "model.zip").read_bytes() == b"the old model"
    assert not [p for p in out.iterdir() if p.name.startswith(".")]
    monkeypatch.undo()
    monkeypatch.setattr(MaskablePPO, "learn", interrupted_learn)
    (out / "summary.json").write_text('{"old": 1}')
    real_write_json = files.write_json

    def failing_summary(path, data, indent=2):
        if str(path).endswith("summary.json"):
            _fail_fsync(monkeypatch)
        return real_write_json(path, data, indent)

    from smac_hard_gym.training import loop

    monkeypatch.setattr(loop, "write_json", failing_summary)
    with pytest.raises(OSError, match="disk died"):
        main(argv)
    assert json.loads((out / "summary.json").read_text()) == {"old": 1}
    assert (out / "model.zip").read_bytes()[:2] == b"PK"  # this time the model was saved whole
    assert not [p for p in out.iterdir() if p.name.startswith(".")]


def test_baselines_writers_are_atomic(tmp_path, monkeypatch):
    from smac_hard_gym.training.baselines import results, write_report

    rows = [{"map": "3m", "opponent": "smac", "seeds": 1, "mean": 0.5, "std": 0.0, "min": 0.5, "max": 0.5}]
    columns = ("map", "opponent", "seeds", "mean", "std", "min", "max")
    results.write_csv(tmp_path / "results.csv", rows, columns)
    before = (tmp_path / "results.csv").read_bytes()
    (tmp_path / "report.md").write_text("old report")
    (tmp_path / "runs").mkdir()
    _fail_fsync(monkeypatch)
    with pytest.raises(OSError, match="disk died"):
        results.write_csv(tmp_path / "results.csv", rows * 2, columns)
    with pytest.raises(OSError, match="disk died"):
        write_report(tmp_path, tmp_path / "report.md")
    assert (tmp_path / "results.csv").read_bytes() == before
    assert (tmp_path / "report.md").read_text() == "old report"
    assert not (tmp_path / "results.json").exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_baselines_curve_plots_are_atomic(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from smac_hard_gym.training.baselines import results

    curves = {("3m", "smac"): [{0: 0.0, 100: 0.5}]}
    results.plot_curves(tmp_path / "curves", curves)
    before = (tmp_path / "curves" / "3m.png").read_bytes()

    def half_savefig(self, path, **kwargs):
        with open(path, "wb") as handle:
            handle.write(b"\x89PNG half")
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", half_savefig)
    with pytest.raises(OSError, match="disk full"):
        results.plot_curves(tmp_path / "curves", curves)
    assert (tmp_path / "curves" / "3m.png").read_bytes() == before
    assert _names(tmp_path / "curves") == ["3m.png"]


def test_duel_json_and_recordings_are_atomic(tmp_path, monkeypatch, capsys):
    from smac_hard_gym.cli import main

    target = tmp_path / "duel.json"
    argv = ["duel", "--map", "3m", "--red", "base", "--blue", "base", "--episodes", "1", "--no-progress",
            "--json", str(target)]
    assert main(argv) == 0
    good = json.loads(target.read_text())
    record = tmp_path / "rec"
    record.mkdir()
    assert main([*argv, "--record", str(record), "--record-episodes", "1"]) == 0
    (recording,) = record.iterdir()
    recorded = recording.read_bytes()
    _fail_fsync(monkeypatch)
    with pytest.raises(OSError, match="disk died"):
        main(argv)
    assert json.loads(target.read_text()) == good
    monkeypatch.setattr("smac_hard_gym.commands.duel.run", lambda args: _record_only(args))
    with pytest.raises(OSError, match="disk died"):
        main([*argv, "--record", str(record), "--record-episodes", "1"])
    assert recording.read_bytes() == recorded
    assert _names(tmp_path) == ["duel.json", "rec"] and _names(record) == [recording.name]


def _record_only(args):
    from smac_hard_gym.commands import duel

    duel._record(args)
    return 0


def test_solutions_json_is_atomic(tmp_path, monkeypatch):
    from smac_hard_gym.commands import solutions

    monkeypatch.setattr("smac_hard_gym.envs.solutions.check_claim", lambda claim, episodes, seed: _Verdict())
    target = tmp_path / "solutions.json"
    target.write_text("[]")
    _fail_fsync(monkeypatch)

    class Args:
        map, episodes, seed, json = None, 1, 0, str(target)

    with pytest.raises(OSError, match="disk died"):
        solutions.run(Args)
    assert target.read_text() == "[]" and _names(tmp_path) == ["solutions.json"]


class _Verdict:
    rate = other_rate = 0.5
    holds = True


def test_np_savez_into_atomic_write_round_trips(tmp_path):
    with atomic_write(tmp_path / "a.npz", "wb") as handle:
        np.savez_compressed(handle, x=np.arange(3))
    with np.load(tmp_path / "a.npz") as data:
        assert data["x"].tolist() == [0, 1, 2]
