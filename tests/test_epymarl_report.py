"""benchmarks/epymarl/report.py on hand-made run folders: the final win rate of a run, runs moved aside on an earlier
engine left out, several folders in one report, and Spearman's correlation with the paper's QMIX column."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from script_helpers import load_benchmark


def _report():
    return load_benchmark("epymarl/report.py", "epymarl_report")


def _run(folder: Path, map_name: str, seed_dir: str, wins: list[float], done: bool = True) -> None:
    run = folder / "qmix" / map_name / seed_dir / "sacred" / "1" / "1"
    run.mkdir(parents=True)
    steps = [50_000 * (k + 1) for k in range(len(wins))]
    (run / "info.json").write_text(json.dumps({"test_battle_won_mean": wins, "test_battle_won_mean_T": steps}))
    if done:
        (run.parents[2] / "done.json").write_text("{}")


def test_report_table_and_spearman(tmp_path):
    first, second = tmp_path / "marines", tmp_path / "others"
    _run(first, "3m", "seed0", [0.1, 0.5, 0.9, 1.0])  # last 3: (0.5 + 0.9 + 1.0) / 3 = 0.8
    _run(first, "8m", "seed0", [0.4, 0.5, 0.6])  # 0.5
    _run(first, "8m", "seed0.engine-0123456789abcdef", [0.0, 0.0, 0.0])  # moved aside: an earlier engine
    _run(second, "corridor", "seed0", [0.0, 0.1, 0.2])  # 0.1
    _run(second, "MMM2", "seed0", [0.3, 0.3, 0.3], done=False)  # running: in the table, not in the correlation
    assert _report().main(["--out", str(first), str(second), "--no-plots"]) == 0
    report = (first / "report.md").read_text()
    assert "| 3m | 0.800 [seed0] | 0.980 |" in report
    assert "| 8m | 0.500 [seed0] | 0.980 |" in report  # the moved-aside zeros are not a second row
    assert "| corridor | 0.100 [seed0] | 0.000 |" in report
    assert "| MMM2 | 0.300* (0.15M) [seed0] |" in report
    # ours 0.8 > 0.5 > 0.1 and the paper's QMIX 0.9798 > 0.9797 > 0.0 rank the three maps alike: rho = 1
    assert "Spearman, QMIX (finished runs) with the paper's QMIX: 1.00 over 3 maps (3m, 8m, corridor)." in report


def _provenance(job: Path, fingerprint: str, commit: str, extra: str = "") -> None:
    (job / "engine.json").write_text(json.dumps({"fingerprint": fingerprint}))
    (job / "logs").mkdir()
    command = (f"# python src/main.py --config=qmix --env-config=sc2 -F {job}/sacred/1 with env_args.map_name=8m "
               f'seed=0 t_max=2050000 save_model=True local_results_path="{job}" runner=parallel batch_size_run=2'
               f"{extra}")
    (job / "logs" / "1.log").write_text(f"{command}\n# smac-hard-gym {commit}; EPyMARL cbc38c0\n")


def test_record_keeps_a_lost_folder_and_a_live_run_supersedes_it(tmp_path):
    runs, kept = tmp_path / "runs", tmp_path / "kept.json"
    _run(runs, "3m", "seed0", [0.1, 0.5, 0.9, 1.0])
    _provenance(runs / "qmix" / "3m" / "seed0", "aaaa", "abc123")
    _run(runs, "8m", "seed0", [0.2, 0.2, 0.2], done=False)
    _provenance(runs / "qmix" / "8m" / "seed0", "aaaa", "abc123")
    report = _report()
    assert report.main(["--out", str(runs), "--record", str(kept), "--no-plots"]) == 0
    text = kept.read_text()
    assert str(tmp_path) not in text  # no machine paths on record
    by_map = {r["map"]: r for r in json.loads(text)["runs"]}
    assert by_map["3m"]["engine"] == "aaaa" and by_map["3m"]["smac_hard_gym"] == "abc123"
    assert by_map["3m"]["done"] and not by_map["8m"]["done"]

    # the machine is lost: the record alone gives the same table
    shutil.rmtree(runs)
    table = tmp_path / "table"
    table.mkdir()
    assert report.main(["--out", str(table), "--records", str(kept), "--no-plots"]) == 0
    text = (table / "report.md").read_text()
    assert "| 3m | 0.800 [seed0] | 0.980 |" in text
    assert "| 8m | 0.200* (0.15M) [seed0] |" in text

    # the 8m run restarted on the same engine and went further: the live run replaces the recorded one
    _run(table, "8m", "seed0", [0.2, 0.2, 0.2, 0.6, 0.7, 0.8])
    _provenance(table / "qmix" / "8m" / "seed0", "aaaa", "abc123")
    assert report.main(["--out", str(table), "--records", str(kept), "--no-plots"]) == 0
    text = (table / "report.md").read_text()
    assert "| 8m | 0.700 [seed0] | 0.980 |" in text  # (0.6 + 0.7 + 0.8) / 3, one row, not two


def test_records_that_are_not_a_record_file_are_refused(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("[1, 2]")
    with pytest.raises(SystemExit, match="not a report.py --record file"):
        _report().main(["--records", str(bad), "--no-plots"])


def test_a_run_still_going_is_set_beside_qmix_in_sc2_at_the_same_steps(tmp_path):
    # 5m_vs_6m evaluated at 0.40M, 0.45M and 0.50M steps: the SMAC paper's QMIX in SC2 reads 0.21 at 0.4M and 0.32
    # at 0.5M (0.265 half way), so the same steps average (0.21 + 0.265 + 0.32) / 3 = 0.265
    run = tmp_path / "qmix" / "5m_vs_6m" / "seed0" / "sacred" / "1" / "1"
    run.mkdir(parents=True)
    (run / "info.json").write_text(json.dumps({"test_battle_won_mean": [0.5, 0.9, 0.8],
                                               "test_battle_won_mean_T": [400_000, 450_000, 500_000]}))
    assert _report().main(["--out", str(tmp_path), "--no-plots"]) == 0
    assert "| 5m_vs_6m | 0.733* (0.50M) [seed0] | 0.544 | 0.265 [seed0] |" in (tmp_path / "report.md").read_text()
    report = _report()
    assert report.sc2_qmix_at("5m_vs_6m", 0) == 0.0
    assert report.sc2_qmix_at("5m_vs_6m", 3_000_000) == 0.65  # its last point, at 2M
    assert report.sc2_qmix_at("3m", 500_000) is None  # no curve for 3m


def test_runs_with_other_epymarl_settings_are_kept_apart_and_labelled(tmp_path):
    runs, kept = tmp_path / "runs", tmp_path / "kept.json"
    _run(runs, "8m", "seed0", [0.2, 0.4, 0.6])
    _provenance(runs / "qmix" / "8m" / "seed0", "aaaa", "abc123")
    other = tmp_path / "gru"
    _run(other, "8m", "seed0", [0.0, 0.1, 0.2])
    _provenance(other / "qmix" / "8m" / "seed0", "aaaa", "abc123", " use_rnn=True")
    report = _report()
    assert report.main(["--out", str(runs), str(other), "--record", str(kept), "--no-plots"]) == 0
    settings = [r["settings"] for r in json.loads(kept.read_text())["runs"]]
    two_envs = ["runner=parallel", "batch_size_run=2"]
    assert settings == [two_envs, [*two_envs, "use_rnn=True"]]  # no paths, no routine settings
    # both read back from the record: two entries, the second labelled with the setting it adds
    table = tmp_path / "table"
    table.mkdir()
    assert report.main(["--out", str(table), "--records", str(kept), "--no-plots"]) == 0
    assert "| 8m | 0.400 [seed0]<br>0.100 [seed0 use_rnn=True] | 0.980 |" in (table / "report.md").read_text()
