"""Baseline sweeps: the planner (runs, skip finished, redo partial), aggregation over hand-made run directories with
hand-computed means and spreads, the markdown report, the CLI's one-line errors, and one tiny sweep end to end."""

import csv
import json
import math
import shutil
import sys

import pytest

from smac_hard_gym.cli import main
from smac_hard_gym.training import baselines
from smac_hard_gym.training.baselines import (
    PAPER,
    Run,
    SweepConfig,
    aggregate,
    plan,
    report_markdown,
    run_state,
    run_sweep,
    sweep,  # run_sweep looks train_command up there
)


def _fake_run(out, map_name, opponent, seed, final, curve, blackbox=None, interrupted=False, value=None,
              per_opponent=None, train_wall_s=1.0):
    """A run directory as `smac-hard-gym train` (and `eval --json`) leave it, with chosen numbers."""
    path = Run(map_name, opponent, seed).path(out)
    path.mkdir(parents=True)
    (path / "config.json").write_text(json.dumps({"map_name": map_name, "opponent": opponent, "seed": seed}))
    with (path / "curve.csv").open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["timesteps", "win_rate"])
        writer.writerows(curve)
    (path / "summary.json").write_text(json.dumps({
        "map": map_name, "opponent": opponent, "timesteps": curve[-1][0], "final_win_rate": final,
        "best_win_rate": max(r for _, r in curve), "train_wall_s": train_wall_s, "interrupted": interrupted,
        "final_per_opponent": per_opponent or {}}))
    if blackbox is not None:
        weights = {name: 1.0 / len(blackbox) for name in blackbox}
        (path / "blackbox.json").write_text(json.dumps({
            "scripts": {name: {"win_rate": rate} for name, rate in blackbox.items()}, "weights": weights,
            "mixture": {"win_rate": sum(weights[n] * r for n, r in blackbox.items())}}))
    if value is not None:
        (path / "value.json").write_text(json.dumps({"mean_value": value}))
    return path


# ---------------------------------------------------------------------------------------------------------------
# Planning and resuming.


def test_plan_covers_maps_opponents_and_seeds_in_order(tmp_path):
    config = SweepConfig(maps=["3m", "MMM"], seeds=2, out=str(tmp_path))
    assert [r.label for r in plan(config)] == [
        "3m-smac-s0", "3m-smac-s1", "3m-default-s0", "3m-default-s1",
        "MMM-smac-s0", "MMM-smac-s1", "MMM-default-s0", "MMM-default-s1"]
    assert len(plan(SweepConfig(seeds=3, out=str(tmp_path)))) == 23 * 2 * 3
    assert config.blackbox and not config.values


def test_mixing_plan_runs_nearest_weakest_and_both_on_10m_vs_11m(tmp_path):
    config = SweepConfig(experiment="mixing", seeds=1, out=str(tmp_path))
    assert [r.label for r in plan(config)] == ["10m_vs_11m-nearest-s0", "10m_vs_11m-weakest-s0",
                                               "10m_vs_11m-nearest+weakest-s0"]
    assert config.values and not config.blackbox


def test_run_state_is_todo_partial_or_done_from_the_run_folder(tmp_path):
    assert run_state(tmp_path / "none") == "todo"
    (tmp_path / "half").mkdir()
    assert run_state(tmp_path / "half") == "partial"
    done = _fake_run(tmp_path, "3m", "smac", 0, 1.0, [(0, 0.0), (256, 1.0)])
    assert run_state(done) == "done"
    cut = _fake_run(tmp_path, "3m", "smac", 1, 1.0, [(0, 0.0), (256, 1.0)], interrupted=True)
    assert run_state(cut) == "partial"


def test_sweep_skips_finished_runs_and_redoes_partial_ones(tmp_path, monkeypatch):
    """Training is replaced by a child that writes a run's files; only the runs not done are started."""
    started = tmp_path / "started.txt"

    def fake_train(run, config):
        path = run.path(config.out)
        code = (f"import json, pathlib; p = pathlib.Path({str(path)!r}); p.mkdir(parents=True, exist_ok=True); "
                f"open({str(started)!r}, 'a').write({run.label!r} + '\\n'); "
                f"(p / 'curve.csv').write_text('timesteps,win_rate\\n0,0.0\\n256,0.5\\n'); "
                f"(p / 'summary.json').write_text(json.dumps({{'map': {run.map_name!r}, "
                f"'opponent': {run.opponent!r}, 'timesteps': 256, 'final_win_rate': 0.5, 'best_win_rate': 0.5, "
                f"'interrupted': False}}))")
        return [sys.executable, "-c", code]

    monkeypatch.setattr(sweep, "train_command", fake_train)
    out = tmp_path / "out"
    config = SweepConfig(maps=["3m"], seeds=3, opponents=["default"], out=str(out), jobs=2)
    _fake_run(out, "3m", "default", 0, 1.0, [(0, 0.0), (256, 1.0)])  # done: kept
    partial = Run("3m", "default", 1).path(out)
    partial.mkdir(parents=True)
    (partial / "stale.txt").write_text("from a killed run")
    results = run_sweep(config, progress=False, log=lambda _: None)
    assert sorted(started.read_text().split()) == ["3m-default-s1", "3m-default-s2"]
    assert not (partial / "stale.txt").exists()
    assert results["failed"] == []
    assert [r["final_win_rate"] for r in results["runs"]] == [1.0, 0.5, 0.5]
    started.unlink()
    run_sweep(config, progress=False, log=lambda _: None)  # all done: nothing started
    assert not started.exists()


def test_a_failed_run_is_reported_and_redone_next_time(tmp_path, monkeypatch):
    monkeypatch.setattr(sweep, "train_command", lambda run, config: [sys.executable, "-c", "raise SystemExit(3)"])
    config = SweepConfig(maps=["3m"], seeds=1, opponents=["default"], out=str(tmp_path))
    results = run_sweep(config, progress=False, log=lambda _: None)
    assert results["failed"] == ["3m-default-s0"]
    assert (Run("3m", "default", 0).path(tmp_path) / "train.log").is_file()
    assert run_state(Run("3m", "default", 0).path(tmp_path)) == "partial"


def test_each_smac_model_is_evaluated_black_box_before_the_next_run_trains(tmp_path, monkeypatch):
    """One slot: train s0, evaluate s0, train s1, ...; and results.json already holds s0 (with its black-box row)
    when s1 starts, so a sweep cut short keeps what finished. A failed training gets no evaluation."""
    events = tmp_path / "events.txt"

    def fake_train(run, config):
        path = run.path(config.out)
        results = str(tmp_path / "out" / "results.json")
        fail = "raise SystemExit(2)" if run.seed == 2 else "pass"
        code = (f"import json, os, pathlib; p = pathlib.Path({str(path)!r}); p.mkdir(parents=True, exist_ok=True); "
                f"r = {results!r}; seen = [(x['seed'], 'blackbox' in x) for x in json.load(open(r))['runs']] "
                f"if os.path.exists(r) else []; "
                f"open({str(events)!r}, 'a').write('train ' + {run.label!r} + ' ' + repr(seen) + '\\n'); {fail}; "
                f"(p / 'curve.csv').write_text('timesteps,win_rate\\n0,0.0\\n256,0.5\\n'); "
                f"(p / 'summary.json').write_text(json.dumps({{'map': {run.map_name!r}, "
                f"'opponent': {run.opponent!r}, 'timesteps': 256, 'final_win_rate': 0.5, 'best_win_rate': 0.5, "
                f"'interrupted': False}})); "
                f"(p / 'config.json').write_text(json.dumps({{'seed': {run.seed}}}))")
        return [sys.executable, "-c", code]

    def fake_blackbox(run, config):
        path = run.path(config.out)
        code = (f"import json; open({str(events)!r}, 'a').write('eval ' + {run.label!r} + '\\n'); "
                f"open({str(path / 'blackbox.json')!r}, 'w').write(json.dumps({{'scripts': {{'line_front': "
                f"{{'win_rate': 0.25}}}}, 'weights': {{'line_front': 1.0}}, 'mixture': {{'win_rate': 0.25}}}}))")
        return [sys.executable, "-c", code]

    monkeypatch.setattr(sweep, "train_command", fake_train)
    monkeypatch.setattr(sweep, "blackbox_command", fake_blackbox)
    out = tmp_path / "out"
    config = SweepConfig(maps=["3m"], seeds=3, opponents=["smac"], out=str(out), jobs=1)
    results = run_sweep(config, progress=False, log=lambda _: None)
    assert events.read_text().splitlines() == [
        "train 3m-smac-s0 []", "eval 3m-smac-s0", "train 3m-smac-s1 [(0, True)]", "eval 3m-smac-s1",
        "train 3m-smac-s2 [(0, True), (1, True)]"]
    assert results["failed"] == ["3m-smac-s2"]
    assert [(r["seed"], r["blackbox"]["line_front"]) for r in results["runs"]] == [(0, 0.25), (1, 0.25)]
    # A trained model whose evaluation is missing (the machine stopped between the two) is evaluated, not retrained.
    (Run("3m", "smac", 1).path(out) / "blackbox.json").unlink()
    events.unlink()
    run_sweep(config, progress=False, log=lambda _: None)
    assert events.read_text().splitlines() == [
        "eval 3m-smac-s1", "train 3m-smac-s2 [(0, True), (1, True)]"]


# ---------------------------------------------------------------------------------------------------------------
# Aggregation and report.


def test_aggregation_gives_hand_computed_mean_std_min_max_per_map_and_script(tmp_path):
    # 3m vs smac: final 1.0, 0.5, 0.75 -> mean 0.75, std sqrt((0.25^2 + 0.25^2 + 0) / 3) = 0.2041, min 0.5, max 1.0
    for seed, (final, bb) in enumerate([(1.0, (0.0, 0.5)), (0.5, (0.25, 0.25)), (0.75, (0.5, 1.0))]):
        _fake_run(tmp_path, "3m", "smac", seed, final, [(0, 0.0), (100, final / 2), (200, final)],
                  blackbox={"line_front": bb[0], "other": bb[1]})
    _fake_run(tmp_path, "3m", "default", 0, 0.25, [(0, 0.0), (200, 0.25)],
              per_opponent={"line_front": 0.0, "base": 0.5})
    _fake_run(tmp_path, "8m", "default", 0, 0.5, [(0, 0.0), (200, 0.5)],
              per_opponent={"line_front": 0.0, "line_weakest": 1.0})
    _fake_run(tmp_path, "8m", "default", 1, 0.75, [(0, 0.0), (200, 0.75)],
              per_opponent={"line_front": 0.5, "line_weakest": 1.0})
    _fake_run(tmp_path, "8m", "smac", 0, 1.0, [(0, 0.0), (200, 1.0)], per_opponent={"smac": 1.0})
    (tmp_path / "runs" / "3m-default-s1").mkdir()  # partial: left out
    results = aggregate(tmp_path)
    smac, default = results["table"][:2]
    pool = {(r["map"], r["script"]): (r["seeds"], r["mean"], r["min"], r["max"]) for r in results["pool"]}
    assert pool == {("3m", "line_front"): (1, 0.0, 0.0, 0.0), ("3m", "base"): (1, 0.5, 0.5, 0.5),  # `smac` runs: none
                    ("8m", "line_front"): (2, 0.25, 0.0, 0.5), ("8m", "line_weakest"): (2, 1.0, 1.0, 1.0)}
    assert [(r["map"], r["script"]) for r in results["pool"]][:2] == [("3m", "base"), ("3m", "line_front")]
    with open(tmp_path / "pool.csv") as handle:
        assert next(csv.DictReader(handle)) == {"map": "3m", "script": "base", "seeds": "1", "mean": "0.5000",
                                                "std": "0.0000", "min": "0.5000", "max": "0.5000"}
    assert "| 8m | line_front | 0.25 ± 0.25 (0.00-0.50) |" in report_markdown(results)
    assert (smac["map"], smac["opponent"], smac["seeds"]) == ("3m", "smac", 3)
    assert smac["mean"] == pytest.approx(0.75)
    assert smac["std"] == pytest.approx(math.sqrt(0.125 / 3))
    assert (smac["min"], smac["max"]) == (0.5, 1.0)
    assert (default["seeds"], default["mean"], default["std"]) == (1, 0.25, 0.0)
    bb = {r["script"]: r for r in results["blackbox"]}
    assert bb["line_front"]["mean"] == pytest.approx(0.25)  # (0 + 0.25 + 0.5) / 3
    assert bb["other"]["mean"] == pytest.approx(0.5833333)  # (0.5 + 0.25 + 1) / 3
    assert bb["mixture"]["mean"] == pytest.approx((0.25 + 0.25 + 0.75) / 3)  # per seed: 0.25, 0.25, 0.75
    assert bb["line_front"]["weight"] == 0.5
    with open(tmp_path / "results.csv") as handle:
        rows = list(csv.DictReader(handle))
    assert rows[0] == {"map": "3m", "opponent": "smac", "seeds": "3", "mean": "0.7500", "std": "0.2041",
                       "min": "0.5000", "max": "1.0000"}
    with open(tmp_path / "blackbox.csv") as handle:
        assert [r["script"] for r in csv.DictReader(handle)] == ["line_front", "other", "mixture"]
    assert (tmp_path / "curves" / "3m.png").stat().st_size > 0
    assert json.loads((tmp_path / "results.json").read_text())["table"] == results["table"]


def test_mean_curve_over_seeds():
    steps, mean, low, high = baselines.mean_curve([{0: 0.0, 100: 0.5, 200: 1.0}, {0: 0.0, 100: 1.0, 200: 0.5}])
    assert steps.tolist() == [0, 100, 200]
    assert mean.tolist() == [0.0, 0.75, 0.75]
    assert low.tolist() == [0.0, 0.5, 0.5] and high.tolist() == [0.0, 1.0, 1.0]


def test_report_renders_a_published_results_json_without_run_folders(tmp_path, capsys):
    # A published sweep (docs/baselines/<name>/) keeps results.json and the tables, not the runs: --report renders it.
    for map_name in ("3m", "8m", "MMM"):
        for seed, final in enumerate([1.0, 0.5]):
            _fake_run(tmp_path / "sweep", map_name, "smac", seed, final, [(0, 0.0), (1000, final)],
                      blackbox={"line_front": final / 2})
    results = aggregate(tmp_path / "sweep")
    results["config"] = {"maps": ["MMM"]}  # a sweep finished over several sessions: its config names the last one's
    published = tmp_path / "published"
    published.mkdir()
    (published / "results.json").write_text(json.dumps(results))
    assert main(["baselines", "--out", str(published), "--report", str(tmp_path / "report.md")]) == 0
    text = (tmp_path / "report.md").read_text()
    assert text == report_markdown(results, ["3m", "8m", "MMM"])
    rows = [line for line in text.splitlines() if line.startswith("| ") and "0.75 ± 0.25" in line]
    listed = {line.split("|")[1].strip() for line in rows}
    assert listed == {r["map"] for r in results["table"]} == {"3m", "8m", "MMM"}
    assert not (published / "runs").exists()  # nothing was aggregated or written under --out


def test_published_sweep_report_lists_every_map():
    # docs/baselines/sweep-1M is the published 23-map sweep: its report lists all 23 maps with our win rates.
    from pathlib import Path

    out = Path(__file__).resolve().parents[1] / "docs" / "baselines" / "sweep-1M"
    results = json.loads((out / "results.json").read_text())
    text = report_markdown(results, results["config"].get("maps") or None)
    maps = {r["map"] for r in results["table"]}
    assert len(maps) == 23
    for map_name in maps:
        assert any(line.startswith(f"| {map_name} |") and "not run yet" not in line for line in text.splitlines())


def test_report_puts_ours_next_to_the_paper(tmp_path):
    for seed, final in enumerate([1.0, 0.5]):
        _fake_run(tmp_path, "3m", "smac", seed, final, [(0, 0.0), (1000, final)],
                  blackbox={"line_front": final / 2})
    path = baselines.write_report(tmp_path, tmp_path / "report.md")
    text = path.read_text()
    row = next(line for line in text.splitlines() if line.startswith("| 3m |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1:3] == ["0.98", "0.99"]  # paper, appendix A: QMIX 0.9798, MAPPO 0.9897
    assert cells[3] == "0.75 ± 0.25 (0.50-1.00)"
    assert cells[4:6] == ["0.99", "1.00"] and cells[8] == "not run yet"  # default: 10M table; ours not run
    assert cells[9:11] == ["0.01", "0.10"] and cells[11] == "0.38 ± 0.12 (0.25-0.50)"
    assert sum(line.count("not run yet") == 3 for line in text.splitlines()) == 22  # the other maps
    assert "after 1,000 env steps" in text and "section 6.2" in text


def test_spearman_matches_hand_computed_ranks_with_ties():
    # one swapped pair of four: 1 - 6 * (1 + 1) / (4 * (16 - 1)) = 0.8
    assert baselines.spearman([1, 2, 3, 4], [10, 30, 20, 40]) == pytest.approx(0.8)
    # a tie shares ranks 1 and 2 (1.5 each): ranks (1.5, 1.5, 3) against (1, 2, 3); Pearson's r = 1.5 / sqrt(1.5 * 2)
    assert baselines.spearman([0.0, 0.0, 1.0], [0.1, 0.2, 0.3]) == pytest.approx(math.sqrt(3) / 2)
    assert baselines.spearman([3, 2, 1], [1, 2, 3]) == pytest.approx(-1.0)
    assert math.isnan(baselines.spearman([0.0, 0.0, 0.0], [0.1, 0.2, 0.3]))  # every map tied: no ranking


def test_findings_sort_maps_by_the_papers_claims(tmp_path):
    # (map, smac finals, default finals, black-box finals of the smac runs), 2 seeds each
    cells = [("3m", (1.0, 1.0), (1.0, 0.96875), (0.0, 0.0)),  # default 1/64 lower: level; black-box lower
             ("8m", (1.0, 1.0), (0.5, 0.5), (0.0, 0.5)),  # both lower
             ("2s3z", (0.5, 0.5), (1.0, 1.0), (0.5, 0.5)),  # default higher; black-box level
             ("MMM", (1.0, 0.0), (0.0, 0.0), (0.0, 0.0))]  # smac 0.5: lower by exactly 0.5
    for map_name, smac, default, bb in cells:
        for seed in range(2):
            _fake_run(tmp_path, map_name, "smac", seed, smac[seed], [(0, 0.0), (100, smac[seed])],
                      blackbox={"only": bb[seed]})
            _fake_run(tmp_path, map_name, "default", seed, default[seed], [(0, 0.0), (100, default[seed])])
    _fake_run(tmp_path, "25m", "smac", 0, 1.0, [(0, 0.0), (100, 1.0)])  # one seed, no default: left out
    found = aggregate(tmp_path)["findings"]
    assert found["seeds"] == 2 and found["maps"] == ["3m", "8m", "2s3z", "MMM"]  # the paper's order
    assert found["pool_vs_smac"] == {"lower": ["8m", "MMM"], "level": ["3m"], "higher": ["2s3z"], "missing": []}
    assert found["blackbox_vs_smac"] == {"lower": ["3m", "8m", "MMM"], "level": ["2s3z"], "higher": [],
                                         "missing": []}
    # smac means 1, 1, 0.5, 0.5 (ranks 3.5, 3.5, 1.5, 1.5) against the paper's 2M means of QMIX and MAPPO:
    # 3m 0.98475, 8m 0.96675, 2s3z 0.9571, MMM 0.954 (ranks 4, 3, 2, 1)
    assert found["spearman"]["smac vs paper smac_2m"] == pytest.approx(2 / math.sqrt(5))
    # black-box means 0, 0.25, 0.5, 0 (ranks 1.5, 3, 4, 1.5) against the paper's 0.057, 0.044, 0.086, 0 (3, 2, 4, 1)
    assert found["spearman"]["black-box vs paper blackbox_10m"] == pytest.approx(3 / math.sqrt(22.5))
    text = report_markdown(aggregate(tmp_path))
    assert "the mixed pool lower than `smac` on 2 of 4, level on 1, higher on 1" in text
    assert "black-box lower than `smac` on 3 of 4, level on 1" in text


def test_training_time_reports_median_range_and_total_per_map(tmp_path):
    for seed, seconds in enumerate([60.0, 180.0, 120.0]):  # 1, 3 and 2 minutes: median 2, total 6
        _fake_run(tmp_path, "8m", "smac", seed, 1.0, [(0, 0.0), (100, 1.0)], train_wall_s=seconds)
    _fake_run(tmp_path, "3m", "default", 0, 1.0, [(0, 0.0), (100, 1.0)], train_wall_s=1800.0)
    results = aggregate(tmp_path)
    rows = baselines.training_time(results)
    assert [(r["map"], r["runs"]) for r in rows] == [("3m", 1), ("8m", 3)]  # the paper's order
    assert (rows[1]["median"], rows[1]["min"], rows[1]["max"], rows[1]["total"]) == (2.0, 1.0, 3.0, 6.0)
    text = report_markdown(results)
    assert "0.6 hours over 4 runs" in text and "| 8m | 3 | 2.0 | 1.0-3.0 |" in text  # (30 + 6) minutes


def test_paper_tables_cover_every_map():
    from smac_hard_gym.maps import list_maps

    for table in PAPER.values():
        assert set(table) == set(list_maps())
        assert all(0.0 <= v <= 1.0 for pair in table.values() for v in pair)
    assert PAPER["default_10m"]["10m_vs_11m"] == (0.6813, 0.5681)
    assert PAPER["blackbox_10m"]["2c_vs_64zg"] == (0.6238, 0.3419)


def test_mixing_report_lists_values(tmp_path):
    for opponent, value in (("nearest", 1.0), ("weakest", 0.8), ("nearest,weakest", 0.5)):
        _fake_run(tmp_path, "10m_vs_11m", opponent, 0, 0.5, [(0, 0.0), (100, 0.5)], value=value)
    results = aggregate(tmp_path, SweepConfig(experiment="mixing", seeds=1, out=str(tmp_path)))
    assert [(r["opponent"], r["mean"]) for r in results["values"]] == [
        ("nearest", 1.0), ("nearest,weakest", 0.5), ("weakest", 0.8)]
    text = report_markdown(results)
    assert "| 10m_vs_11m | nearest,weakest | 0.50 (1 seed) | 0.50 (1 seed) |" in text
    assert "paper" not in text.lower()


# ---------------------------------------------------------------------------------------------------------------
# Command line.


@pytest.mark.parametrize(("argv", "message"), [
    (["--maps", "4m"], "unknown map '4m'"),
    (["--maps", ","], "--maps must be 'all' or map names"),
    (["--seeds", "0"], "seeds must be a positive int, got 0"),
    (["--timesteps", "-5"], "timesteps must be a positive int"),
    (["--jobs", "0"], "jobs must be a positive int"),
    (["--maps", "3m", "--opponents", "nobody"], "unknown opponent 'nobody' for map '3m'"),
    (["--report", "r.md", "--out", "/nonexistent/results"], "no runs under /nonexistent/results and no results.json"),
])
def test_cli_bad_input_is_one_line(argv, message, capsys):
    assert main(["baselines", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("smac-hard-gym baselines: error: ") and message in err and err.count("\n") == 1


def test_dry_run_prints_the_plan(tmp_path, capsys):
    _fake_run(tmp_path, "3m", "smac", 0, 1.0, [(0, 0.0), (10, 1.0)])
    assert main(["baselines", "--maps", "3m", "--seeds", "2", "--out", str(tmp_path), "--dry-run"]) == 0
    printed = capsys.readouterr().out
    assert "1 map(s) x 2 opponent(s) (smac, default) x 2 seed(s) = 4 runs" in printed
    assert "done     3m-smac-s0" in printed and "todo     3m-default-s1" in printed
    assert not (tmp_path / "results.json").exists()


@pytest.mark.long  # trains a tiny sweep end to end: 96 s at load 8
def test_tiny_sweep_end_to_end(tmp_path, capsys):
    out = tmp_path / "results"
    code = main(["baselines", "--maps", "3m", "--seeds", "1", "--opponents", "smac", "--timesteps", "256",
                 "--num-envs", "8", "--eval-episodes", "4", "--out", str(out), "--no-progress",
                 "--train-args", "--n-steps 32 --batch-size 64 --epochs 1"])
    assert code == 0, capsys.readouterr()
    run = out / "runs" / "3m-smac-s0"
    for name in ("model.zip", "summary.json", "curve.csv", "train.log", "blackbox.json", "eval.log"):
        assert (run / name).is_file(), name
    results = json.loads((out / "results.json").read_text())
    assert [(r["map"], r["opponent"], r["seeds"]) for r in results["table"]] == [("3m", "smac", 1)]
    assert [r["script"] for r in results["blackbox"]] == ["line_front", "mixture"]
    for name in ("results.csv", "blackbox.csv", "curves/3m.png"):
        assert (out / name).is_file(), name
    assert "| 3m |" in capsys.readouterr().out

    baselines.value_main(str(run / "model.zip"), "smac,base", 4, 0, str(tmp_path / "value.json"))  # a mixture
    assert math.isfinite(json.loads((tmp_path / "value.json").read_text())["mean_value"])


# ---------------------------------------------------------------------------------------------------------------
# Malformed files under --out: `baselines --report` gives one line naming the file, never a traceback.


def _corrupt(name, content):
    def apply(path):
        (path / name).write_bytes(content if isinstance(content, bytes) else json.dumps(content).encode())
    return apply


_SUMMARY = {"map": "3m", "opponent": "smac", "timesteps": 100, "final_win_rate": 0.5, "best_win_rate": 0.5,
            "train_wall_s": 1.0, "interrupted": False, "final_per_opponent": {}}

MALFORMED = [
    ("summary.json", _corrupt("summary.json", {**_SUMMARY, "final_win_rate": "high"}), "final_win_rate"),
    ("summary.json", _corrupt("summary.json", {**_SUMMARY, "final_win_rate": 7.5}), "final_win_rate"),
    ("summary.json", _corrupt("summary.json", {**_SUMMARY, "timesteps": None}), "timesteps"),
    ("summary.json", _corrupt("summary.json", {k: v for k, v in _SUMMARY.items() if k != "map"}), "'map'"),
    ("summary.json", _corrupt("summary.json", {**_SUMMARY, "final_per_opponent": [1, 2]}), "final_per_opponent"),
    ("config.json", _corrupt("config.json", b"\x00\xff garbage"), "config.json"),
    ("config.json", _corrupt("config.json", [1, 2, 3]), "config.json"),
    ("config.json", _corrupt("config.json", {"seed": "zero"}), "seed"),
    ("curve.csv", _corrupt("curve.csv", b"timesteps,win_rate\n0,abc\n"), "curve.csv"),
    ("curve.csv", _corrupt("curve.csv", b"\x00\x01\x02\xff\xfe"), "curve.csv"),
    ("curve.csv", _corrupt("curve.csv", b"a,b\n1,2\n"), "curve.csv"),
    ("blackbox.json", _corrupt("blackbox.json", b"{truncated"), "blackbox.json"),
    ("blackbox.json", _corrupt("blackbox.json", {"scripts": {}}), "blackbox.json"),
    ("blackbox.json", _corrupt("blackbox.json", {"scripts": {"a": {"win_rate": None}}, "mixture": {"win_rate": 0},
                                                 "weights": {}}), "win_rate"),
    ("value.json", _corrupt("value.json", {"mean_value": float("nan")}), "mean_value"),
    ("value.json", _corrupt("value.json", b""), "value.json"),
]


@pytest.mark.parametrize(("name", "corrupt", "named"), MALFORMED, ids=[f"{m[0]}-{i}" for i, m in enumerate(MALFORMED)])
def test_report_on_malformed_run_files_is_one_line(tmp_path, capsys, name, corrupt, named):
    path = _fake_run(tmp_path, "3m", "smac", 0, 0.5, [(0, 0.0), (100, 0.5)], blackbox={"line_front": 0.5},
                     value=0.1)
    corrupt(path)
    assert main(["baselines", "--out", str(tmp_path), "--report", str(tmp_path / "report.md")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("smac-hard-gym baselines: error: ") and err.count("\n") == 1, err
    assert name in err and named in err and "Traceback" not in err, err
    assert not (tmp_path / "report.md").exists()


def test_report_with_malformed_results_json_is_one_line(tmp_path, capsys):
    _fake_run(tmp_path, "3m", "smac", 0, 0.5, [(0, 0.0), (100, 0.5)])
    for content in (b"\xff\xfe", b"[1, 2]", b'{"config": 5}', b'{"config": {"maps": 3}}'):
        (tmp_path / "results.json").write_bytes(content)
        assert main(["baselines", "--out", str(tmp_path), "--report", str(tmp_path / "report.md")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "results.json" in err and "Traceback" not in err, (content, err)


def test_unreadable_summary_counts_as_partial(tmp_path):
    path = _fake_run(tmp_path, "3m", "smac", 0, 0.5, [(0, 0.0), (100, 0.5)])
    for content in (b"", b"\xff\xfe", b"[1]", b'{"interrupted": "no"}', b"{"):
        (path / "summary.json").write_bytes(content)
        assert run_state(path) == "partial", content


def test_runs_recorded_in_results_json_without_folders_count_as_done_and_stay_in_the_tables(tmp_path, capsys):
    # A sweep carried on over machines: the first machine's run folders (models, logs) are gone, its results.json
    # (committed) lists them. They are not trained again and stay in the tables beside the new runs.
    _fake_run(tmp_path, "3m", "smac", 0, 1.0, [(0, 0.0), (100, 0.5), (200, 1.0)],
              blackbox={"line_front": 0.5, "other": 0.0})
    _fake_run(tmp_path, "8m", "default", 0, 0.25, [(0, 0.0), (200, 0.25)], per_opponent={"line_front": 0.25})
    aggregate(tmp_path)
    for label in ("3m-smac-s0", "8m-default-s0"):
        shutil.rmtree(tmp_path / "runs" / label)
    _fake_run(tmp_path, "3m", "smac", 1, 0.5, [(0, 0.0), (100, 0.0), (200, 0.5)],
              blackbox={"line_front": 0.0, "other": 1.0})
    results = aggregate(tmp_path)
    smac = next(r for r in results["table"] if (r["map"], r["opponent"]) == ("3m", "smac"))
    assert (smac["seeds"], smac["mean"], smac["min"], smac["max"]) == (2, 0.75, 0.5, 1.0)
    bb = {r["script"]: (r["seeds"], r["mean"], r["weight"]) for r in results["blackbox"]}
    # mixture per seed: 0.5 * 0.5 + 0.5 * 0.0 = 0.25 and 0.5 * 0.0 + 0.5 * 1.0 = 0.5
    assert bb == {"line_front": (2, 0.25, 0.5), "other": (2, 0.5, 0.5), "mixture": (2, 0.375, 1.0)}
    assert [(r["map"], r["script"], r["mean"]) for r in results["pool"]] == [("8m", "line_front", 0.25)]
    recorded = next(r for r in results["runs"] if r["dir"] == "runs/3m-smac-s0")
    assert recorded["curve"] == [[0, 0.0], [100, 0.5], [200, 1.0]]
    # Written back, read back: a third aggregation keeps the same tables.
    assert aggregate(tmp_path)["table"] == results["table"]

    config = SweepConfig(maps=["3m"], seeds=3, opponents=["smac"], out=str(tmp_path))
    states = {run.label: state for run, state in sweep.sweep_states(config).items()}
    assert states == {"3m-smac-s0": "recorded", "3m-smac-s1": "done", "3m-smac-s2": "todo"}
    assert main(["baselines", "--maps", "3m", "--seeds", "3", "--opponents", "smac", "--out", str(tmp_path),
                 "--dry-run"]) == 0
    printed = capsys.readouterr().out
    assert "recorded 3m-smac-s0" in printed and "done     3m-smac-s1" in printed and "todo     3m-smac-s2" in printed


def test_a_malformed_recorded_run_is_named(tmp_path):
    (tmp_path / "results.json").write_text(json.dumps({"runs": [
        {"map": "3m", "opponent": "smac", "seed": 0, "timesteps": 200, "final_win_rate": 1.5, "best_win_rate": 1.0,
         "dir": "runs/3m-smac-s0"}]}))
    with pytest.raises(baselines.MalformedFile, match=r"results\.json.*final_win_rate is 1\.5"):
        aggregate(tmp_path)
