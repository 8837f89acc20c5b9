"""benchmarks/epymarl/report.py on hand-made run folders: the final win rate of a run, runs moved aside on an earlier
engine left out, several folders in one report, and Spearman's correlation with the paper's QMIX column."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

REPORT = Path(__file__).resolve().parents[1] / "benchmarks" / "epymarl" / "report.py"


def _report():
    spec = importlib.util.spec_from_file_location("epymarl_report", REPORT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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
