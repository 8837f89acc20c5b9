"""Fuzzing every step API on every map with malformed actions (seeded): each one raises ``TypeError`` or
``ValueError`` and nothing else, leaves the env exactly as it was, and a legal step works right after."""

from __future__ import annotations

import numpy as np
import pytest
from fuzz_harness import (
    ROUNDS,
    SEED,
    GymApi,
    PettingZooApi,
    Sc2Api,
    VectorApi,
    first_difference,
    fuzz,
    fuzz_remote,
)

from smac_hard_gym.envs.subproc import make_subproc_env
from smac_hard_gym.maps import list_maps


@pytest.mark.parametrize("map_name", list_maps())
def test_malformed_actions_are_rejected_and_change_nothing(map_name):
    rng = np.random.default_rng([SEED, list_maps().index(map_name)])
    for api in (Sc2Api(map_name, "script"), Sc2Api(map_name, "self-play"), GymApi(map_name), VectorApi(map_name)):
        try:
            fuzz(api, rng)
        finally:
            api.close()


@pytest.mark.parametrize("map_name", ["3m", "MMM"])
def test_subprocess_env_rejects_before_any_worker_steps(map_name):
    # The workers' state is out of reach: a native batch of the same seeds, stepped in lock-step with the same legal
    # actions, shows that no rejection moved any battle.
    rng = np.random.default_rng([SEED, 100 + len(map_name)])
    native = VectorApi(map_name, opponent="default")
    with make_subproc_env(map_name, 2, 1, invalid_action="raise", autoreset_mode="SameStep",
                          opponent="default") as env:
        fuzz_remote(env, native, rng)
    native.close()



@pytest.mark.parametrize("map_name", list_maps())
def test_pettingzoo_rejects_malformed_actions_and_changes_nothing(map_name):
    pytest.importorskip("pettingzoo", reason="the [pettingzoo] extra is not installed")
    rng = np.random.default_rng([SEED, 200 + list_maps().index(map_name)])
    for teams in ("red", "both"):
        api = PettingZooApi(map_name, teams)
        try:
            fuzz(api, rng, rounds=ROUNDS // 2)
        finally:
            api.close()


def test_pettingzoo_rejects_bools_mixed_with_ints():
    # The mixes np.array(row) used to convert before the check (True -> 1, or 1.0 beside a float).
    pytest.importorskip("pettingzoo", reason="the [pettingzoo] extra is not installed")
    api = PettingZooApi("3m")
    for actions in ({"red_0": True, "red_1": 1, "red_2": 1}, {"red_0": 1.0, "red_1": True, "red_2": 1},
                    {"red_0": 1, "red_1": 1, "red_2": np.bool_(True)}):
        before = api.snapshot()
        with pytest.raises(TypeError, match="bool"):
            api.env.step(actions)
        assert first_difference(before, api.snapshot()) == ""
    api.close()
