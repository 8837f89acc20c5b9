"""Adapters from smac-hard-gym's envs to other libraries (installed as ``smac_hard_gym.wrappers``).

- :class:`~smac_hard_gym.wrappers.sb3.SB3VecEnv`: a Stable-Baselines3 ``VecEnv`` over any gymnasium vector env
  (``pip install smac-hard-gym[train]``).
- :class:`~smac_hard_gym.wrappers.ray_vec.RayVectorEnv` and ``make_ray_vec``: vector workers as Ray actors, on one
  machine or a cluster (``pip install smac-hard-gym[ray]``).

Each adapter loads its library only when its name is first used, so ``import smac_hard_gym.wrappers`` stays light.
``__all__`` lists only the adapters whose library is installed, so ``from smac_hard_gym.wrappers import *`` works
with any set of extras; asking for one whose library is missing by name raises an ``ImportError`` naming the extra.
"""

from __future__ import annotations

import importlib
import importlib.util

# name -> (module that defines it, top-level library it needs, the extra that installs that library)
_LAZY_EXPORTS: dict[str, tuple[str, str, str]] = {
    "SB3VecEnv": ("smac_hard_gym.wrappers.sb3", "stable_baselines3", "train"),
    "RayVectorEnv": ("smac_hard_gym.wrappers.ray_vec", "ray", "ray"),
    "make_ray_vec": ("smac_hard_gym.wrappers.ray_vec", "ray", "ray"),
}


def _installed(library: str) -> bool:
    """Whether ``library`` can be found, without importing it (Ray's import takes about a second)."""
    try:
        return importlib.util.find_spec(library) is not None
    except (ImportError, ValueError):  # a finder that refuses it, or a module entry set to None
        return False


__all__ = [name for name, (_, library, _) in _LAZY_EXPORTS.items() if _installed(library)]


def __getattr__(name: str):
    if name in _LAZY_EXPORTS:
        module_name, library, extra = _LAZY_EXPORTS[name]
        try:
            module = importlib.import_module(module_name)
        except ImportError as err:
            if f"[{extra}]" in str(err):  # the module's own message already names the extra
                raise
            raise ImportError(f"{name} needs {library}: pip install 'smac-hard-gym[{extra}]' ({err})") from err
        return getattr(module, name)
    raise AttributeError(f"module 'smac_hard_gym.wrappers' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY_EXPORTS))
