"""SMAC observation and state layouts: sizes on every map, and exact vectors for hand-built battles.

Expected values come from SMAC's definitions (docs/smac_interface.md §3-§4), worked out by hand here.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.engine.units import UNITS
from smac_hard_gym.maps import SMAC_MAPS, load_map
from smac_hard_gym.smac.actions import available_actions
from smac_hard_gym.smac.features import SideFeatures, SmacOptions

# docs/smac_interface.md §4: default-config sizes (n_actions, obs, state).
SMAC_SIZES = {
    "3m": (9, 30, 48), "8m": (14, 80, 168), "25m": (31, 250, 950), "5m_vs_6m": (12, 55, 98),
    "8m_vs_9m": (15, 85, 179), "10m_vs_11m": (17, 105, 243), "27m_vs_30m": (36, 285, 1170),
    "MMM": (16, 160, 290), "MMM2": (18, 176, 322), "2s3z": (11, 80, 120), "3s5z": (14, 128, 216),
    "3s5z_vs_3s6z": (15, 136, 230), "3s_vs_3z": (9, 36, 54), "3s_vs_4z": (10, 42, 61), "3s_vs_5z": (11, 48, 68),
    "1c3s5z": (15, 162, 270), "2m_vs_1z": (7, 16, 26), "corridor": (30, 156, 282), "6h_vs_8z": (14, 78, 140),
    "2s_vs_1sc": (7, 17, 27), "so_many_baneling": (38, 202, 397), "bane_vs_bane": (30, 336, 984),
    "2c_vs_64zg": (70, 332, 342),
}

# docs/smac_interface.md §7: agents, enemies, races and unit_type_bits, written out independently of the map files.
SMAC_REGISTRY = {
    "3m": (3, 3, "T", "T", 0), "8m": (8, 8, "T", "T", 0), "25m": (25, 25, "T", "T", 0),
    "5m_vs_6m": (5, 6, "T", "T", 0), "8m_vs_9m": (8, 9, "T", "T", 0), "10m_vs_11m": (10, 11, "T", "T", 0),
    "27m_vs_30m": (27, 30, "T", "T", 0), "MMM": (10, 10, "T", "T", 3), "MMM2": (10, 12, "T", "T", 3),
    "2s3z": (5, 5, "P", "P", 2), "3s5z": (8, 8, "P", "P", 2), "3s5z_vs_3s6z": (8, 9, "P", "P", 2),
    "3s_vs_3z": (3, 3, "P", "P", 0), "3s_vs_4z": (3, 4, "P", "P", 0), "3s_vs_5z": (3, 5, "P", "P", 0),
    "1c3s5z": (9, 9, "P", "P", 3), "2m_vs_1z": (2, 1, "T", "P", 0), "corridor": (6, 24, "P", "Z", 0),
    "6h_vs_8z": (6, 8, "Z", "P", 0), "2s_vs_1sc": (2, 1, "P", "Z", 0), "so_many_baneling": (7, 32, "P", "Z", 0),
    "bane_vs_bane": (24, 24, "Z", "Z", 2), "2c_vs_64zg": (2, 64, "P", "Z", 0),
}

OBS_FLAGS = ("obs_all_health", "obs_own_health", "obs_last_action", "obs_pathing_grid", "obs_terrain_height",
             "obs_timestep_number", "state_last_action", "state_timestep_number", "obs_instead_of_state")


def formula_sizes(n_agents, n_enemies, ally_race, enemy_race, bits, o):
    """obs and state sizes from docs/smac_interface.md §3/§4 (own block counting the timestep slot once)."""
    n_actions = 6 + n_enemies
    sa, se = int(ally_race == "P"), int(enemy_race == "P")
    own_health = o["obs_all_health"] or o["obs_own_health"]
    move = 4 + 8 * o["obs_pathing_grid"] + 9 * o["obs_terrain_height"]
    nf_en = 4 + bits + o["obs_all_health"] * (1 + se)
    nf_al = 4 + bits + o["obs_all_health"] * (1 + sa) + o["obs_last_action"] * n_actions
    own = bits + own_health * (1 + sa) + o["obs_timestep_number"]
    obs = move + n_enemies * nf_en + (n_agents - 1) * nf_al + own
    if o["obs_instead_of_state"]:
        state = n_agents * obs
    else:
        state = (n_agents * (4 + sa + bits) + n_enemies * (3 + se + bits)
                 + o["state_last_action"] * n_agents * n_actions + o["state_timestep_number"])
    return n_actions, obs, state


@pytest.mark.parametrize("name", SMAC_MAPS)
def test_default_sizes_match_smac_table(name):
    feats = SideFeatures(load_map(name), RED)
    # The features' slot types are the engine's slot layout.
    np.testing.assert_array_equal(feats.utype, BattleEngine(name).state.utype[0])
    assert (feats.n_actions, feats.obs_size, feats.state_size) == SMAC_SIZES[name]
    assert len(feats.obs_feature_names()) == feats.obs_size
    assert len(feats.state_feature_names()) == feats.state_size


# Eight option combinations per map: all off, all on, and six mixed (fixed, so the test is reproducible).
_COMBOS = [dict.fromkeys(OBS_FLAGS, False), dict.fromkeys(OBS_FLAGS, True)] + [
    dict(zip(OBS_FLAGS, bits, strict=True)) for bits in itertools.islice(
        (b for b in itertools.product([False, True], repeat=len(OBS_FLAGS)) if sum(b) in (3, 5)), 0, 120, 20)
]


@pytest.mark.parametrize("name", SMAC_MAPS)
def test_sizes_for_option_combinations_both_sides(name):
    n_agents, n_enemies, a_race, e_race, bits = SMAC_REGISTRY[name]
    engine = BattleEngine(name, batch_size=1)
    for combo in _COMBOS:
        options = SmacOptions(**combo)
        for side, (n, m, own_race, other_race) in ((RED, (n_agents, n_enemies, a_race, e_race)),
                                                   (BLUE, (n_enemies, n_agents, e_race, a_race))):
            feats = SideFeatures(engine.spec, side, options)
            expected = formula_sizes(n, m, own_race, other_race, bits, combo)
            assert (feats.n_actions, feats.obs_size, feats.state_size) == expected, (side, combo)
            # The arrays really have these lengths (SMAC's obs is one longer with the timestep: not here).
            avail = available_actions(feats, engine.state)
            last = np.full((1, n), -1)
            step = np.zeros(1, dtype=np.int64)
            obs = feats.observations(engine.state, avail, last, step)
            state = feats.global_state(engine.state, last, step, obs=obs)
            assert obs.shape == (1, n, expected[1]) and state.shape == (1, expected[2])
            assert obs.dtype == np.float32 and state.dtype == np.float32


# ---------------------------------------------------------------------------------------------------------------
# Hand-built 3m battle.


@pytest.fixture
def marines():
    """3m with hand-placed units (red slots 0-2, blue slots 3-5)."""
    engine = BattleEngine("3m", batch_size=1)
    place = engine.place
    place(0, 0, x=10.0, y=16.0, health=45.0, cooldown=7.5)
    place(0, 1, x=13.0, y=16.0, health=30.0)
    place(0, 2, x=19.5, y=16.0)  # 9.5 from agent 0: out of its sight
    place(0, 3, x=14.0, y=19.0, health=15.0)  # 5 from agent 0 (3-4-5 triangle)
    place(0, 4, x=16.0, y=16.0)  # exactly 6 from agent 0: still attackable
    place(0, 5, x=19.0, y=16.0)  # exactly 9 from agent 0: not seen (sight is strict)
    return engine


def _features(engine, side=RED, **options):
    feats = SideFeatures(engine.spec, side, SmacOptions(**options))
    avail = available_actions(feats, engine.state)
    return feats, avail


def test_marine_observation_matches_the_hand_computed_vector(marines):
    feats, avail = _features(marines)
    obs = feats.observations(marines.state, avail, np.full((1, 3), -1), np.zeros(1, dtype=np.int64))[0]
    expected_agent0 = [
        1, 1, 1, 1,  # can move N, S, E, W
        1, 5 / 9, 4 / 9, 3 / 9, 15 / 45,  # enemy 0: attackable, distance, dx, dy, health
        1, 6 / 9, 6 / 9, 0, 1,  # enemy 1 at exactly 6
        0, 0, 0, 0, 0,  # enemy 2 at exactly 9: unseen
        1, 3 / 9, 3 / 9, 0, 30 / 45,  # ally 1
        0, 0, 0, 0, 0,  # ally 2 out of sight
        1,  # own health
    ]
    np.testing.assert_allclose(obs[0], expected_agent0, rtol=1e-6, atol=1e-7)
    d0 = math.hypot(1, 3)
    expected_agent1 = [
        1, 1, 1, 1,
        1, d0 / 9, 1 / 9, 3 / 9, 15 / 45,
        1, 3 / 9, 3 / 9, 0, 1,
        1, 6 / 9, 6 / 9, 0, 1,  # enemy 2 is exactly 6 away from agent 1
        1, 3 / 9, -3 / 9, 0, 1,  # ally 0 (agent 1 skips itself)
        1, 6.5 / 9, 6.5 / 9, 0, 1,  # ally 2
        30 / 45,
    ]
    np.testing.assert_allclose(obs[1], expected_agent1, rtol=1e-6, atol=1e-7)


def test_marine_state_matches_the_hand_computed_vector(marines):
    feats, _ = _features(marines, state_timestep_number=True)
    last = np.array([[1, 6, 2]])
    state = feats.global_state(marines.state, last, np.array([6]))[0]
    ally_rows = [
        [1, 7.5 / 15, (10 - 16) / 32, 0],  # health, cooldown / 15 (marine), rel_x, rel_y
        [30 / 45, 0, (13 - 16) / 32, 0],
        [1, 0, (19.5 - 16) / 32, 0],
    ]
    enemy_rows = [[15 / 45, (14 - 16) / 32, 3 / 32], [1, 0, 0], [1, 3 / 32, 0]]
    last_onehot = np.zeros((3, 9))
    last_onehot[0, 1] = last_onehot[1, 6] = last_onehot[2, 2] = 1
    expected = np.concatenate([np.ravel(ally_rows), np.ravel(enemy_rows), last_onehot.ravel(), [6 / 60]])
    np.testing.assert_allclose(state, expected, rtol=1e-6, atol=1e-7)


def test_dead_agent_observation_is_zero_but_keeps_timestep(marines):
    marines.place(0, 1, alive=False, health=0.0)
    feats, avail = _features(marines, obs_timestep_number=True, obs_last_action=True)
    obs = feats.observations(marines.state, avail, np.array([[2, 0, 3]]), np.array([15]))[0]
    assert obs.shape[1] == feats.obs_size
    np.testing.assert_array_equal(obs[1, :-1], 0.0)
    assert obs[1, -1] == pytest.approx(15 / 60)
    assert obs[0, -1] == pytest.approx(15 / 60)
    # Agent 0 no longer sees ally 1 (dead): that row is zero, ally 2 row is also out of sight.
    ally0 = feats.ally_offset
    np.testing.assert_array_equal(obs[0, ally0:feats.own_offset], 0.0)
    state = feats.global_state(marines.state, np.array([[2, 0, 3]]), np.array([15]))[0]
    np.testing.assert_array_equal(state[4:8], 0.0)  # the dead unit's state row


def test_last_action_in_ally_rows(marines):
    feats, avail = _features(marines, obs_last_action=True)
    obs = feats.observations(marines.state, avail, np.array([[1, 7, 4]]), np.zeros(1, dtype=np.int64))[0]
    nf_al = 5 + 9
    row = obs[0, feats.ally_offset:feats.ally_offset + nf_al]  # agent 0 sees ally 1, whose last action was 7
    expected = np.zeros(nf_al)
    expected[:5] = [1, 3 / 9, 3 / 9, 0, 30 / 45]
    expected[5 + 7] = 1
    np.testing.assert_allclose(row, expected, rtol=1e-6)
    hidden = obs[0, feats.ally_offset + nf_al:feats.own_offset]  # ally 2 unseen: its last action hidden too
    np.testing.assert_array_equal(hidden, 0.0)


def test_health_options_drop_or_keep_the_health_columns(marines):
    feats, avail = _features(marines, obs_all_health=False, obs_own_health=False)
    obs = feats.observations(marines.state, avail, np.full((1, 3), -1), np.zeros(1, dtype=np.int64))[0]
    assert feats.obs_size == 4 + 3 * 4 + 2 * 4 + 0
    np.testing.assert_allclose(obs[0, 4:8], [1, 5 / 9, 4 / 9, 3 / 9], rtol=1e-6)
    feats, avail = _features(marines, obs_all_health=False, obs_own_health=True)
    obs = feats.observations(marines.state, avail, np.full((1, 3), -1), np.zeros(1, dtype=np.int64))[0]
    assert obs[1, -1] == pytest.approx(30 / 45)


def test_pathing_and_height_features():
    engine = BattleEngine("3m", batch_size=1)
    engine.place(0, 0, x=10.5, y=9.5)  # strip y 8..23: cells below y=8 are unpathable
    engine.place(0, 1, x=1.5, y=16.0)  # next to the west edge
    feats, avail = _features(engine, obs_pathing_grid=True, obs_terrain_height=True)
    obs = feats.observations(engine.state, avail, np.full((1, 3), -1), np.zeros(1, dtype=np.int64))[0]
    # Points (10,13) (10,5) (14,9) (6,9) (12,11) (8,7) (12,7) (8,11).
    np.testing.assert_array_equal(obs[0, 4:12], [1, 0, 1, 1, 1, 0, 0, 1])
    # (1,20) (1,12) (5,16) (-3,16)->outside=1 (3,18) (-1,14)->1 (3,14) (-1,18)->1.
    np.testing.assert_array_equal(obs[1, 4:12], [1, 1, 1, 1, 1, 1, 1, 1])
    # Heights: SMAC reads the SC2 height byte / 255, and python-sc2 maps z = -16 + 32 * byte / 255, so a
    # platform at z = 8 (cliff level 1, docs/smac_interface.md §9) reads 0.75. Cell (10, 5) is the lower void (level 0).
    cells = [(10, 13), (10, 5), (14, 9), (6, 9), (12, 11), (8, 7), (12, 7), (8, 11), (10, 9)]
    levels = [engine.spec.cliff[c] for c in cells]
    assert levels == [1, 0, 1, 1, 1, 1, 1, 1, 1]
    heights = obs[0, 12:21]
    np.testing.assert_allclose(np.delete(heights, 1), 0.75, rtol=1e-6)
    assert heights[1] < 0.75
    assert obs[1, 12 + 3] == 1.0


# ---------------------------------------------------------------------------------------------------------------
# Shields, unit types, medivacs.


def test_stalkers_and_zealots_types_and_shields():
    engine = BattleEngine("2s3z", batch_size=1)
    st = engine.state
    # Red slots: stalkers 0-1, zealots 2-4; blue slots 5-9: stalkers 5-6, zealots 7-9.
    bases = [UNITS[t].base for t in st.utype[0]]
    assert bases == ["stalker"] * 2 + ["zealot"] * 3 + ["stalker"] * 2 + ["zealot"] * 3
    engine.place(0, 0, x=10.0, y=16.0, health=40.0, shield=20.0)
    engine.place(0, 2, x=10.0, y=18.0, health=50.0, shield=25.0)  # a zealot ally 2 above
    engine.place(0, 5, x=14.0, y=16.0, health=80.0, shield=40.0)  # enemy stalker 4 east
    engine.place(0, 7, x=10.0, y=12.0, health=100.0, shield=10.0)  # enemy zealot 4 south
    for slot, x in ((1, 3.0), (3, 3.0), (4, 3.0), (6, 30.0), (8, 30.0), (9, 30.0)):
        engine.place(0, slot, x=x, y=23.0)  # everyone else out of sight
    feats, avail = _features(engine)
    obs = feats.observations(st, avail, np.full((1, 5), -1), np.zeros(1, dtype=np.int64))[0]
    agent = obs[0]
    nf = 4 + 2 + 2  # dist features, health + shield, 2 type bits
    enemy = agent[4:4 + 5 * nf].reshape(5, nf)
    # SMAC's enemy one-hot on stalkers_and_zealots: zealot 0, stalker 1.
    np.testing.assert_allclose(enemy[0], [1, 4 / 9, 4 / 9, 0, 80 / 80, 40 / 80, 0, 1], rtol=1e-6)
    np.testing.assert_allclose(enemy[2], [1, 4 / 9, 0, -4 / 9, 100 / 100, 10 / 50, 1, 0], rtol=1e-6)
    ally = agent[4 + 5 * nf:4 + 9 * nf].reshape(4, nf)
    # Ally one-hot: stalker 0, zealot 1. Ally rows skip self: row 1 is agent 2.
    np.testing.assert_allclose(ally[1], [1, 2 / 9, 0, 2 / 9, 50 / 100, 25 / 50, 0, 1], rtol=1e-6)
    np.testing.assert_allclose(agent[-4:], [40 / 80, 20 / 80, 1, 0], rtol=1e-6)
    state = feats.global_state(st, np.full((1, 5), -1), np.zeros(1, dtype=np.int64))[0]
    # Ally row: health, cooldown, rel_x, rel_y, shield, type (7); enemy row: health, rel_x, rel_y, shield, type (6).
    np.testing.assert_allclose(state[0:7], [40 / 80, 0, -6 / 32, 0, 20 / 80, 1, 0], rtol=1e-6)
    np.testing.assert_allclose(state[35 + 2 * 6:35 + 3 * 6], [1, -6 / 32, -4 / 32, 10 / 50, 1, 0], rtol=1e-6)


# SMAC's one-hot column per unit: red (custom ids in alphabetical order) and blue (SMAC's enemy table).
TYPE_COLUMNS = {
    "MMM": ({"marauder": 0, "marine": 1, "medivac": 2}, {"marauder": 0, "marine": 1, "medivac": 2}),
    "2s3z": ({"stalker": 0, "zealot": 1}, {"zealot": 0, "stalker": 1}),
    "1c3s5z": ({"colossus": 0, "stalker": 1, "zealot": 2}, {"colossus": 0, "stalker": 1, "zealot": 2}),
    "bane_vs_bane": ({"baneling": 0, "zergling": 1}, {"baneling": 0, "zergling": 1}),
}


@pytest.mark.parametrize("name", sorted(TYPE_COLUMNS))
def test_type_one_hot_schemes(name):
    red_cols, blue_cols = TYPE_COLUMNS[name]
    for side in (RED, BLUE):
        feats = SideFeatures(load_map(name), side)
        own_scheme, enemy_scheme = (red_cols, blue_cols) if side == RED else (blue_cols, red_cols)
        for onehot, types, scheme in ((feats.own_onehot, feats.utype[feats.own], own_scheme),
                                      (feats.enemy_onehot, feats.utype[feats.enemy], enemy_scheme)):
            for row, t in zip(onehot, types, strict=True):
                assert row.sum() == 1 and row.argmax() == scheme[UNITS[t].base], (side, UNITS[t].name)


def test_medivac_state_energy_and_heal_quirk():
    engine = BattleEngine("MMM", batch_size=1)
    st = engine.state
    medivac = 9  # red sorted by type: marauders 0-1, marines 2-8, medivac 9
    for slot in range(20):
        engine.place(0, slot, x=2.0 + slot, y=22.0)  # spread out along the top, far from the test pair
    engine.place(0, medivac, x=10.0, y=12.0, energy=100.0)
    engine.place(0, 3, x=10.0, y=16.0, health=20.0)  # marine ally 3, 4 away: healable
    engine.place(0, 4, x=10.0, y=18.5)  # ally 4, 6.5 away: not healable
    engine.place(0, 10 + 3, x=13.0, y=12.0)  # enemy 3, 3 away: seen
    engine.place(0, 10 + 4, x=14.0, y=12.0)  # enemy 4, 4 away: seen
    feats, avail = _features(engine)
    assert avail[0, medivac, 6 + 3] and not avail[0, medivac, 6 + 4]
    obs = feats.observations(st, avail, np.full((1, 10), -1), np.zeros(1, dtype=np.int64))[0]
    nf = 4 + 1 + 3
    enemy = obs[medivac, 4:4 + 10 * nf].reshape(10, nf)
    # SMAC quirk kept: a medivac's enemy column 0 shows whether it can heal the *ally* with that index.
    assert enemy[3, 0] == 1.0 and enemy[4, 0] == 0.0
    assert enemy[3, 1] == pytest.approx(3 / 9) and enemy[4, 1] == pytest.approx(4 / 9)
    state = feats.global_state(st, np.full((1, 10), -1), np.zeros(1, dtype=np.int64))[0]
    nf_s = 4 + 3
    assert state[medivac * nf_s + 1] == pytest.approx(100 / 200)  # energy / 200 in the cooldown column


def test_visibility_matrix_follows_sight_and_is_symmetric_among_allies(marines):
    feats, _ = _features(marines)
    vis = feats.visibility(marines.state)[0]
    # Columns: allies 0-2, enemies 0-2. Agent 0 sees ally 1 and enemies 0, 1; agent 1 sees everyone.
    np.testing.assert_array_equal(vis[0], [0, 1, 0, 1, 1, 0])
    np.testing.assert_array_equal(vis[1], [1, 0, 1, 1, 1, 1])
    np.testing.assert_array_equal(vis[:, :3], vis[:, :3].T)


# ---------------------------------------------------------------------------------------------------------------
# Self-play: blue's view of a mirrored battle is red's view, mirrored.


def _mirror_engine(name, red_positions, healths):
    engine = BattleEngine(name, batch_size=1)
    n = len(red_positions)
    for k, ((x, y), h) in enumerate(zip(red_positions, healths, strict=True)):
        engine.place(0, k, x=x, y=y, health=h)
        engine.place(0, n + k, x=32.0 - x, y=y, health=h)
    return engine


def _short(feature):
    """A feature's name without its block prefix: "enemy_2_rel_x" -> "rel_x", "own_type_0" -> "type_0"."""
    for prefix in ("enemy_", "ally_"):
        if feature.startswith(prefix):
            return feature.split("_", 2)[2]
    return feature.removeprefix("own_")


@pytest.mark.parametrize("name,positions,healths,swap_types", [
    ("3m", [(10.3, 15.2), (12.7, 17.1), (14.2, 16.6)], [45, 20, 33], False),
    ("2s3z", [(11.2, 14.3), (12.6, 17.4), (13.1, 15.5), (14.4, 16.9), (10.2, 18.8)], [80, 30, 100, 55, 70], True),
])
def test_mirrored_battle_gives_mirrored_observations(name, positions, healths, swap_types):
    engine = _mirror_engine(name, positions, healths)
    red, red_avail = _features(engine, RED, obs_last_action=True)
    blue, blue_avail = _features(engine, BLUE, obs_last_action=True)
    n = len(positions)
    mirror_action = {1: 1, 2: 2, 3: 3, 4: 5, 5: 4}  # east and west swap
    last = np.array([[1, 4, 2, 3, 5][:n]])
    last_blue = np.array([[mirror_action[int(a)] for a in last[0]]])
    step = np.zeros(1, dtype=np.int64)
    red_obs = red.observations(engine.state, red_avail, last, step)[0]
    blue_obs = blue.observations(engine.state, blue_avail, last_blue, step)[0]
    names = red.obs_feature_names()
    assert names == blue.obs_feature_names()
    swapped_type = {"type_0": "type_1", "type_1": "type_0"}
    expected = np.empty_like(red_obs)
    for col, feature in enumerate(names):
        short = _short(feature)
        source, sign = feature, 1.0
        if short == "rel_x":
            sign = -1.0
        elif feature in ("move_east", "move_west"):
            source = "move_west" if feature == "move_east" else "move_east"
        elif short.startswith("last_action_"):
            a = int(short.rsplit("_", 1)[1])
            source = feature.replace(short, f"last_action_{mirror_action.get(a, a)}")
        elif swap_types and short in swapped_type:
            # Each team keeps its own one-hot scheme: red's stalker 0 / zealot 1 is blue's zealot 0 / stalker 1.
            source = feature.replace(short, swapped_type[short])
        expected[:, col] = sign * red_obs[:, names.index(source)]
    np.testing.assert_allclose(blue_obs, expected, rtol=1e-5, atol=1e-6)
    assert blue_obs.any(axis=1).all()  # every blue agent sees something: the comparison is not vacuous


def test_bad_smac_options_are_rejected_naming_the_option():
    with pytest.raises(TypeError, match="option obs_last_action must be True or False, got 'yes'"):
        SmacOptions(obs_last_action="yes")
    with pytest.raises(TypeError, match="option reward_win must be a finite number"):
        SmacOptions(reward_win=float("nan"))
    with pytest.raises(ValueError, match="move_amount must be > 0"):
        SmacOptions(move_amount=0)
    with pytest.raises(TypeError, match=r"unknown SMAC option\(s\) \['obs_everything'\]"):
        SmacOptions.from_kwargs(obs_everything=True)
    assert SmacOptions(obs_all_health=True, obs_own_health=False).own_health


def test_encoding_chosen_battles_matches_their_rows_of_the_batch():
    # A vector env encodes terminal observations of the ended battles only: same values as their batch rows.
    engine = BattleEngine("2s3z", batch_size=5)
    rng = np.random.default_rng(3)
    engine.state.x[:] += rng.uniform(-4, 4, engine.state.x.shape)
    engine.state.alive[1, 2] = engine.state.alive[3, 6] = False
    feats = SideFeatures(engine.spec, RED, SmacOptions(obs_last_action=True, obs_timestep_number=True))
    last = rng.integers(-1, feats.n_actions, (5, feats.n_agents))
    steps = rng.integers(0, 100, 5)
    avail = available_actions(feats, engine.state)
    obs = feats.observations(engine.state, avail, last, steps)
    state = feats.global_state(engine.state, last, steps)
    rows = np.array([3, 1])
    some_avail = available_actions(feats, engine.state, rows=rows)
    np.testing.assert_array_equal(some_avail, avail[rows])
    np.testing.assert_array_equal(feats.observations(engine.state, some_avail, last, steps, rows=rows), obs[rows])
    np.testing.assert_array_equal(feats.global_state(engine.state, last, steps, rows=rows), state[rows])


@pytest.mark.parametrize("name", ["MMM", "2s3z", "corridor"])
def test_one_pass_encoding_matches_the_separate_features(name):
    # StarCraft2Env reads masks, observations and state through one fused kernel: same values as each on its own.
    engine = BattleEngine(name, batch_size=3)
    rng = np.random.default_rng(5)
    engine.state.x[:] += rng.uniform(-3, 3, engine.state.x.shape)
    engine.state.health[:] *= rng.uniform(0.2, 1.0, engine.state.health.shape)
    engine.state.alive[0, 1] = engine.state.alive[2, -1] = False
    for combo in ({}, {"obs_last_action": True, "obs_pathing_grid": True, "obs_terrain_height": True,
                       "obs_timestep_number": True, "state_timestep_number": True}, {"obs_instead_of_state": True}):
        for side in (RED, BLUE):
            feats = SideFeatures(engine.spec, side, SmacOptions(**combo))
            last = rng.integers(-1, feats.n_actions, (3, feats.n_agents))
            steps = rng.integers(0, 50, 3)
            avail, obs, state = feats.encode(engine.state, last, steps)
            expected_avail = available_actions(feats, engine.state)
            expected_obs = feats.observations(engine.state, expected_avail, last, steps)
            np.testing.assert_array_equal(avail, expected_avail)
            np.testing.assert_array_equal(obs, expected_obs)
            np.testing.assert_array_equal(state, feats.global_state(engine.state, last, steps, obs=expected_obs))


# The column table's fields that name their feature differently from the feature-name lists.
_COLUMN_FEATURES = {"type": "type_0", "last_action": "last_action_0", "cooldown": "energy/cooldown"}


@pytest.mark.parametrize("name", ["3m", "2s3z", "MMM2", "bane_vs_bane"])
def test_column_table_points_at_the_named_columns(name):
    """Every column the kernels write (``SideFeatures.columns``) is where obs_feature_names() and
    state_feature_names() name that feature, for every option combination and both sides."""
    spec = load_map(name)
    for combo in _COMBOS:
        for side in (RED, BLUE):
            feats = SideFeatures(spec, side, SmacOptions(**{**combo, "obs_instead_of_state": False}))
            cols, obs_names, state_names = feats.columns, feats.obs_feature_names(), feats.state_feature_names()
            blocks = {"enemy": ("enemy_0_", cols.enemy_offset), "ally": ("ally_0_", cols.ally_offset),
                      "own": ("own_", cols.own_offset), "state_ally": ("ally_0_", 0),
                      "state_enemy": ("enemy_0_", cols.state_enemy_offset)}
            for field, column in cols._asdict().items():
                block = next((b for b in sorted(blocks, key=len, reverse=True) if field.startswith(f"{b}_")), None)
                feature = field.removeprefix(f"{block}_") if block else field
                if block is None or feature in ("offset", "feats") or column < 0:
                    continue
                prefix, offset = blocks[block]
                names = state_names if block.startswith("state") else obs_names
                assert names[offset + column] == prefix + _COLUMN_FEATURES.get(feature, feature), (field, combo)
            assert obs_names[cols.move:cols.move + 4] == ["move_north", "move_south", "move_east", "move_west"]
            for field, first in (("pathing", "pathing_n2"), ("height", "height_n2")):
                assert (getattr(cols, field) >= 0) == (first in obs_names)
                assert getattr(cols, field) < 0 or obs_names[getattr(cols, field)] == first
            assert cols.state_timestep < 0 or state_names[cols.state_timestep] == "timestep"
            assert cols.state_last_action < 0 or state_names[cols.state_last_action] == "ally_0_last_action_0"
