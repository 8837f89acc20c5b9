"""A recorded corpus of seeded episodes on every map, through every env API, for refactoring checks.

Each entry is the sha256 of everything one API returned over a fixed, seeded run (observations, masks, states,
rewards, flags and infos, bytes and dtypes): a change that alters any returned value by one bit changes the digest.
The corpus (``tests/data/equivalence_corpus.json``) was recorded before a restructuring of the env layers; the test
``test_equivalence_corpus.py`` replays it. Rewrite it only for a change meant to alter behaviour, and say so in the
commit:

    python -m tests.equivalence_corpus --write

Runs (actions drawn uniformly from each agent's legal actions by a seeded generator; the map's default opponent
mixture, so the scripts' choices are covered too):

- ``single``: ``SMACHardEnv`` in ``"dict"`` mode (observations, global state and masks), 2 episodes or 120 steps;
- ``smac``: ``StarCraft2Env``'s pymarl loop (``get_obs``, ``get_state``, ``get_avail_actions``, ``step``);
- ``native``: ``NativeVectorEnv`` of 3 battles, ``"joint+state"``, same-step autoreset (terminal observations);
- ``subproc``: ``SubprocVectorEnv`` of 2 workers (2 + 1 battles), ``"joint"``, next-step autoreset.
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
from pathlib import Path
from typing import Any

import numpy as np

CORPUS = Path(__file__).parent / "data" / "equivalence_corpus.json"
APIS = ("single", "smac", "native", "subproc")
SEED = 11
STEPS = 120
BATTLES = 3


class Digest:
    """sha256 over a stream of values: arrays by dtype, shape and bytes; scalars, strings and dicts by value."""

    def __init__(self) -> None:
        self.hash = hashlib.sha256()

    def add(self, value: Any) -> None:
        h = self.hash
        if isinstance(value, dict):
            for key in sorted(value):
                h.update(repr(key).encode())
                self.add(value[key])
        elif isinstance(value, np.ndarray) and value.dtype == object:
            h.update(repr(value.shape).encode())
            for v in value.reshape(-1):
                self.add(v)
        elif isinstance(value, np.ndarray):
            h.update(f"{value.dtype.str}{value.shape}".encode())
            h.update(np.ascontiguousarray(value).tobytes())
        elif isinstance(value, (list, tuple)):
            h.update(f"seq{len(value)}".encode())
            for v in value:
                self.add(v)
        elif isinstance(value, (np.generic, bool, int, float, str)) or value is None:
            h.update(f"{type(value).__name__}:{value!r}".encode())
        else:
            raise TypeError(f"cannot digest {type(value).__name__}")

    def hexdigest(self) -> str:
        return self.hash.hexdigest()


def _pick(rng: np.random.Generator, mask: np.ndarray) -> np.ndarray:
    """One legal action per agent from bool masks ``(..., n_agents, n_actions)``."""
    noise = rng.random(mask.shape)
    return np.where(mask, noise, -1.0).argmax(axis=-1).astype(np.int64)


def play_single(map_name: str) -> str:
    import gymnasium as gym

    import smac_hard_gym  # noqa: F401  (registers the ids)

    env = gym.make(f"SMACHard-{map_name}-v0", obs_mode="dict").unwrapped
    rng, digest = np.random.default_rng(SEED), Digest()
    obs, info = env.reset(seed=SEED)
    digest.add([obs, info])
    episodes = 0
    for _ in range(STEPS):
        mask = env.action_masks().reshape(env.n_agents, env.n_actions)
        obs, reward, terminated, truncated, info = env.step(_pick(rng, mask))
        digest.add([obs, reward, terminated, truncated, info])
        if terminated or truncated:
            episodes += 1
            if episodes == 2:
                break
            obs, info = env.reset(seed=SEED + episodes)
            digest.add([obs, info])
    env.close()
    return digest.hexdigest()


def play_smac(map_name: str) -> str:
    from smac_hard_gym import StarCraft2Env

    env = StarCraft2Env(map_name=map_name, seed=SEED)
    rng, digest = np.random.default_rng(SEED), Digest()
    env.reset()
    episodes = 0
    for _ in range(STEPS):
        avail = np.array(env.get_avail_actions(), dtype=bool)
        digest.add([np.stack(env.get_obs()), env.get_state(), avail])
        reward, terminated, info = env.step(_pick(rng, avail).tolist())
        digest.add([reward, terminated, info])
        if terminated:
            episodes += 1
            if episodes == 2:
                break
            env.reset()
    digest.add(env.get_stats())
    env.close()
    return digest.hexdigest()


def _play_vector(envs: Any, mask_of: Any) -> str:
    rng, digest = np.random.default_rng(SEED), Digest()
    obs, infos = envs.reset(seed=SEED)
    digest.add([obs, infos])
    for _ in range(STEPS):
        actions = _pick(rng, mask_of(envs))
        digest.add(list(envs.step(actions)))
    return digest.hexdigest()


def _masks(envs: Any) -> np.ndarray:
    return envs.action_masks().reshape(envs.num_envs, -1, envs.single_action_space.nvec[0])


def play_native(map_name: str) -> str:
    from smac_hard_gym import NativeVectorEnv

    with NativeVectorEnv(map_name, BATTLES, obs_mode="joint+state", autoreset_mode="SameStep") as envs:
        return _play_vector(envs, _masks)


def play_subproc(map_name: str) -> str:
    from smac_hard_gym import NativeVectorEnv, SubprocVectorEnv

    factories = [functools.partial(NativeVectorEnv, map_name, num_envs=n) for n in (2, BATTLES - 2)]
    envs = SubprocVectorEnv(factories)
    try:
        return _play_vector(envs, _masks)
    finally:
        envs.close()


PLAYERS = {"single": play_single, "smac": play_smac, "native": play_native, "subproc": play_subproc}


def load() -> dict[str, dict[str, str]]:
    return json.loads(CORPUS.read_text())


def main() -> None:
    from smac_hard_gym.maps import list_maps

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="record the corpus anew (a change meant to alter play)")
    parser.add_argument("--maps", nargs="+", default=list(list_maps()), help="check these maps only")
    parser.add_argument("--apis", nargs="+", default=list(APIS), choices=APIS, help="check these APIs only")
    args = parser.parse_args()
    if args.write:
        args.maps, args.apis = list(list_maps()), list(APIS)
    corpus = {name: {api: PLAYERS[api](name) for api in args.apis} for name in args.maps}
    if args.write:
        CORPUS.parent.mkdir(exist_ok=True)
        CORPUS.write_text(json.dumps(corpus, indent=1, sort_keys=True) + "\n")
        print(f"wrote {CORPUS}")
    else:
        stored = load()
        differ = [(m, a) for m in corpus for a in args.apis if stored.get(m, {}).get(a) != corpus[m][a]]
        print("identical" if not differ else f"differ: {differ}")


if __name__ == "__main__":
    main()
