"""Rendering, episode recording and replay.

Pixel expectations use the world->pixel mapping written out here, independently of the renderer: x grows to the
right at ``scale`` pixels per world unit, y grows upwards, and the map sits below a header band, so world (x, y) lies
in pixel row ``header + (map_y - y) * scale``, column ``x * scale``. Unit radii and the baneling's splash radius are
the public values collected in docs/smac_interface.md §8 (marine 0.375, medivac 0.75, splash 2.2).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys

import numpy as np
import pytest

from smac_hard_gym.engine import CMD_ATTACK_MOVE, NO_UNIT, BattleEngine, Commands
from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.engine.units import UNITS
from smac_hard_gym.envs.duel import record_engine_episode
from smac_hard_gym.render import (
    BattleRenderer,
    EnvRenderer,
    EpisodeError,
    EpisodeRecorder,
    load_episode,
    write_video,
)
from smac_hard_gym.render import renderer as rmod

MAP_CELLS = 32  # every SMAC map is 32 x 32 cells
MARINE_RADIUS, MEDIVAC_RADIUS, BANELING_SPLASH = 0.375, 0.75, 2.2


def pixel(frame: np.ndarray, scale: int, x: float, y: float) -> np.ndarray:
    """The pixel covering world point (x, y)."""
    header = frame.shape[0] - MAP_CELLS * scale
    return frame[int(math.floor(header + (MAP_CELLS - y) * scale)), int(math.floor(x * scale))]


def clear_battle(engine: BattleEngine, b: int = 0) -> None:
    """Kill every unit and park it in the bottom-left corner, so a test places only the units it looks at."""
    for slot in range(engine.n_units):
        engine.place(b, slot, alive=False, x=1.0, y=1.0, fired_at=NO_UNIT, burst=False)


def slot_of(engine: BattleEngine, base: str, side: int, nth: int = 0) -> int:
    slots = [i for i in range(engine.n_units)
             if UNITS[engine.state.utype[0, i]].base == base and engine.state.side[0, i] == side]
    return slots[nth]


def count_color(frame: np.ndarray, color: tuple[int, int, int]) -> int:
    return int(np.all(frame == np.array(color, dtype=np.uint8), axis=-1).sum())


# ---------------------------------------------------------------------------------------------------------------
# Frames.


def test_frame_is_rgb_uint8_covering_the_map_below_a_header():
    engine = BattleEngine("3m", batch_size=2)
    for scale in (4, 10):
        frame = BattleRenderer(engine.spec, scale=scale).render(engine.state, battle=1, step=0)
        assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
        assert frame.shape[1] == MAP_CELLS * scale
        assert 0 < frame.shape[0] - MAP_CELLS * scale < 4 * scale + 20  # a header band, not a second map


def test_grid_tiles_battles_row_by_row():
    engine = BattleEngine("3m", batch_size=3)
    renderer = BattleRenderer("3m", scale=4)
    h, w, _ = renderer.frame_shape
    grid = renderer.render_grid(engine.state, battles=[0, 1, 2], cols=2)
    assert grid.shape == (2 * h + 2, 2 * w + 2, 3)  # 2 gap pixels between tiles
    np.testing.assert_array_equal(grid[h + 2:, :w], renderer.render(engine.state, 2, title="#2"))
    assert not grid[h + 2:, w + 2:].any()  # the unused fourth cell stays black


def test_units_are_discs_of_their_side_colour_at_their_world_position():
    engine = BattleEngine("3m")
    clear_battle(engine)
    engine.place(0, 0, alive=True, x=8.0, y=16.0)  # a red marine
    engine.place(0, 3, alive=True, x=24.0, y=12.5)  # a blue marine
    scale = 16
    frame = BattleRenderer("3m", scale=scale).render(engine.state)
    off = 0.6 * MARINE_RADIUS  # inside the disc, beside the centred type letter
    for (x, y), side in (((8.0, 16.0), RED), ((24.0, 12.5), BLUE)):
        for dx, dy in ((-off, 0.0), (off, 0.0), (0.0, -off)):
            np.testing.assert_array_equal(pixel(frame, scale, x + dx, y + dy), rmod.SIDE_RGB[side])
        # Just outside the radius (and below, away from the health bar) is ground again.
        assert tuple(pixel(frame, scale, x, y - 1.5 * MARINE_RADIUS)) not in rmod.SIDE_RGB.values()
    red, blue = pixel(frame, scale, 8.0 - off, 16.0).astype(int), pixel(frame, scale, 24.0 - off, 12.5).astype(int)
    assert red[0] > red[1] + 100 and red[0] > red[2] + 100  # learner red
    assert blue[2] > blue[0] + 100 and blue[2] > blue[1] + 50  # opponent blue


def test_unit_types_get_distinct_letters_and_bigger_units_bigger_discs():
    engine = BattleEngine("MMM")
    clear_battle(engine)
    marine, medivac = slot_of(engine, "marine", RED), slot_of(engine, "medivac", RED)
    engine.place(0, marine, alive=True, x=8.0, y=16.0)
    engine.place(0, medivac, alive=True, x=20.0, y=16.0)
    scale = 16
    frame = BattleRenderer("MMM", scale=scale).render(engine.state)
    red = rmod.SIDE_RGB[RED]
    # The medivac (radius 0.75) still shows red at 0.65 of its radius where a marine's disc (0.375) has ended.
    np.testing.assert_array_equal(pixel(frame, scale, 20.0, 16.0 - 0.65 * MEDIVAC_RADIUS), red)
    assert tuple(pixel(frame, scale, 8.0, 16.0 - 0.65 * MEDIVAC_RADIUS)) != red

    def letter(x: float, y: float, radius: float) -> np.ndarray:
        half = int(radius * scale * 0.7)
        r, c = pixel_index(frame, scale, x, y)
        return np.all(frame[r - half: r + half + 1, c - half: c + half + 1] == rmod.GLYPH_RGB, axis=-1)

    marine_letter, medivac_letter = letter(8.0, 16.0, MARINE_RADIUS), letter(20.0, 16.0, MEDIVAC_RADIUS)
    assert marine_letter.any() and medivac_letter.any()
    assert medivac_letter.sum() > marine_letter.sum()  # glyphs grow with the radius
    assert rmod.UNIT_GLYPHS["marine"] != rmod.UNIT_GLYPHS["medivac"]


def pixel_index(frame: np.ndarray, scale: int, x: float, y: float) -> tuple[int, int]:
    header = frame.shape[0] - MAP_CELLS * scale
    return int(math.floor(header + (MAP_CELLS - y) * scale)), int(math.floor(x * scale))


def test_terrain_shows_pathable_ground_and_brighter_high_ground():
    engine = BattleEngine("2c_vs_64zg")
    clear_battle(engine)
    spec, scale = engine.spec, 8
    frame = BattleRenderer(spec, scale=scale).render(engine.state)

    def inner_cells(pathable: bool, level: float) -> list[tuple[int, int]]:
        # Cells whose 3x3 neighbourhood shares their kind and level: no cliff outline, no unit.
        out = []
        for x in range(4, MAP_CELLS - 1):
            for y in range(4, MAP_CELLS - 1):
                block_p, block_c = spec.pathable[x - 1:x + 2, y - 1:y + 2], spec.cliff[x - 1:x + 2, y - 1:y + 2]
                if (block_p == pathable).all() and (block_c == level).all():
                    out.append((x, y))
        return out

    def brightness(cell: tuple[int, int]) -> int:
        return int(pixel(frame, scale, cell[0] + 0.5, cell[1] + 0.5).astype(int).sum())

    low, high, rock = inner_cells(True, 1.0), inner_cells(True, 2.0), inner_cells(False, 0.0)
    assert low and high and rock
    assert brightness(high[0]) > brightness(low[0]) > brightness(rock[0])
    assert len({brightness(c) for c in low}) == 1  # one level, one colour


def test_attack_lines_take_the_shooters_colour_and_heal_links_are_green():
    engine = BattleEngine("MMM")
    clear_battle(engine)
    medivac, red_marine = slot_of(engine, "medivac", RED), slot_of(engine, "marine", RED)
    blue_a, blue_b = slot_of(engine, "marine", BLUE, 0), slot_of(engine, "marine", BLUE, 1)
    for slot, (x, y) in ((medivac, (10.0, 8.0)), (red_marine, (10.0, 20.0)), (blue_a, (22.0, 20.0)),
                         (blue_b, (22.0, 8.0))):
        engine.place(0, slot, alive=True, x=x, y=y)
    scale = 16
    renderer = BattleRenderer("MMM", scale=scale)
    quiet = renderer.render(engine.state)
    assert count_color(quiet, rmod.HEAL_RGB) == 0 and count_color(quiet, rmod.ATTACK_RGB[RED]) == 0

    engine.place(0, medivac, fired_at=red_marine)  # heal link straight up x = 10
    engine.place(0, red_marine, fired_at=blue_a)  # red shot along y = 20
    engine.place(0, blue_b, fired_at=red_marine)  # blue shot on the diagonal
    frame = renderer.render(engine.state)
    np.testing.assert_array_equal(pixel(frame, scale, 10.0, 14.0), rmod.HEAL_RGB)
    np.testing.assert_array_equal(pixel(frame, scale, 16.0, 20.0), rmod.ATTACK_RGB[RED])
    r, c = pixel_index(frame, scale, 16.0, 14.0)  # the diagonal's midpoint, give or take a pixel
    assert np.all(frame[r - 1:r + 2, c - 1:c + 2] == rmod.ATTACK_RGB[BLUE], axis=-1).any()


def test_baneling_burst_covers_its_splash_radius():
    engine = BattleEngine("so_many_baneling")
    clear_battle(engine)
    bane = slot_of(engine, "baneling", BLUE)
    engine.place(0, bane, x=16.0, y=16.0)  # dead: a burst baneling destroys itself
    scale = 8
    renderer = BattleRenderer("so_many_baneling", scale=scale)
    before = renderer.render(engine.state)
    engine.place(0, bane, burst=True)
    after = renderer.render(engine.state)
    inside = pixel(after, scale, 16.0 + 0.5 * BANELING_SPLASH, 16.0).astype(int)
    assert inside[0] > 170 and inside[2] < 100 and (inside != pixel(before, scale, 17.1, 16.0)).any()
    for far in (16.0 + 1.3 * BANELING_SPLASH, 16.0 - 1.3 * BANELING_SPLASH):
        np.testing.assert_array_equal(pixel(after, scale, far, 16.0), pixel(before, scale, far, 16.0))


def test_health_and_shield_bars_shrink_with_damage():
    engine = BattleEngine("2s3z")
    clear_battle(engine)
    stalker = slot_of(engine, "stalker", RED)
    engine.place(0, stalker, alive=True, x=16.0, y=16.0)
    renderer = BattleRenderer("2s3z", scale=16)
    full = renderer.render(engine.state)
    engine.place(0, stalker, health=40.0, shield=20.0)  # of 80 and 80
    hurt = renderer.render(engine.state)
    for color in (rmod.HEALTH_RGB, rmod.SHIELD_RGB):
        assert count_color(full, color) > 0
    assert count_color(hurt, rmod.HEALTH_RGB) / count_color(full, rmod.HEALTH_RGB) == pytest.approx(0.5, abs=0.1)
    assert count_color(hurt, rmod.SHIELD_RGB) / count_color(full, rmod.SHIELD_RGB) == pytest.approx(0.25, abs=0.1)


def test_header_changes_with_step_and_opponent_but_the_map_does_not():
    engine = BattleEngine("3m")
    renderer = BattleRenderer("3m", scale=8)
    a = renderer.render(engine.state, step=3, opponent_name="base")
    b = renderer.render(engine.state, step=4, opponent_name="base")
    c = renderer.render(engine.state, step=3, opponent_name="kite")
    header = a.shape[0] - MAP_CELLS * 8
    assert (a[:header] != b[:header]).any() and (a[:header] != c[:header]).any()
    np.testing.assert_array_equal(a[header:], b[header:])
    assert count_color(a[:header], rmod.TEXT_RGB) > 0


def test_bad_renderer_arguments_are_named():
    engine = BattleEngine("3m")
    with pytest.raises(ValueError, match="scale"):
        BattleRenderer("3m", scale=0)
    with pytest.raises(ValueError, match="battle must be an int in 0..0"):
        BattleRenderer("3m", scale=2).render(engine.state, battle=1)
    with pytest.raises(ValueError, match="render_mode"):
        EnvRenderer("3m", "video")


# ---------------------------------------------------------------------------------------------------------------
# Recording and replay.


def _play_and_record(tmp_path):
    """Attack-move both sides at each other; record every step and keep the frames drawn live."""
    engine = BattleEngine("3m")
    renderer = BattleRenderer(engine.spec, scale=6)
    recorder = EpisodeRecorder(engine.spec, step_mul=engine.step_mul, metadata={"seed": np.int64(7)})
    commands = Commands.empty(1, engine.n_units)
    live, rewards = [renderer.render(engine.state, 0, 0, "base")], []
    recorder.capture(engine.state, 0, step=0, opponent="base")
    for t in range(1, 16):
        commands.clear()
        if t == 1:
            commands.kind[0, :] = CMD_ATTACK_MOVE
            commands.x[0, :3], commands.y[0, :3] = 23.0, 16.0
            commands.x[0, 3:], commands.y[0, 3:] = 9.0, 16.0
        engine.step(commands)
        rewards.append([0.5 * t, -0.5 * t])
        recorder.capture(engine.state, 0, step=t, rewards=rewards[-1], actions=commands, opponent="base")
        live.append(renderer.render(engine.state, 0, t, "base"))
    return recorder.save(tmp_path / "episode"), live, rewards


def test_record_then_replay_reproduces_the_live_frames(tmp_path):
    path, live, rewards = _play_and_record(tmp_path)
    assert path.name == "episode.npz"
    episode = load_episode(path)
    assert len(episode) == len(live) == 16
    assert (episode.units["fired_at"] >= 0).any()  # the battle had shots to draw
    replayed = list(episode.render(scale=6))
    for t, (a, b) in enumerate(zip(live, replayed, strict=True)):
        np.testing.assert_array_equal(a, b, err_msg=f"frame {t}")
    assert episode.map_name == "3m" and episode.n_red == 3 and episode.n_blue == 3
    assert episode.opponent_at(0) == "base" and episode.metadata == {"seed": 7}
    np.testing.assert_array_equal(episode.step, np.arange(16))
    assert np.isnan(episode.rewards[0]).all()
    np.testing.assert_allclose(episode.rewards[1:], rewards)
    kinds = episode.actions["commands.kind"]
    assert kinds.shape == (16, 6) and (kinds[0] == -1).all()
    assert (kinds[1] == CMD_ATTACK_MOVE).all() and (kinds[2:] == 0).all()
    np.testing.assert_array_equal(episode.actions["commands.x"][1], [23, 23, 23, 9, 9, 9])


def test_replay_command_writes_one_gif_frame_per_step(tmp_path, capsys):
    from PIL import Image

    from smac_hard_gym import cli
    from smac_hard_gym.commands import replay

    path, live, _ = _play_and_record(tmp_path)
    parser = argparse.ArgumentParser()
    replay.add_arguments(parser)
    out = tmp_path / "battle.gif"
    assert cli.main(["replay", str(path), "--out", str(out), "--scale", "6"]) == 0
    with Image.open(out) as gif:
        assert gif.n_frames == len(live)
        assert gif.size == (live[0].shape[1], live[0].shape[0])
    assert replay.run(parser.parse_args([str(tmp_path / "missing.npz")])) == 2
    assert "missing.npz" in capsys.readouterr().err
    assert replay.run(parser.parse_args([str(path), "--out", str(tmp_path / "battle.avi")])) == 2
    assert ".gif, .mp4" in capsys.readouterr().err


def test_record_engine_episode_plays_to_the_end():
    # Red's *_RL marines are passive: left idle they never shoot back, so the base opponent must win.
    recorder = record_engine_episode("3m", None, "base", seed=1)
    episode = recorder.to_episode()
    assert recorder.metadata["winner"] == "blue" and recorder.metadata["blue"] == "base"
    assert not episode.units["alive"][-1, :3].any() and episode.units["alive"][-1, 3:].all()
    assert 2 <= len(episode) <= 61  # 3m's limit is 60 steps
    assert (episode.units["fired_at"][1:, :3] == NO_UNIT).all()
    assert episode.opponent_at(len(episode) - 1) == "base"


def test_episode_errors_name_the_problem(tmp_path):
    engine = BattleEngine("3m")
    with pytest.raises(FileNotFoundError, match="nope.npz"):
        load_episode(tmp_path / "nope.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(EpisodeError, match="not an episode file"):
        load_episode(tmp_path / "other.npz")
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(EpisodeError, match="not an episode file"):
        load_episode(tmp_path / "text.npz")
    recorder = EpisodeRecorder("3m")
    with pytest.raises(EpisodeError, match="nothing captured"):
        recorder.save(tmp_path / "empty.npz")
    with pytest.raises(EpisodeError, match="battle must be an int in 0..0"):
        recorder.capture(engine.state, battle=2)
    recorder.capture(engine.state, rewards=[1.0, 2.0])
    with pytest.raises(EpisodeError, match="rewards must keep one length"):
        recorder.capture(engine.state, rewards=1.0)
    with pytest.raises(EpisodeError, match="units changed"):
        recorder.capture(BattleEngine("8m").state)


def test_video_writer_makes_gifs_and_names_bad_suffixes_and_missing_ffmpeg(tmp_path, monkeypatch):
    from PIL import Image

    frames = [np.full((10, 12, 3), v, dtype=np.uint8) for v in (0, 120, 250)]
    with Image.open(write_video(frames, tmp_path / "a.gif", fps=4)) as gif:
        assert gif.n_frames == 3 and gif.size == (12, 10)
    with pytest.raises(ValueError, match=".gif, .mp4"):
        write_video(frames, tmp_path / "a.webm")
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # as if the package were not installed
    with pytest.raises(ImportError, match="imageio-ffmpeg"):
        write_video(frames, tmp_path / "a.mp4")


def test_human_mode_shows_the_rgb_frame(monkeypatch):
    matplotlib = pytest.importorskip("matplotlib")  # in the dev and render extras
    matplotlib.use("Agg", force=True)
    engine = BattleEngine("3m")
    shown = EnvRenderer("3m", "human", scale=4)
    assert shown.render(engine.state, 0, 0, "base") is None
    expected = EnvRenderer("3m", "rgb_array", scale=4).render(engine.state, 0, 0, "base")
    np.testing.assert_array_equal(np.asarray(shown.viewer._image.get_array()), expected)
    shown.close()
    shown.close()
    assert not shown.viewer.is_open


def test_rendering_is_not_on_the_engine_step_path():
    code = (
        "import sys\n"
        "import smac_hard_gym, smac_hard_gym.opponents\n"
        "from smac_hard_gym.backend import make_backend\n"
        "from smac_hard_gym.engine import Commands\n"
        "b = make_backend('native', '3m', batch_size=2)\n"
        "import numpy as np\n"
        "for _ in range(3): b.step(Commands.empty(2, 6), np.ones(2, bool))\n"
        "print(sorted(m for m in sys.modules if m.startswith('smac_hard_gym.render')\n"
        "             or m.split('.')[0] in ('PIL', 'matplotlib', 'imageio_ffmpeg')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


# ---------------------------------------------------------------------------------------------------------------
# Malformed recordings: every one gives the CLI's one-line error (exit 2), never a traceback.


def _arrays(path):
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def _malformed(tmp_path, good):
    """(name, writer) pairs: each writes one malformed recording to the path it is given."""
    def edit(**changes):
        def write(path):
            arrays = _arrays(good)
            for key, change in changes.items():
                arrays[key] = change(arrays[key])
            with open(path, "wb") as handle:
                np.savez(handle, **arrays)
        return write

    def at(value, dtype=np.float64):
        def change(a):
            a = a.astype(dtype)
            a[3, 1] = value
            return a
        return change

    data = good.read_bytes()
    return [
        ("empty", lambda p: p.write_bytes(b"")),
        ("random bytes", lambda p: p.write_bytes(np.random.default_rng(0).bytes(4096))),
        ("truncated", lambda p: p.write_bytes(data[: len(data) // 2])),
        ("zip of junk", lambda p: p.write_bytes(data[:200] + b"\0" * 300)),
        ("huge position", edit(x=at(1e300))),
        ("nan position", edit(y=at(np.nan, np.float32))),
        ("inf position", edit(x=at(np.inf, np.float32))),
        ("outside the map", edit(x=at(1e6, np.float32))),
        ("negative health", edit(health=at(-5.0, np.float32))),
        ("nan health", edit(health=at(np.nan, np.float32))),
        ("huge shield", edit(shield=at(1e30))),
        ("bad fired_at", edit(fired_at=at(99, np.int16))),
        ("wrong shape", edit(x=lambda a: a[:, :2])),
        ("wrong side", edit(side=lambda a: np.full_like(a, 7))),
        ("string positions", edit(x=lambda a: a.astype(str))),
        ("bad terrain", edit(pathable=lambda a: a[:3])),
        ("no frames", edit(**{k: (lambda a: a[:0]) for k in ("loop", "step", "opponent", "x", "y", "health",
                                                             "shield", "energy", "alive", "burst", "fired_at",
                                                             "rewards", "commands.kind", "commands.target",
                                                             "commands.x", "commands.y")})),
        ("bad opponent index", edit(opponent=lambda a: np.full_like(a, 40))),
        ("bad meta", edit(meta=lambda a: np.frombuffer(b'{"format": "smac-hard-gym-episode", "version": 1, '
                                                      b'"map": 3, "size": [1e300, -1]}', dtype=np.uint8))),
        ("meta not json", edit(meta=lambda a: np.frombuffer(b"\xff\xfe{", dtype=np.uint8))),
    ]


def test_replay_of_malformed_files_is_one_clean_line(tmp_path, capsys):
    from smac_hard_gym import cli

    good, _, _ = _play_and_record(tmp_path)
    for name, write in _malformed(tmp_path, good):
        path = tmp_path / f"bad-{name.replace(' ', '_')}.npz"
        write(path)
        with pytest.raises(EpisodeError):
            load_episode(path)
        out = tmp_path / f"bad-{name.replace(' ', '_')}.gif"
        assert cli.main(["replay", str(path), "--out", str(out)]) == 2, name
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("smac-hard-gym replay: error: "), (name, err)
        assert "Traceback" not in err and str(path) in err, (name, err)
        assert not out.exists(), name
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_recording_save_is_atomic(tmp_path, monkeypatch):
    good, _, _ = _play_and_record(tmp_path)
    before = good.read_bytes()
    recorder = EpisodeRecorder("3m")
    recorder.capture(BattleEngine("3m").state)

    def half_then_fail(file, **arrays):
        file.write(b"PK\x03\x04 half an archive")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez_compressed", half_then_fail)
    with pytest.raises(OSError, match="disk full"):
        recorder.save(good)
    assert good.read_bytes() == before  # the old recording, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == [good.name]  # no temporary file left
    monkeypatch.undo()
    recorder.save(good)
    assert len(load_episode(good)) == 1 and sorted(p.name for p in tmp_path.iterdir()) == [good.name]


def test_replay_video_is_written_atomically(tmp_path, monkeypatch):
    from smac_hard_gym import cli
    from smac_hard_gym.render import video

    good, _, _ = _play_and_record(tmp_path)
    out = tmp_path / "battle.gif"
    out.write_bytes(b"old video")

    def broken(frames, path, fps):
        path.write_bytes(b"GIF89a half")
        raise ValueError("encoder died")

    monkeypatch.setitem(video._WRITERS, ".gif", broken)
    assert cli.main(["replay", str(good), "--out", str(out)]) == 2
    assert out.read_bytes() == b"old video"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([good.name, out.name])
