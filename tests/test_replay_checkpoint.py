"""benchmarks/epymarl/replay_checkpoint.py's trace of one game, with its fixed script (no EPyMARL needed)."""

from __future__ import annotations

import json
import re

from script_helpers import load_benchmark


def _replay():
    return load_benchmark("epymarl/replay_checkpoint.py", "replay_checkpoint")


def test_trace_prints_every_step_of_one_game(tmp_path, capsys):
    config = tmp_path / "config.json"  # the part of a sacred config.json the replay reads
    config.write_text(json.dumps({"env_args": {"map_name": "3m"}}))
    assert _replay().main(["--config", str(config), "--policy", "focus_lowest", "--trace", "7"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1] in ("won: True", "won: False")
    steps = lines[:-1]
    assert [int(line.split()[1]) for line in steps] == list(range(len(steps)))
    shots = []
    for line in steps:
        cells = line.split(" | ")[1:]
        assert [int(c.split(":")[0]) for c in cells] == list(range(6))  # 3 marines a side, the learner's first
        actions = [int(a) for a in line.split(" | ")[0].split()[3:]]
        for k, cell in enumerate(cells[:3]):
            shot = re.search(r"shot (-?\d+)", cell)
            if shot and int(shot.group(1)) >= 0:
                shots.append(int(shot.group(1)))
                assert actions[k] >= 6  # SMAC's attack actions: 6 + enemy
    assert shots and all(3 <= s <= 5 for s in shots)  # the learner shoots enemy slots only
