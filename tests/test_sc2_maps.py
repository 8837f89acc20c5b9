"""``smac-hard-gym maps install`` / ``maps check`` and the SC2 folder checks, on fake map files written here.

A real .SC2Map is an MPQ archive: it starts with b"MPQ\\x1a" (or b"MPQ\\x1b" before a user-data header). No real map
file is used or written.
"""

from __future__ import annotations

import zipfile

import pytest

from smac_hard_gym.cli import main as cli
from smac_hard_gym.maps import SMAC_MAPS
from smac_hard_gym.sc2.errors import MapInstallError, MapNotInstalledError, Sc2NotFoundError
from smac_hard_gym.sc2.maps import find_sc2, install_maps

FAKE_MAP = b"MPQ\x1a" + b"\0" * 28 + b"fake map body"


@pytest.fixture
def game(tmp_path):
    root = tmp_path / "StarCraftII"
    (root / "Versions" / "Base75689").mkdir(parents=True)
    return root


def _source(folder, names, data=FAKE_MAP):
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        (folder / name).write_bytes(data)
    return folder


def test_install_from_a_folder_copies_known_maps_and_reports_the_rest(tmp_path, game):
    src = _source(tmp_path / "smac-hard" / "SMAC_HARD_maps", ["3m.SC2Map", "MMM.SC2Map", "readme.SC2Map"])
    (src / "nested").mkdir()
    (src / "nested" / "corridor.sc2map").write_bytes(FAKE_MAP)
    report = install_maps(tmp_path / "smac-hard", sc2path=game)
    target = game / "Maps" / "SMAC_HARD_maps"
    assert report.installed == ["3m", "MMM", "corridor"]
    assert sorted(p.name for p in target.iterdir()) == ["3m.SC2Map", "MMM.SC2Map", "corridor.SC2Map"]
    assert (target / "3m.SC2Map").read_bytes() == FAKE_MAP
    assert [reason for _, reason in report.skipped] == ["not one of the 23 SMAC map names"]
    assert any(line.startswith("still missing (20)") for line in report.lines())
    again = install_maps(src, sc2path=game)
    assert again.installed == [] and again.unchanged == ["3m", "MMM", "corridor"]
    assert find_sc2(game).installed_maps() == ["3m", "MMM", "corridor"]


def test_install_from_a_zip(tmp_path, game):
    archive = tmp_path / "maps.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for name in SMAC_MAPS:
            z.writestr(f"SMAC_HARD_maps/{name}.SC2Map", FAKE_MAP)
        z.writestr("SMAC_HARD_maps/../../evil.SC2Map", FAKE_MAP)  # never extracted by its own path
    report = install_maps(archive, sc2path=game)
    assert report.installed == list(SMAC_MAPS)
    assert not (tmp_path / "evil.SC2Map").exists()
    assert find_sc2(game).installed_maps() == list(SMAC_MAPS)


def test_bad_sources_install_nothing_and_say_why(tmp_path, game):
    with pytest.raises(MapInstallError, match="does not exist"):
        install_maps(tmp_path / "missing", sc2path=game)
    with pytest.raises(MapInstallError, match="no SMAC-HARD map file"):
        install_maps(_source(tmp_path / "other", ["Lobby.SC2Map"]), sc2path=game)
    html = _source(tmp_path / "html", ["3m.SC2Map"], data=b"<!DOCTYPE html>")
    _source(html, ["8m.SC2Map"])
    with pytest.raises(MapInstallError, match="3m.SC2Map is not an SC2 map"):
        install_maps(html, sc2path=game)
    twice = _source(tmp_path / "twice" / "a", ["3m.SC2Map"])
    _source(twice.parent / "b", ["3m.SC2Map"])
    with pytest.raises(MapInstallError, match="two files for map '3m'"):
        install_maps(twice.parent, sc2path=game)
    plain = tmp_path / "notes.txt"
    plain.write_text("x")
    with pytest.raises(MapInstallError, match="neither a folder nor a zip"):
        install_maps(plain, sc2path=game)
    assert not (game / "Maps").exists()


def test_missing_game_folder_names_the_path_and_its_source(tmp_path, monkeypatch):
    monkeypatch.setenv("SC2PATH", str(tmp_path / "nope"))
    with pytest.raises(Sc2NotFoundError, match=r"nope \(from the SC2PATH environment variable\) is not a folder"):
        find_sc2()
    (tmp_path / "nope").mkdir()
    with pytest.raises(Sc2NotFoundError, match="no Versions folder"):
        install_maps(tmp_path, sc2path=tmp_path / "nope")


def test_require_map_names_the_path_and_the_install_command(game):
    with pytest.raises(MapNotInstalledError) as info:
        find_sc2(game).require_map("3m")
    message = str(info.value)
    assert str(game / "Maps" / "SMAC_HARD_maps" / "3m.SC2Map") in message
    assert "smac-hard-gym maps install" in message


def test_cli_lists_installs_and_checks(tmp_path, game, capsys):
    assert cli(["maps"]) == 0
    assert capsys.readouterr().out.startswith("23 maps")
    assert cli(["maps", "check", "--sc2path", str(game)]) == 1
    assert "installed (0/23)" in capsys.readouterr().out
    src = _source(tmp_path / "src", [f"{name}.SC2Map" for name in SMAC_MAPS])
    assert cli(["maps", "install", str(src), "--sc2path", str(game)]) == 0
    assert "installed  2c_vs_64zg" in capsys.readouterr().out
    assert cli(["maps", "check", "--sc2path", str(game)]) == 0
    assert "installed (23/23)" in capsys.readouterr().out
    assert cli(["maps", "install", str(tmp_path / "none"), "--sc2path", str(game)]) == 1
    assert "does not exist" in capsys.readouterr().err
    assert cli(["maps", "install"]) == 2
    assert "needs SRC" in capsys.readouterr().err
