"""The duel runner and the ``scripts`` / ``duel`` commands."""

from __future__ import annotations

import json

import numpy as np
import pytest

from smac_hard_gym.cli import main
from smac_hard_gym.envs.core import TwoPlayerCore
from smac_hard_gym.envs.duel import Idle, play, record_engine_episode, run_duel
from smac_hard_gym.maps import load_map
from smac_hard_gym.opponents import Script
from smac_hard_gym.smac.features import BLUE_WON


def test_two_idle_sides_draw_at_the_episode_limit():
    result = run_duel("3m", red="stop", blue="stop", episodes=3, seed=0)
    assert (result.red_wins, result.blue_wins, result.draws, result.timeouts) == (0, 0, 3, 3)
    assert result.mean_steps == 60  # 3m's episode limit


def test_base_beats_a_side_that_stops_and_counts_add_up():
    result = run_duel("3m", red="stop", blue="base", episodes=5, seed=0, batch_size=2)
    assert result.blue_wins == 5 and result.red_wins == 0 and result.draws == 0
    assert result.by_script == {"stop vs base": {"games": 5, "red_wins": 0, "blue_wins": 5, "draws": 0}}
    assert result.blue_win_rate == 1.0


def test_results_depend_on_the_seed_not_the_batch_size():
    # Episode e is a battle seeded seed + e whichever row plays it: every count and the mean length agree.
    runs = [run_duel("8m", red="weakest", blue="default", episodes=6, seed=4, batch_size=b).to_dict()
            for b in (1, 2, 4, 6)]
    for run in runs:
        assert run.pop("batch_size") in (1, 2, 4, 6)
    assert all(run == runs[0] for run in runs[1:])
    assert sum(c["games"] for c in runs[0]["by_script"].values()) == 6
    assert len(runs[0]["by_script"]) > 1  # the mixture drew more than one of 8m's pool scripts


def _env_episode(map_name, blue, seed):
    """One SMACHardEnv episode seeded ``seed`` in which red orders what the ``stop`` script orders (stop for the
    living, no-op for the dead); returns blue's units per step, the length, whether blue won and blue's script."""
    from smac_hard_gym.envs.gym_env import SMACHardEnv

    env = SMACHardEnv(map_name, opponent=blue)
    _, info = env.reset(seed=seed)
    core, n_red = env.core, env.n_agents
    frames = [core.state.x[0, n_red:].astype(np.float32)]
    steps, done = 0, False
    while not done:
        action = np.where(core.state.alive[0, :n_red], 1, 0)
        _, _, terminated, truncated, step_info = env.step(action)
        frames.append(core.state.x[0, n_red:].astype(np.float32))
        steps, done = steps + 1, terminated or truncated
    blue_won = terminated and step_info["dead_allies"] == n_red
    env.close()
    return np.array(frames), steps, blue_won, info["opponent"]


def test_a_duel_episode_plays_like_the_env_seeded_the_same():
    # The seeding rule: episode e of a duel seeded s is SMACHardEnv(map, opponent=blue).reset(seed=s + e) on
    # blue's side (same script drawn, same moves, same length), given red's orders.
    seed, episodes = 5, 4
    envs = [_env_episode("8m", "default", seed + e) for e in range(episodes)]
    for e, (frames, steps, _, name) in enumerate(envs):
        recording = record_engine_episode("8m", "stop", "default", seed=seed + e).to_episode()
        assert recording.opponent_at(0) == name and len(recording) == steps + 1
        np.testing.assert_array_equal(recording.units["x"][:, 8:], frames)
    result = run_duel("8m", red="stop", blue="default", episodes=episodes, seed=seed, batch_size=3)
    assert result.mean_steps == np.mean([steps for _, steps, _, _ in envs])
    assert result.blue_wins == sum(won for _, _, won, _ in envs)
    names = sorted({name for *_, name in envs})
    assert sorted(result.by_script) == [f"stop vs {name}" for name in names]
    assert len({steps for _, steps, _, _ in envs}) > 1  # episodes differ, so the check means something


def test_play_yields_every_episode_once_with_its_seed():
    spec = load_map("3m")
    core = TwoPlayerCore(spec, 2, opponent="base", red_script=Idle(), seed=7, encode_state=False)
    done = list(play(core, 7, 5))
    core.close()
    assert sorted(d.episode for d in done) == [0, 1, 2, 3, 4]
    assert all(d.seed == 7 + d.episode and d.red == "idle" and d.blue == "base" for d in done)
    assert all(d.outcome == BLUE_WON and not d.truncated for d in done)


def test_an_idle_side_gives_no_orders():
    result = run_duel("3m", red=None, blue="base", episodes=2, seed=0)
    assert result.red == "idle" and result.blue_wins == 2
    assert run_duel("3m", red="idle", blue="base", episodes=2, seed=0) == result


class _KillOwnFighters(Script):
    """Red test script: on the first step it removes its own units except the medivac (by writing the state)."""

    name = "medivac_only"

    def act(self, view, commands, active):
        st = view.state
        fighters = np.flatnonzero(st.utype[0, view.own] != st.utype[0, view.own][-1]) + view.own.start
        st.alive[:, fighters] = False
        st.health[:, fighters] = 0.0


def test_a_side_left_with_only_medivacs_has_lost():
    # SMAC: on MMM maps a side whose only survivors are medivacs loses.
    result = run_duel("MMM", red=_KillOwnFighters(), blue="stop", episodes=1, guard=False)
    assert result.blue_wins == 1 and result.mean_steps == 1


def test_bad_arguments_are_rejected():
    with pytest.raises(ValueError, match="episodes must be a positive int"):
        run_duel("3m", red="stop", blue="base", episodes=0)
    with pytest.raises(ValueError, match="batch_size must be a positive int"):
        run_duel("3m", red="stop", blue="base", episodes=2, batch_size=0)
    with pytest.raises(ValueError, match="unknown opponent 'nope'"):
        run_duel("3m", red="nope", blue="base", episodes=2)


def test_duel_command_prints_rates_and_writes_json(tmp_path, capsys):
    out = tmp_path / "duel.json"
    code = main(["duel", "--map", "3m", "--red", "stop", "--blue", "base", "--episodes", "3", "--seed", "1",
                 "--json", str(out), "--no-progress"])
    assert code == 0
    printed = capsys.readouterr().out
    assert "blue wins   100.0%" in printed and "red=stop blue=base episodes=3 seed=1" in printed
    doc = json.loads(out.read_text())
    assert doc["blue_wins"] + doc["red_wins"] + doc["draws"] == 3 and doc["blue_win_rate"] == 1.0


def test_scripts_command_lists_pools(capsys):
    assert main(["scripts", "--map", "6h_vs_8z"]) == 0
    printed = capsys.readouterr().out
    assert "default = chase, round_robin; blackbox = chase, round_robin" in printed
    assert main(["scripts", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["default"]) == 23 and doc["scripts"]["line_front"]["maps"][0] == "3m"


def test_duel_records_episodes_that_replay(tmp_path):
    from smac_hard_gym.cli import main
    from smac_hard_gym.render.recorder import load_episode

    assert main(["duel", "--map", "3m", "--red", "nearest", "--blue", "base", "--episodes", "2", "--no-progress",
                 "--record", str(tmp_path), "--record-episodes", "2"]) == 0
    files = sorted(tmp_path.glob("*.npz"))
    assert [f.name for f in files] == ["duel_3m_nearest_vs_base_0.npz", "duel_3m_nearest_vs_base_1.npz"]
    episode = load_episode(files[0])
    assert episode.metadata["red"] == "nearest" and episode.metadata["blue"] == "base"
    assert main(["replay", str(files[0]), "--out", str(tmp_path / "e.gif")]) == 0
    assert (tmp_path / "e.gif").stat().st_size > 0
