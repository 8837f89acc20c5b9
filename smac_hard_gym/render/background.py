"""The static part of a frame: the map's terrain, drawn once per renderer and copied under every frame.

Pathable ground is khaki, brighter on higher cliff levels (ramps fall half-way); unpathable cells are near-black,
also lifted a little per level so plateaus stay visible; a dark outline marks every drop of a full cliff level.
"""

from __future__ import annotations

import numpy as np

PATHABLE_RGB = np.array([112.0, 124.0, 92.0])  # level-1 ground, SMAC's usual playing field
UNPATHABLE_RGB = np.array([28.0, 30.0, 38.0])
LEVEL_BRIGHTEN = 0.2  # pathable colour gains 20% per cliff level above 1
UNPATHABLE_LEVEL_LIFT = 12.0  # unpathable colour gains this much per level
CLIFF_EDGE_DARKEN = 0.45  # edge pixels keep this fraction of their colour


def cell_colors(pathable: np.ndarray, cliff: np.ndarray) -> np.ndarray:
    """RGB float colour per cell, indexed [x, y] like the map grids."""
    level = cliff[..., None]
    ground = PATHABLE_RGB * (1.0 + LEVEL_BRIGHTEN * (level - 1.0))
    rock = UNPATHABLE_RGB + UNPATHABLE_LEVEL_LIFT * level
    return np.clip(np.where(pathable[..., None], ground, rock), 0, 255)


def to_image_rows(grid: np.ndarray) -> np.ndarray:
    """A map grid indexed [x, y] (y up) as image rows: row 0 is the top of the map (largest y)."""
    return np.swapaxes(grid, 0, 1)[::-1]


def terrain_image(pathable: np.ndarray, cliff: np.ndarray, scale: int) -> np.ndarray:
    """The map at ``scale`` pixels per cell, (map_y*scale, map_x*scale, 3) uint8."""
    pathable = np.asarray(pathable, dtype=bool)
    cliff = np.asarray(cliff, dtype=np.float64)
    if pathable.shape != cliff.shape or pathable.ndim != 2:
        raise ValueError(f"pathable and cliff must be 2-D grids of one shape, got {pathable.shape} and {cliff.shape}")
    colors = to_image_rows(cell_colors(pathable, cliff))
    img = np.repeat(np.repeat(colors, scale, axis=0), scale, axis=1)
    level = np.repeat(np.repeat(to_image_rows(cliff), scale, axis=0), scale, axis=1)
    # An edge pixel is on the high side of a full-level drop to one of its four neighbours.
    edge = np.zeros(level.shape, dtype=bool)
    edge[:, 1:] |= level[:, 1:] - level[:, :-1] >= 1.0
    edge[:, :-1] |= level[:, :-1] - level[:, 1:] >= 1.0
    edge[1:, :] |= level[1:, :] - level[:-1, :] >= 1.0
    edge[:-1, :] |= level[:-1, :] - level[1:, :] >= 1.0
    img[edge] *= CLIFF_EDGE_DARKEN
    return np.rint(img).astype(np.uint8)
