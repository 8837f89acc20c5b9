"""Fuzzing every step API on every map with malformed actions (seeded): each one raises ``TypeError`` or
``ValueError`` and nothing else, leaves the env exactly as it was, and a legal step works right after."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.envs.gym_env import SMACHardEnv
from smac_hard_gym.envs.starcraft2 import StarCraft2Env
from smac_hard_gym.envs.subproc import make_subproc_env
from smac_hard_gym.envs.vector import NativeVectorEnv
from smac_hard_gym.maps import list_maps

SEED = 13
ROUNDS = 100  # malformed actions per env, each followed by a legal step (the file takes ~12 s on 2 cores)
N = object()  # stands for n_actions (the first value out of range)
# Values that are not an action: not integers (TypeError) or out of range (ValueError).
BAD_VALUES = [3.5, -0.5, float("nan"), float("inf"), -float("inf"), 1e19, 2**70, -(2**70), -1, N, True, np.True_,
              "3", b"3", None, 3j, [1], (1, 1), {}, object(), np.float32(2.5), np.uint64(2**64 - 1)]
# Whole action containers that are malformed.
BAD_CONTAINERS = [None, "111", 7, {}, set(), [], [[]]]


class Api:
    """One env under test: its action parts (shape, n_actions, masks), how they pack into ``step``'s argument,
    a legal step, and a snapshot of everything a step changes."""

    name = ""

    def parts(self) -> list[tuple[tuple[int, ...], int, np.ndarray]]:
        raise NotImplementedError

    def pack(self, parts: list[Any]) -> Any:
        return parts[0]

    def step(self, actions: Any) -> None:
        raise NotImplementedError

    def snapshot(self) -> list[Any]:
        raise NotImplementedError

    def close(self) -> None:
        self.env.close()


def _core_snapshot(core) -> list[Any]:
    arrays = [np.copy(a) for a in core.state]
    arrays += [core.episode_step.copy(), core.done.copy(), core.last_action[RED].copy(), core.last_action[BLUE].copy()]
    return arrays + [None if rng is None else rng.bit_generator.state for rng in core.rngs]


class Sc2Api(Api):
    def __init__(self, map_name: str, mode: str) -> None:
        self.env = StarCraft2Env(map_name=map_name, mode=mode, seed=SEED)
        self.name = f"StarCraft2Env-{mode}"
        self.self_play = mode == "self-play"
        self.env.reset()

    def parts(self):
        players = (RED, BLUE) if self.self_play else (RED,)
        out = []
        for p in players:
            avail = np.array(self.env.get_avail_actions(p), dtype=bool)
            out.append((avail.shape[:1], avail.shape[1], avail))
        return out

    def pack(self, parts):
        return list(parts) if self.self_play else parts[0]

    def step(self, actions):
        _, terminated, _ = self.env.step(actions)
        if (terminated[0] if self.self_play else terminated):
            self.env.reset()

    def snapshot(self):
        env = self.env
        return _core_snapshot(env._core) + [env._episode_steps, env._total_steps, env._needs_reset]


class GymApi(Api):
    name = "SMACHardEnv"

    def __init__(self, map_name: str) -> None:
        self.env = SMACHardEnv(map_name, invalid_action="raise")
        self.env.reset(seed=SEED)

    def parts(self):
        avail = self.env.action_masks().reshape(self.env.n_agents, -1)
        return [(avail.shape[:1], avail.shape[1], avail)]

    def step(self, actions):
        _, _, terminated, truncated, _ = self.env.step(actions)
        if terminated or truncated:
            self.env.reset()

    def snapshot(self):
        return _core_snapshot(self.env.core) + [self.env._needs_reset]


class VectorApi(Api):
    name = "NativeVectorEnv"

    def __init__(self, map_name: str, **kwargs: Any) -> None:
        # SameStep: every battle is active at every step, so an unavailable action is always checked.
        self.env = NativeVectorEnv(map_name, 2, invalid_action="raise", autoreset_mode="SameStep", **kwargs)
        self.env.reset(seed=SEED)

    def parts(self):
        avail = self.env.action_masks().reshape(2, self.env.view.n_agents, -1)
        return [(avail.shape[:2], avail.shape[2], avail)]

    def step(self, actions):
        self.env.step(actions)

    def snapshot(self):
        return _core_snapshot(self.env.core) + [self.env._ended.copy()]


def _legal(rng: np.random.Generator, avail: np.ndarray) -> np.ndarray:
    """A random available action per agent."""
    scores = rng.random(avail.shape) * avail
    return scores.argmax(axis=-1)


def _corrupt(rng: np.random.Generator, legal: np.ndarray, n_actions: int, avail: np.ndarray) -> Any:
    """``legal`` with one malformed change: a bad value (in a list, or in a float array when it is a float), an
    unavailable action, or a wrong shape."""
    kind = rng.choice(4, p=[0.5, 0.2, 0.15, 0.15])
    index = tuple(int(rng.integers(s)) for s in legal.shape)
    if kind == 0:
        value = BAD_VALUES[rng.integers(len(BAD_VALUES))]
        value = n_actions if value is N else value
        if isinstance(value, float) and rng.random() < 0.5:
            out = legal.astype(np.float64)
            out[index] = value
            return out
        out = legal.astype(object)
        out[index] = value
        return out.tolist()
    if kind == 1:
        out = legal.copy()
        out[index] = rng.choice(np.flatnonzero(~avail[index]))
        return out if rng.random() < 0.5 else out.tolist()
    if kind == 2:
        shapes = [legal[..., :-1], np.concatenate([legal, legal[..., :1]], axis=-1), legal[None], legal.reshape(-1)]
        out = shapes[rng.integers(len(shapes))]
        if out.shape == legal.shape:  # the flat view of a single row is no change
            out = legal[None]
        return out.tolist() if rng.random() < 0.5 else out
    return BAD_CONTAINERS[rng.integers(len(BAD_CONTAINERS))]


def _malformed(rng: np.random.Generator, api: Api) -> Any:
    parts = api.parts()
    legal = [_legal(rng, avail) for _, _, avail in parts]
    k = int(rng.integers(len(parts)))
    legal_k = legal[k]
    legal[k] = _corrupt(rng, legal_k, parts[k][1], parts[k][2])
    if len(parts) > 1 and rng.random() < 0.2:  # self-play: the pair itself is malformed
        return [legal[0]] if rng.random() < 0.5 else legal + [legal[0]]
    return api.pack(legal)


def _assert_same(before: list[Any], after: list[Any], what: str) -> None:
    assert len(before) == len(after)
    for k, (a, b) in enumerate(zip(before, after, strict=True)):
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=f"{what}: state array {k} changed")
        else:
            assert a == b, f"{what}: state item {k} changed"


def _fuzz(api: Api, rng: np.random.Generator) -> None:
    for _ in range(ROUNDS):
        actions = _malformed(rng, api)
        before = api.snapshot()
        what = f"{api.name} on {actions!r}"
        try:
            api.step(actions)
        except (TypeError, ValueError):
            pass
        else:
            raise AssertionError(f"{what} was accepted")
        _assert_same(before, api.snapshot(), what)
        api.step(api.pack([_legal(rng, avail) for _, _, avail in api.parts()]))


@pytest.mark.parametrize("map_name", list_maps())
def test_malformed_actions_are_rejected_and_change_nothing(map_name):
    rng = np.random.default_rng([SEED, list_maps().index(map_name)])
    for api in (Sc2Api(map_name, "script"), Sc2Api(map_name, "self-play"), GymApi(map_name), VectorApi(map_name)):
        try:
            _fuzz(api, rng)
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
        obs, _ = env.reset(seed=SEED)
        ref, _ = native.env.reset(seed=SEED)
        np.testing.assert_array_equal(obs, ref)
        for _ in range(ROUNDS):
            masks = env.action_masks()
            np.testing.assert_array_equal(masks, native.env.action_masks())
            with pytest.raises((TypeError, ValueError)):
                env.step(_malformed(rng, native))
            actions = _legal(rng, masks.reshape(2, native.env.view.n_agents, -1))
            obs, *_ = env.step(actions)
            ref, *_ = native.env.step(actions)
            np.testing.assert_array_equal(obs, ref)
    native.close()

