"""Adapters from smac-hard-gym's envs to other libraries (installed as ``smac_hard_gym.wrappers``).

- :class:`~smac_hard_gym.wrappers.sb3.SB3VecEnv`: a Stable-Baselines3 ``VecEnv`` over any gymnasium vector env
  (``pip install smac-hard-gym[train]``).
- :class:`~smac_hard_gym.wrappers.ray_vec.RayVectorEnv` and ``make_ray_vec``: vector workers as Ray actors, on one
  machine or a cluster (``pip install smac-hard-gym[ray]``).

Each adapter loads its library only when imported, so ``import smac_hard_gym.wrappers`` stays light.
"""

from __future__ import annotations

_LAZY_EXPORTS = {"SB3VecEnv": "smac_hard_gym.wrappers.sb3", "RayVectorEnv": "smac_hard_gym.wrappers.ray_vec",
                 "make_ray_vec": "smac_hard_gym.wrappers.ray_vec"}

__all__ = list(_LAZY_EXPORTS)


def __getattr__(name: str):
    if name in _LAZY_EXPORTS:
        import importlib

        return getattr(importlib.import_module(_LAZY_EXPORTS[name]), name)
    raise AttributeError(f"module 'smac_hard_gym.wrappers' has no attribute {name!r}")
