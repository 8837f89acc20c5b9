"""Shared memory between :class:`~smac_hard_gym.envs.subproc.SubprocVectorEnv` and its workers.

One segment holds, for all N battles of the batch, every array leaf of the observations (``"obs"`` for a ``Box``
space, ``"obs.<key>"`` for each ``Box`` of a ``Dict`` space) and the flat action masks (``"mask"``, int8
``(N, mask_size)``). Each worker writes its own rows ``start:stop``; the parent reads them. Other observation spaces,
and the rewards, flags and infos, travel through the pipe.
"""

from __future__ import annotations

from multiprocessing.shared_memory import SharedMemory
from typing import Any

import numpy as np
from gymnasium import spaces

__all__ = ["SharedBlock", "MASK_KEY", "block_layout", "obs_layout", "write_obs", "read_obs", "write_masks"]

MASK_KEY = "action_mask"  # the infos key whose arrays travel through the block's "mask" rows

Layout = list[tuple[str, tuple[int, ...], str]]


class SharedBlock:
    """Arrays ``(N, ...)`` laid out in one shared memory segment; ``layout`` is [(key, shape, dtype)].

    Built without ``name``, it creates (and at ``close()`` unlinks) the segment; with ``name``, it attaches to it.
    """

    def __init__(self, layout: Layout, name: str | None = None) -> None:
        self.layout = layout
        sizes = [int(np.prod(shape)) * np.dtype(dtype).itemsize for _, shape, dtype in layout]
        offsets = np.concatenate([[0], np.cumsum([-(-s // 64) * 64 for s in sizes])]).astype(int)
        self.owner = name is None
        self.shm = SharedMemory(name=name, create=self.owner, size=max(int(offsets[-1]), 1))
        self.arrays = {key: np.ndarray(shape, dtype=dtype, buffer=self.shm.buf, offset=int(off))
                       for (key, shape, dtype), off in zip(layout, offsets[:-1], strict=True)}

    @property
    def name(self) -> str:
        return self.shm.name

    def close(self) -> None:
        self.arrays = {}
        try:
            self.shm.close()
        except BufferError:  # a view still alive somewhere; the segment goes with the process
            pass
        if self.owner:
            try:
                self.shm.unlink()
            except FileNotFoundError:
                pass


def obs_layout(space: spaces.Space, num_envs: int) -> Layout | None:
    """The observation arrays of ``num_envs`` battles, or None when the space travels through the pipe."""
    if isinstance(space, spaces.Box):
        return [("obs", (num_envs, *space.shape), space.dtype.str)]
    if isinstance(space, spaces.Dict) and all(isinstance(s, spaces.Box) for s in space.values()):
        return [(f"obs.{key}", (num_envs, *s.shape), s.dtype.str) for key, s in space.items()]
    return None  # other spaces travel through the pipe


def block_layout(space: spaces.Space, num_envs: int, mask_size: int | None) -> Layout:
    """Everything the block holds: the observations (when they fit) and, when there are masks, the masks."""
    layout = obs_layout(space, num_envs) or []
    if mask_size:
        layout.append(("mask", (num_envs, mask_size), "|i1"))
    return layout


def _obs_keys(block: SharedBlock) -> list[str]:
    return [k for k in block.arrays if k.startswith("obs.")]


def write_obs(block: SharedBlock | None, obs: Any, start: int, stop: int) -> Any:
    """Copy ``obs`` rows into the block; returns what the pipe must carry instead (None when all went in)."""
    if block is None:
        return obs
    if "obs" in block.arrays:
        block.arrays["obs"][start:stop] = obs
        return None
    keys = _obs_keys(block)
    if not keys:
        return obs
    for key in keys:
        block.arrays[key][start:stop] = obs[key[4:]]
    return None


def read_obs(block: SharedBlock, start: int, stop: int) -> Any:
    """A copy of rows ``start:stop`` of the observations in the block (None when they travel by pipe)."""
    if "obs" in block.arrays:
        return block.arrays["obs"][start:stop].copy()
    keys = _obs_keys(block)
    if not keys:
        return None
    return {key[4:]: block.arrays[key][start:stop].copy() for key in keys}


def write_masks(block: SharedBlock | None, infos: dict[str, Any], start: int, stop: int) -> dict[str, Any]:
    """Move ``infos["action_mask"]`` into the block's mask rows; returns the infos without it (its
    ``_action_mask`` stays), or the infos as they were when the masks do not fit."""
    if block is None or MASK_KEY not in infos or "mask" not in block.arrays:
        return infos
    masks = np.asarray(infos[MASK_KEY])
    target = block.arrays["mask"][start:stop]
    if masks.reshape(len(target), -1).shape != target.shape:
        return infos
    present = np.asarray(infos.get(f"_{MASK_KEY}", np.ones(len(target), dtype=bool)))
    target[present] = masks.reshape(target.shape)[present]
    infos = dict(infos)
    del infos[MASK_KEY]
    return infos
