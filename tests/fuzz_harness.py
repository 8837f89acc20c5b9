"""The fuzzing harness shared by tests/test_fuzz_actions.py, the Ray and PettingZoo fuzz tests and
benchmarks/soak.py: each step API behind one small interface (:class:`Api`), seeded malformed actions, and snapshots
of everything a step changes, so a rejection can be shown to change nothing."""

from __future__ import annotations

from typing import Any

import numpy as np

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.envs.gym_env import SMACHardEnv
from smac_hard_gym.envs.starcraft2 import StarCraft2Env
from smac_hard_gym.envs.vector import NativeVectorEnv
from smac_hard_gym.smac.features import SIDE_NAMES

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


def core_snapshot(core) -> list[Any]:
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
        return core_snapshot(env._core) + [env._episode_steps, env._total_steps, env._needs_reset]


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
        return core_snapshot(self.env.core) + [self.env._needs_reset]


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
        return core_snapshot(self.env.core) + [self.env._ended.copy()]


class PettingZooApi(Api):
    """The PettingZoo parallel env: one part per team, the live agents' actions packed into a dict by name (a part
    of the wrong length drops a live agent's entry or adds an unknown agent)."""

    def __init__(self, map_name: str, teams: str = "red") -> None:
        from smac_hard_gym.pettingzoo import parallel_env

        self.env = parallel_env(map_name, teams=teams, invalid_action="raise", seed=SEED)
        self.name = f"PettingZoo-{teams}"
        self.env.reset(seed=SEED)

    def _live(self, side: int) -> list[int]:
        return [i for i, live in enumerate(self.env._live[side]) if live]

    def parts(self):
        core = self.env.core
        out = []
        for side in self.env._sides:
            avail = core.avail_actions(side)[0][self._live(side)]
            out.append((avail.shape[:1], avail.shape[1], avail))
        return out

    def pack(self, parts):
        if len(parts) != len(self.env._sides):
            return parts  # a malformed pair of teams: not a dict
        actions: dict[str, Any] = {}
        for side, part in zip(self.env._sides, parts, strict=True):
            if isinstance(part, np.ndarray) and part.ndim != 1:
                return part.tolist()  # a batch of rows where a team's actions go: not a dict
            if not isinstance(part, (list, np.ndarray)) or any(isinstance(v, (list, np.ndarray)) for v in part):
                return part
            names = [self.env._names[side][i] for i in self._live(side)]
            values = list(part)
            actions.update(zip(names, values, strict=False))  # a short part leaves a live agent out
            if len(values) > len(names):
                actions[f"{SIDE_NAMES[side]}_99"] = values[-1]
        return actions

    def step(self, actions):
        self.env.step(actions)
        if not self.env.agents:
            self.env.reset()

    def snapshot(self):
        env = self.env
        return core_snapshot(env.core) + [list(env.agents), [list(live) for live in env._live], env._dead]


def legal_actions(rng: np.random.Generator, avail: np.ndarray) -> np.ndarray:
    """A random available action per agent."""
    scores = rng.random(avail.shape) * avail
    return scores.argmax(axis=-1)


def corrupt(rng: np.random.Generator, legal: np.ndarray, n_actions: int, avail: np.ndarray) -> Any:
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


def malformed(rng: np.random.Generator, api: Api) -> Any:
    parts = api.parts()
    legal = [legal_actions(rng, avail) for _, _, avail in parts]
    k = int(rng.integers(len(parts)))
    legal_k = legal[k]
    legal[k] = corrupt(rng, legal_k, parts[k][1], parts[k][2])
    if len(parts) > 1 and rng.random() < 0.2:  # self-play: the pair itself is malformed
        return [legal[0]] if rng.random() < 0.5 else legal + [legal[0]]
    return api.pack(legal)


def first_difference(before: list[Any], after: list[Any]) -> str:
    """Where two snapshots differ ("" when they are equal)."""
    if len(before) != len(after):
        return f"snapshot length {len(before)} -> {len(after)}"
    for k, (a, b) in enumerate(zip(before, after, strict=True)):
        same = np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b
        if not same:
            return f"state item {k} changed"
    return ""


def fuzz_round(api: Api, rng: np.random.Generator) -> str:
    """One malformed step, then a legal one: "rejected" when the malformed one raised TypeError or ValueError and
    changed nothing, else what went wrong (a silent accept, a state change, another exception)."""
    actions = malformed(rng, api)
    before = api.snapshot()
    try:
        api.step(actions)
    except (TypeError, ValueError):
        pass
    except Exception as err:  # noqa: BLE001 - reported, not raised: the soak counts them
        return f"crash: {type(err).__name__}: {err} on {actions!r}"
    else:
        return f"silent accept of {actions!r}"
    changed = first_difference(before, api.snapshot())
    if changed:
        return f"{changed} after rejecting {actions!r}"
    api.step(api.pack([legal_actions(rng, avail) for _, _, avail in api.parts()]))
    return "rejected"


def fuzz(api: Api, rng: np.random.Generator, rounds: int = ROUNDS) -> None:
    """``rounds`` fuzz rounds on ``api``; fails on the first that is not a clean rejection."""
    for _ in range(rounds):
        outcome = fuzz_round(api, rng)
        assert outcome == "rejected", f"{api.name}: {outcome}"


def fuzz_remote(env: Any, native: VectorApi, rng: np.random.Generator, rounds: int = ROUNDS) -> None:
    """Fuzz a vector env whose battles live in other processes (subprocess workers, Ray actors), whose state is out
    of reach: ``native``, a native batch of the same seeds stepped in lock-step with the same legal actions, shows
    that no rejection moved any battle. ``env`` is freshly built, ``invalid_action="raise"``, SameStep."""
    obs, _ = env.reset(seed=SEED)
    ref, _ = native.env.reset(seed=SEED)
    np.testing.assert_array_equal(obs, ref)
    n = env.num_envs
    for _ in range(rounds):
        masks = env.action_masks()
        np.testing.assert_array_equal(masks, native.env.action_masks())
        actions = malformed(rng, native)
        try:
            env.step(actions)
        except (TypeError, ValueError):
            pass
        else:
            raise AssertionError(f"{type(env).__name__} accepted {actions!r}")
        actions = legal_actions(rng, masks.reshape(n, native.env.view.n_agents, -1))
        obs, *_ = env.step(actions)
        ref, *_ = native.env.step(actions)
        np.testing.assert_array_equal(obs, ref)
