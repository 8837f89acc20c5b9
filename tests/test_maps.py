"""The 23 SMAC maps as data, checked against SMAC's registry (docs/smac_interface.md §7, §9), and the loader's
errors."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from smac_hard_gym.maps import DATA_DIR, MapError, list_maps, load_map, load_map_file, parse_map, register_map

# SMAC's map registry (smac_maps.py via docs/smac_interface.md §7): agents, enemies, limit, races, type bits, map_type.
SMAC_REGISTRY = {
    "3m": (3, 3, 60, "T", "T", 0, "marines"),
    "8m": (8, 8, 120, "T", "T", 0, "marines"),
    "25m": (25, 25, 150, "T", "T", 0, "marines"),
    "5m_vs_6m": (5, 6, 70, "T", "T", 0, "marines"),
    "8m_vs_9m": (8, 9, 120, "T", "T", 0, "marines"),
    "10m_vs_11m": (10, 11, 150, "T", "T", 0, "marines"),
    "27m_vs_30m": (27, 30, 180, "T", "T", 0, "marines"),
    "MMM": (10, 10, 150, "T", "T", 3, "MMM"),
    "MMM2": (10, 12, 180, "T", "T", 3, "MMM"),
    "2s3z": (5, 5, 120, "P", "P", 2, "stalkers_and_zealots"),
    "3s5z": (8, 8, 150, "P", "P", 2, "stalkers_and_zealots"),
    "3s5z_vs_3s6z": (8, 9, 170, "P", "P", 2, "stalkers_and_zealots"),
    "3s_vs_3z": (3, 3, 150, "P", "P", 0, "stalkers"),
    "3s_vs_4z": (3, 4, 200, "P", "P", 0, "stalkers"),
    "3s_vs_5z": (3, 5, 250, "P", "P", 0, "stalkers"),
    "1c3s5z": (9, 9, 180, "P", "P", 3, "colossi_stalkers_zealots"),
    "2m_vs_1z": (2, 1, 150, "T", "P", 0, "marines"),
    "corridor": (6, 24, 400, "P", "Z", 0, "zealots"),
    "6h_vs_8z": (6, 8, 150, "Z", "P", 0, "hydralisks"),
    "2s_vs_1sc": (2, 1, 300, "P", "Z", 0, "stalkers"),
    "so_many_baneling": (7, 32, 100, "P", "Z", 0, "zealots"),
    "bane_vs_bane": (24, 24, 200, "Z", "Z", 2, "bane"),
    "2c_vs_64zg": (2, 64, 400, "P", "Z", 0, "colossus"),
}


def test_all_23_smac_maps_are_registered():
    assert set(SMAC_REGISTRY) <= set(list_maps())
    assert len(list(DATA_DIR.glob("*.json"))) == 23


@pytest.mark.parametrize("name", sorted(SMAC_REGISTRY))
def test_map_matches_smac_registry(name):
    spec = load_map(name)
    n_agents, n_enemies, limit, red_race, blue_race, bits, map_type = SMAC_REGISTRY[name]
    assert (spec.n_agents, spec.n_enemies, spec.episode_limit) == (n_agents, n_enemies, limit)
    assert (spec.red_race, spec.blue_race, spec.unit_type_bits, spec.map_type) == (red_race, blue_race, bits, map_type)
    assert all(u.endswith("_RL") for u in spec.red_unit_names)  # the learner plays SMAC's custom units
    assert not any(u.endswith("_RL") for u in spec.blue_unit_names)
    assert spec.pathable.shape == (32, 32)


def test_spawns_and_orders_follow_the_map_scripts():
    # docs/smac_interface.md §9.
    assert load_map("3m").red[0].spawn == (9.0, 16.0) and load_map("3m").blue[0].spawn == (23.0, 16.0)
    corridor = load_map("corridor")
    assert corridor.enemy_order.kind == "attack_move"
    assert corridor.enemy_order.point == pytest.approx((4.47, 4.33), abs=0.01)
    assert load_map("2s_vs_1sc").enemy_order.kind == "none"
    assert load_map("2c_vs_64zg").enemy_order.kind == "attack_units"
    assert load_map("2m_vs_1z").enemy_order.points == ((13.0, 12.0), (19.0, 12.0))
    # Enemy creation order: MMM marines, marauders, medivac; 1c3s5z colossus, stalkers, zealots.
    assert load_map("MMM").blue_unit_names == ["Marine"] * 7 + ["Marauder"] * 2 + ["Medivac"]
    assert load_map("1c3s5z").blue_unit_names == ["Colossus"] + ["Stalker"] * 3 + ["Zealot"] * 5


@pytest.mark.parametrize("name, rows", [
    # Pathable areas of docs/smac_interface.md §9 (cells (x, y) covering [x, x+1) x [y, y+1)).
    ("3m", {8: (0, 31), 23: (0, 31)}),
    ("2m_vs_1z", {6: (10, 21), 9: (8, 23), 15: (6, 25), 23: (8, 23), 25: (10, 21)}),
    ("corridor", {5: (2, 11), 12: (12, 13), 15: (14, 25), 20: (12, 29), 29: (20, 29)}),
])
def test_pathable_extent_of_rows_matches_the_documented_areas(name, rows):
    spec = load_map(name)
    for y, (x0, x1) in rows.items():
        xs = np.flatnonzero(spec.pathable[:, y])
        assert (xs.min(), xs.max()) == (x0, x1), (name, y)
    if name == "3m":
        assert not spec.pathable[:, :8].any() and not spec.pathable[:, 24:].any()


def _doc(name="3m") -> dict:
    return json.loads((DATA_DIR / f"{name}.json").read_text())


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d.pop("episode_limit"), "episode_limit"),
    (lambda d: d.update(episode_limit=0), "episode_limit"),
    (lambda d: d["races"].update(red="X"), "races.red"),
    (lambda d: d.update(map_type="tanks"), "map_type"),
    (lambda d: d["units"]["red"][0].update(unit="Battlecruiser"), "units.red[0].unit"),
    (lambda d: d["units"]["blue"][0].update(count=0), "units.blue[0].count"),
    (lambda d: d["units"]["red"][0].update(spawn=[40, 16]), "units.red[0].spawn"),
    (lambda d: d["units"]["red"][0].update(spawn=[9, 2]), "units.red[0].spawn"),  # on an unpathable cell
    (lambda d: d["enemy_order"].update(kind="charge"), "enemy_order.kind"),
    (lambda d: d["terrain"]["pathable"].pop(), "terrain.pathable"),
    (lambda d: d["terrain"]["cliff"].__setitem__(3, "x" * 32), "terrain.cliff[3]"),
])
def test_loader_names_the_bad_field(mutate, field):
    doc = _doc()
    mutate(doc)
    with pytest.raises(MapError, match=re.escape(f"field '{field}'")):
        parse_map(doc, "bad.json")


def test_unknown_map_lists_the_known_ones():
    with pytest.raises(MapError, match="unknown map 'nope'.*3m"):
        load_map("nope")
    with pytest.raises(MapError, match="does not exist"):
        load_map_file("/nonexistent/map.json")


def test_user_scenario_by_file_without_code_change(tmp_path, monkeypatch):
    # Any unit mix and counts: 4 hydralisks and a colossus against 10 zerglings and 2 banelings.
    doc = _doc("3s_vs_5z")
    doc["name"] = "my_mix"
    doc["units"] = {
        "red": [{"unit": "Hydralisk_RL", "count": 4, "spawn": [9, 16]}, {"unit": "Colossus_RL", "count": 1,
                                                                         "spawn": [8, 16]}],
        "blue": [{"unit": "Zergling", "count": 10, "spawn": [23, 16]}, {"unit": "Baneling", "count": 2,
                                                                         "spawn": [25, 16]}],
    }
    path = tmp_path / "my_mix.json"
    path.write_text(json.dumps(doc))
    spec = load_map(str(path))
    assert (spec.n_agents, spec.n_enemies) == (5, 12)
    from smac_hard_gym import maps

    monkeypatch.setattr(maps, "_USER_FILES", {})  # the registration below must not outlive this test
    monkeypatch.setenv("SMAC_HARD_GYM_MAP_PATH", str(tmp_path))
    assert "my_mix" in list_maps() and load_map("my_mix").n_enemies == 12
    register_map(path)
    from smac_hard_gym.engine import BattleEngine

    engine = BattleEngine("my_mix", batch_size=2)
    engine.step()
    assert engine.state.alive.shape == (2, 17)


def test_cli_lists_every_map():
    out = subprocess.run([sys.executable, "-m", "smac_hard_gym.cli", "maps"], capture_output=True, text=True,
                         check=True).stdout
    for name, (n_agents, n_enemies, limit, *_rest) in SMAC_REGISTRY.items():
        line = next(row for row in out.splitlines() if row.split()[0] == name)
        assert f"{n_agents} vs {n_enemies}" in " ".join(line.split()) and f"limit {limit}" in line
