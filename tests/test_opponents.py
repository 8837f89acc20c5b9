"""The script API, helpers, the registry, mixtures and make_opponent's validation.

Expected values are computed by hand from the geometry or taken from SMAC-HARD's pool table
(docs/smac_hard_reference.md §3), never from the code under test.
"""

from __future__ import annotations

import numpy as np
import pytest

from smac_hard_gym.engine import BattleEngine
from smac_hard_gym.engine.state import BLUE, CMD_ATTACK, CMD_NOOP, RED, Commands
from smac_hard_gym.maps import list_maps, load_map
from smac_hard_gym.opponents import (
    Mixture,
    Script,
    SideView,
    make_opponent,
    pool_for_map,
    scripts_for_map,
)
from smac_hard_gym.opponents.helpers import (
    Frame,
    Memory,
    Orders,
    argmin_masked,
    centroid,
    from_blue_frame,
    line_points,
    lowest,
    retreat_points,
    to_pathable,
    weakest_of_nearest,
)

# ---------------------------------------------------------------------------------------------------------------
# Side views.


def test_side_views_split_slots_and_mirror_geometry():
    engine = BattleEngine("MMM2", batch_size=2)
    steps = np.zeros(2, dtype=np.int64)
    red = SideView.of(engine.state, engine.spec, RED, steps)
    blue = SideView.of(engine.state, engine.spec, BLUE, steps)
    assert (red.n_own, red.n_enemy) == (10, 12)  # MMM2: 7+2+1 vs 8+3+1
    assert (blue.n_own, blue.n_enemy) == (12, 10)
    assert blue.enemy_slot(0) == 0 and blue.own_slot(0) == 10
    # Learner at "Team 1" (9, 16), opponent at "Team 2" (23, 16): blue advances west, red east.
    np.testing.assert_allclose(blue.own_spawn, [23, 16])
    np.testing.assert_allclose(blue.forward, [-1, 0])
    np.testing.assert_allclose(red.forward, [1, 0])
    assert red.own_x.shape == (2, 10)
    with pytest.raises(ValueError, match="side must be RED"):
        SideView.of(engine.state, engine.spec, 2, steps)


# ---------------------------------------------------------------------------------------------------------------
# Helpers.


def test_argmin_masked_and_lowest_tie_break():
    values = np.array([[3.0, 1.0, 2.0], [5.0, 5.0, 5.0]])
    mask = np.array([[True, False, True], [False, False, False]])
    np.testing.assert_array_equal(argmin_masked(values, mask), [2, -1])
    hp = np.array([[10.0, 4.0, 4.0]])
    dist = np.array([[1.0, 9.0, 3.0]])
    assert lowest(hp, np.ones((1, 3), bool), tie=dist)[0] == 2  # both 4 HP: the nearer one


def test_weakest_of_nearest_reads_smac_hards_nearest_n_units():
    # One unit, 4 enemies at distances 4, 1, 3, 2 with health 10, 20, 10, 20.
    dist = np.array([[[4.0, 1.0, 3.0, 2.0]]])
    health = np.array([[10.0, 20.0, 10.0, 20.0]])
    alive = np.ones((1, 1, 4), bool)
    # The 2 nearest are enemies 1 and 3, both at 20: the nearer (1). The 3 nearest: enemy 2 alone has 10.
    assert weakest_of_nearest(dist, health, alive, k=2)[0, 0] == 1
    assert weakest_of_nearest(dist, health, alive, k=3)[0, 0] == 2
    # With k or fewer candidates SMAC-HARD's list stays in index order: of enemies 1 and 3 (both 20), the first
    # is 1, and of 0 and 2 (both 10) it is 0 although 2 is nearer.
    assert weakest_of_nearest(dist, health, np.array([[[False, True, False, True]]]), k=2)[0, 0] == 1
    assert weakest_of_nearest(dist, health, np.array([[[True, False, True, False]]]), k=2)[0, 0] == 0
    assert weakest_of_nearest(dist, health, np.zeros((1, 1, 4), bool), k=2)[0, 0] == -1


def test_blue_frame_reflects_red_through_the_spawns_midpoint():
    engine = BattleEngine("3m", batch_size=1)
    steps = np.zeros(1, dtype=np.int64)
    for side, expected in ((BLUE, (25.0, 15.5)), (RED, (7.0, 16.5))):
        frame = Frame(SideView.of(engine.state, engine.spec, side, steps), np.array([0]))
        x, y = from_blue_frame(frame, 25.0, 15.5)  # SMAC-HARD's line centre, written for blue
        assert (float(x), float(y)) == expected
        assert frame.blue_frame(*frame.blue_frame(3.0, 4.0)) == (3.0, 4.0)  # its own inverse
    # corridor's spawns are not mirror images: red's reflection of a point can land off the path; it is moved on.
    engine = BattleEngine("corridor", batch_size=1)
    frame = Frame(SideView.of(engine.state, engine.spec, RED, steps), np.array([0]))
    x, y = from_blue_frame(frame, 15.0, 22.0)
    assert engine.spec.pathable[int(x), int(y)]


def test_centroid_falls_back_where_nothing_is_alive():
    x = np.array([[0.0, 2.0, 100.0], [1.0, 1.0, 1.0]])
    y = np.array([[0.0, 4.0, 100.0], [1.0, 1.0, 1.0]])
    mask = np.array([[True, True, False], [False, False, False]])
    cx, cy = centroid(x, y, mask, fallback=(7.0, 8.0))
    np.testing.assert_allclose(cx, [1.0, 7.0])
    np.testing.assert_allclose(cy, [2.0, 8.0])


def test_line_points_across_the_direction_of_advance():
    # Facing west: the line runs north-south; 3 slots spaced 1 around y=16, as SMAC-HARD's line at x=25.
    x, y = line_points(np.array([25.0]), np.array([16.0]), np.array([-1.0, 0.0]), 3, spacing=1.0)
    np.testing.assert_allclose(x, [[25, 25, 25]])
    np.testing.assert_allclose(sorted(y[0]), [15, 16, 17])
    # Two ranks of 2: the second rank one behind (east when facing west).
    x, y = line_points(np.array([0.0]), np.array([0.0]), np.array([-1.0, 0.0]), 4, spacing=2.0, per_rank=2)
    np.testing.assert_allclose(sorted(x[0]), [0, 0, 1, 1])


def test_retreat_points_turn_away_from_walls():
    spec = load_map("3m")  # pathable strip y 8..23
    # Threat straight north of a unit at the bottom edge: straight away (south) is off the strip, so it turns.
    x, y = retreat_points(np.array([16.0]), np.array([8.5]), np.array([16.0]), np.array([10.5]), 2.0, spec,
                          (np.array([9.0]), np.array([16.0])))
    assert spec.pathable[int(x[0]), int(y[0])]
    assert np.hypot(x[0] - 16.0, y[0] - 8.5) == pytest.approx(2.0)
    # In the open it goes straight away.
    x, y = retreat_points(np.array([16.0]), np.array([16.0]), np.array([18.0]), np.array([16.0]), 2.0, spec,
                          (np.array([9.0]), np.array([16.0])))
    np.testing.assert_allclose([x[0], y[0]], [14.0, 16.0])


def test_to_pathable_moves_points_off_walls():
    spec = load_map("3m")
    x, y = to_pathable(np.array([16.2, 5.0]), np.array([2.0, 12.0]), spec)
    assert spec.pathable[int(x[0]), int(y[0])] and y[0] == pytest.approx(8.5)  # nearest row of the strip
    np.testing.assert_allclose([x[1], y[1]], [5.0, 12.0])  # already pathable: unchanged


def test_memory_clears_only_the_restarting_battles():
    engine = BattleEngine("3m", batch_size=3)
    view = SideView.of(engine.state, engine.spec, BLUE, np.zeros(3, dtype=np.int64))
    mem = Memory(flag=((), bool, False), last=(("own",), float, -1.0))
    mem.clear(view, np.arange(3))
    assert mem.last.shape == (3, 3)
    mem.flag[:] = True
    mem.clear(view, np.array([1]))
    np.testing.assert_array_equal(mem.flag, [True, False, True])


def test_orders_skip_dead_units_and_missing_targets_and_write_only_own_slots():
    engine = BattleEngine("3m", batch_size=2)
    engine.place(1, 4, alive=False, health=0.0)  # blue unit 1 of battle 1 is dead
    view = SideView.of(engine.state, engine.spec, BLUE, np.zeros(2, dtype=np.int64))
    frame = Frame(view, np.array([1]))
    orders = Orders(frame)
    orders.attack(np.ones((1, 3), bool), np.array([[0, 1, -1]]))
    commands = Commands.empty(2, 6)
    orders.write(commands)
    np.testing.assert_array_equal(commands.kind[1], [CMD_NOOP] * 3 + [CMD_ATTACK, CMD_NOOP, CMD_NOOP])
    assert commands.target[1, 3] == 0  # enemy index 0 of blue = red slot 0
    assert (commands.kind[0] == CMD_NOOP).all()  # other battle untouched


# ---------------------------------------------------------------------------------------------------------------
# Registry and pools.

# SMAC-HARD's SCRIPT_DICT at HEAD (reference §3), transcribed independently of opponents/library.py, as the
# number of scripts per map and whether base is in it.
_POOL_SIZES = {
    "3m": 2, "8m": 3, "5m_vs_6m": 3, "8m_vs_9m": 3, "10m_vs_11m": 3, "25m": 4, "27m_vs_30m": 4, "2s3z": 3,
    "3s5z": 3, "3s5z_vs_3s6z": 2, "3s_vs_3z": 3, "3s_vs_4z": 3, "3s_vs_5z": 3, "1c3s5z": 2, "2m_vs_1z": 2,
    "2s_vs_1sc": 2, "2c_vs_64zg": 2, "so_many_baneling": 2, "bane_vs_bane": 2, "MMM": 3, "MMM2": 3,
    "6h_vs_8z": 2, "corridor": 3,
}


@pytest.mark.parametrize("map_name", list_maps())
def test_every_map_has_smac_hard_pool(map_name):
    default = pool_for_map(map_name, "default")
    blackbox = pool_for_map(map_name, "blackbox")
    assert len(default) == _POOL_SIZES[map_name]
    assert ("base" in default) == (map_name != "6h_vs_8z")  # 6h_vs_8z's pool is easy + hard, no base
    assert "base" not in blackbox and set(blackbox) == set(default) - {"base"}
    available = scripts_for_map(map_name)
    assert set(default) <= set(available)
    for generic in ("base", "nearest", "weakest", "kite", "retreat_wounded", "focus_fire"):
        assert generic in available


def test_map_scripts_only_play_their_maps():
    assert "line_front" in scripts_for_map("8m") and "line_front" not in scripts_for_map("MMM")
    with pytest.raises(ValueError, match="does not play map 'MMM'"):
        make_opponent("MMM", "line_front")


def test_make_opponent_accepts_a_name_a_pool_or_weighted_names():
    assert make_opponent("3m").name == "base"
    assert make_opponent("3m", "weakest").name == "weakest"
    mix = make_opponent("8m", "default")
    assert isinstance(mix, Mixture) and mix.name == "default"
    assert mix.names == ["line_front", "line_weakest", "base"]
    np.testing.assert_allclose(mix.probs, [1 / 3] * 3)
    black = make_opponent("8m", "blackbox", [0.25, 0.75])
    assert black.names == ["line_front", "line_weakest"]
    np.testing.assert_allclose(black.probs, [0.25, 0.75])
    listed = make_opponent("3m", ["nearest", "kite"], np.array([0.4, 0.6]))
    assert listed.names == ["nearest", "kite"]


@pytest.mark.parametrize("opponent, probs, message", [
    ("nope", None, "unknown opponent 'nope' for map '3m'; allowed: default, blackbox"),
    ("default", [0.5, 0.6], "must sum to 1, got 1.1"),
    ("default", [0.5], "has 1 entries but there are 2 scripts"),
    ("default", [1.5, -0.5], "entry for 'base' must be finite and >= 0"),
    ("default", [float("nan"), 1.0], "must be finite and >= 0"),
    ("default", "0.5,0.5", "must be a list of 2 numbers"),
    (["nearest", "default"], None, "names a whole pool"),
    (["nearest", "nearest"], None, "distinct names"),
    ([], None, "opponent list is empty"),
    (["nearest", "weakest"], [0.5, "x"], "entry for 'weakest' must be a number"),
])
def test_make_opponent_rejects_bad_input(opponent, probs, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)").replace(".", r"\.")):
        make_opponent("3m", opponent, probs)


# ---------------------------------------------------------------------------------------------------------------
# Mixtures.


class _Named(Script):
    def __init__(self, name):
        self.name = name
        self.reset_battles: list[int] = []
        self.acted: list[np.ndarray] = []

    def reset(self, view, battles, rngs):
        self.reset_battles += [int(b) for b in battles]

    def act(self, view, commands, active):
        self.acted.append(np.flatnonzero(active))


def _view(batch: int, map_name: str = "3m") -> SideView:
    engine = BattleEngine(map_name, batch_size=batch)
    return SideView.of(engine.state, engine.spec, BLUE, np.zeros(batch, dtype=np.int64))


def test_mixture_frequencies_match_probabilities():
    batch = 6000
    view = _view(batch)
    probs = np.array([0.5, 0.3, 0.2])
    mix = Mixture([_Named("a"), _Named("b"), _Named("c")], probs)
    rngs = [np.random.default_rng([7, b]) for b in range(batch)]
    mix.reset(view, np.arange(batch), rngs)
    counts = np.bincount(mix.choice, minlength=3)
    sigma = np.sqrt(batch * probs * (1 - probs))
    assert np.all(np.abs(counts - batch * probs) < 4.5 * sigma), counts
    # Every battle went to exactly one sub-script's reset, and name_of agrees with the draw.
    resets = sorted(sum((s.reset_battles for s in mix.scripts), []))
    assert resets == list(range(batch))
    assert [mix.name_of(b) for b in range(5)] == [("a", "b", "c")[k] for k in mix.choice[:5]]


def test_mixture_with_zero_weight_never_draws_it():
    view = _view(500)
    mix = Mixture([_Named("a"), _Named("b")], [0.0, 1.0])
    mix.reset(view, np.arange(500), [np.random.default_rng(b) for b in range(500)])
    assert (mix.choice == 1).all()


def test_mixture_draws_are_reproducible_per_seed():
    def sequence(seed):
        view = _view(64)
        mix = make_opponent("8m", "default")
        names = []
        for episode in range(3):
            rngs = [np.random.default_rng([seed, episode, b]) for b in range(64)]
            mix.reset(view, np.arange(64), rngs)
            names.append([mix.name_of(b) for b in range(64)])
        return names

    assert sequence(1) == sequence(1)
    assert sequence(1) != sequence(2)


def test_mixture_calls_each_script_once_on_its_own_battles():
    view = _view(40)
    a, b = _Named("a"), _Named("b")
    mix = Mixture([a, b])
    mix.reset(view, np.arange(40), [np.random.default_rng(i) for i in range(40)])
    active = np.ones(40, bool)
    active[:5] = False
    mix.act(view, Commands.empty(40, 6), active)
    assert len(a.acted) == 1 and len(b.acted) == 1
    np.testing.assert_array_equal(a.acted[0], np.flatnonzero(active & (mix.choice == 0)))
    np.testing.assert_array_equal(b.acted[0], np.flatnonzero(active & (mix.choice == 1)))
    # Restarting some battles redraws only those.
    before = mix.choice.copy()
    mix.reset(view, np.array([3]), [np.random.default_rng(99 + i) for i in range(40)])
    np.testing.assert_array_equal(np.delete(mix.choice, 3), np.delete(before, 3))
