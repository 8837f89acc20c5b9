"""smac-hard-gym: SMAC-HARD on an embedded, batched StarCraft II battle engine.

Importing the package registers ``SMACHard-<map>-v0`` for every map in :func:`smac_hard_gym.maps.list_maps`, so
``gymnasium.make("SMACHard-3m-v0")`` builds a :class:`~smac_hard_gym.envs.gym_env.SMACHardEnv` and
``gymnasium.make_vec("SMACHard-3m-v0", num_envs=8)`` a :class:`~smac_hard_gym.envs.vector.NativeVectorEnv`. The entry
points are lazy strings: the import stays light (no engine compile, no torch), and ``"smac_hard_gym:SMACHard-3m-v0"``
works in fresh worker processes. ``StarCraft2Env`` (SMAC's API) is exported lazily too, and so are
``RayVectorEnv`` and ``make_ray_vec`` (vector workers on Ray; ``ray`` is imported only when they are used).

``__version__`` is the installed distribution's version (written once, in ``pyproject.toml``), read on first use.
"""

from __future__ import annotations

import os as _os

# The engine's threading layer (see smac_hard_gym/engine/kernels.py); set before numba is imported anywhere.
_os.environ.setdefault("NUMBA_THREADING_LAYER", "workqueue")

ENTRY_POINT = "smac_hard_gym.envs.gym_env:SMACHardEnv"
VECTOR_ENTRY_POINT = "smac_hard_gym.envs.vector:NativeVectorEnv"

_LAZY_EXPORTS = {
    "StarCraft2Env": "smac_hard_gym.envs.starcraft2",
    "SMACHardEnv": "smac_hard_gym.envs.gym_env",
    "NativeVectorEnv": "smac_hard_gym.envs.vector",
    "SubprocVectorEnv": "smac_hard_gym.envs.subproc",
    "RayVectorEnv": "smac_hard_gym.wrappers.ray_vec",  # needs the [ray] extra; ray loads only when asked for
    "make_ray_vec": "smac_hard_gym.wrappers.ray_vec",
}


def env_id(map_name: str) -> str:
    """The gymnasium id of a map: ``SMACHard-<map>-v0``."""
    return f"SMACHard-{map_name}-v0"


def register_envs() -> list[str]:
    """Register every map's id with gymnasium (ids already registered are kept); returns the ids of all maps.

    Runs at import; call it again after ``smac_hard_gym.maps.register_map`` to give a map added later its id."""
    from gymnasium.envs.registration import register, registry

    from smac_hard_gym.maps import list_maps, load_map

    ids = []
    for name in list_maps():
        new_id = env_id(name)
        if new_id not in registry:
            register(new_id, entry_point=ENTRY_POINT, vector_entry_point=VECTOR_ENTRY_POINT,
                     max_episode_steps=load_map(name).episode_limit, kwargs={"map_name": name})
        ids.append(new_id)
    return ids


def _read_version() -> str:
    """The installed distribution's version: pyproject.toml is its one source. ``0+unknown`` when the package runs
    from a source tree that was never installed (no metadata to read)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("smac-hard-gym")
    except PackageNotFoundError:
        return "0+unknown"


def __getattr__(name: str):  # lazy exports keep `import smac_hard_gym` light
    if name == "__version__":
        globals()["__version__"] = found = _read_version()  # read once
        return found
    if name in _LAZY_EXPORTS:
        import importlib

        return getattr(importlib.import_module(_LAZY_EXPORTS[name]), name)
    raise AttributeError(f"module 'smac_hard_gym' has no attribute {name!r}")


ENV_IDS = register_envs()
