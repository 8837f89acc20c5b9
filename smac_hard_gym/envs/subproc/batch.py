"""Several workers' parts as one batch, and one batch's seeds split among workers."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["concat_infos", "concat_obs", "obs_row", "split_seed", "compact_seed"]


def concat_infos(parts: Sequence[dict[str, Any]], sizes: Sequence[int]) -> dict[str, Any]:
    """Gymnasium vector infos of consecutive batches joined into one (keys missing in a part get blank rows and a
    False ``_key`` mask)."""
    keys: list[str] = []
    for part in parts:
        keys += [k for k in part if not k.startswith("_") and k not in keys]
    out: dict[str, Any] = {}
    for key in keys:
        values = [part.get(key) for part in parts]
        masks = [np.asarray(part.get(f"_{key}", np.ones(n, dtype=bool))) if key in part else np.zeros(n, dtype=bool)
                 for part, n in zip(parts, sizes, strict=True)]
        if any(isinstance(v, dict) for v in values):
            out[key] = concat_infos([v if isinstance(v, dict) else {} for v in values], sizes)
        else:
            template = np.asarray(next(v for v in values if v is not None))
            out[key] = np.concatenate([np.asarray(v) if v is not None else _blank(template, n)
                                       for v, n in zip(values, sizes, strict=True)])
        out[f"_{key}"] = np.concatenate(masks)
    return out


def _blank(template: np.ndarray, n: int) -> np.ndarray:
    if template.dtype == object:
        return np.full((n, *template.shape[1:]), None, dtype=object)
    return np.zeros((n, *template.shape[1:]), dtype=template.dtype)


def concat_obs(parts: list[Any]) -> Any:
    """Consecutive batches of observations (arrays, or dicts of arrays) joined into one."""
    if isinstance(parts[0], dict):
        return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return np.concatenate([np.asarray(p) for p in parts])


def obs_row(obs: Any, i: int) -> Any:
    """Battle ``i``'s observation of a batch (an array, or a dict of arrays)."""
    if isinstance(obs, dict):
        return {k: v[i] for k, v in obs.items()}
    return obs[i]


def split_seed(seed: Any, n: int) -> list[int | None] | None:
    """One seed per battle: an int ``s`` gives battle ``i`` the seed ``s + i``; a list is taken as it is."""
    if seed is None:
        return None
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return [int(seed) + i for i in range(n)]
    if isinstance(seed, Sequence) and len(seed) == n:
        return list(seed)
    raise ValueError(f"seed must be None, an int, or a list of {n} seeds (one per battle), got {seed!r}")


def compact_seed(seeds: list[int | None] | None) -> Any:
    """A worker's seeds as an int when they count up from its first battle's (what a batch env expects)."""
    if seeds is None or all(s is None for s in seeds):
        return None
    if all(s is not None for s in seeds) and seeds == list(range(seeds[0], seeds[0] + len(seeds))):
        return int(seeds[0])
    return seeds
