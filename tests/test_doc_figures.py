"""The figures README.md states for its quick-start command match a run of that command.

The README's "What to expect" sentence names the command and the figures it gives (final test win rate, per script
of the pool, first evaluation at >= 0.8); this test parses them out of README.md, runs the command (seed 0) through
the CLI in-process and compares, so the doc and the run cannot drift apart. It checks figures, not time: marked slow
(a 100k-step training run takes minutes), run with ``pytest -m slow tests/test_doc_figures.py``.
"""

import json
import re
import shlex
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
COMMAND = "smac-hard-gym train --map 3m --opponent default --timesteps 100000"


def readme_figures(text: str) -> dict:
    """The quick-start figures stated in the README: the command, the win rate, the per-script rates, the episodes
    and the first evaluation at >= 0.8 (None for "not reached")."""
    match = re.search(r"Measured with `(?P<command>smac-hard-gym train [^`]+)` \(seed (?P<seed>\d+)\): after "
                      r"(?P<steps>[\d,]+) steps a final test win rate of \*\*(?P<rate>\d\.\d{3})\*\* over "
                      r"(?P<episodes>\d+) test episodes \((?P<scripts>[^)]*)\); first evaluation at >= 0\.8: "
                      r"(?P<reached>not reached|[\d,]+ steps)", " ".join(text.split()))
    assert match, "README.md lost its 'Measured with `smac-hard-gym train ...` (seed N): ...' sentence"
    scripts = dict((name, float(rate)) for name, rate in re.findall(r"`(\w+)` (\d\.\d{3})", match["scripts"]))
    reached = None if match["reached"] == "not reached" else int(match["reached"].split()[0].replace(",", ""))
    return {"command": match["command"], "seed": int(match["seed"]), "steps": int(match["steps"].replace(",", "")),
            "rate": float(match["rate"]), "episodes": int(match["episodes"]), "scripts": scripts,
            "reached": reached}


def test_readme_states_the_quick_start_figures():
    text = README.read_text()
    figures = readme_figures(text)
    assert figures["command"] == COMMAND
    assert COMMAND in text.split("\n```", 2)[1]  # the command the README opens with is the one measured
    assert figures["scripts"] and 0.0 <= figures["rate"] <= 1.0


@pytest.mark.slow
def test_readme_quick_start_figures_match_a_run(tmp_path, capsys):
    from smac_hard_gym.cli import main

    figures = readme_figures(README.read_text())
    argv = shlex.split(figures["command"])[1:] + ["--seed", str(figures["seed"]), "--out", str(tmp_path / "run"),
                                                   "--no-progress"]
    assert main(argv) == 0
    capsys.readouterr()
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["timesteps"] == figures["steps"]
    assert summary["eval_episodes"] == figures["episodes"]
    assert round(summary["final_win_rate"], 3) == figures["rate"]
    assert {k: round(v, 3) for k, v in summary["final_per_opponent"].items()} == figures["scripts"]
    assert summary["first_timesteps_at_0.8"] == figures["reached"]
