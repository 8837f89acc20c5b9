"""Top-down frames of a battle: terrain, units, bars, attack and heal links, baneling bursts and a header line.

World ``(x, y)`` maps to pixel ``(row, col) = (header + (map_y - y) * scale, x * scale)``: x to the right, y up, and
a header band of text above the map. A unit is a filled disc of its true radius in its side's colour (red = learner,
blue = opponent) with its type letter inside (see :data:`UNIT_GLYPHS`); air units get a light outline; dead units
leave a small dark cross. Above each living unit sit a health bar and, for protoss, a shield bar.

The renderer reads only ``utype, side, alive, x, y, health, shield, fired_at, burst, loop`` of a state, converted to
float32 first, so a recorded episode (stored in float32) replays to identical frames.
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np

from smac_hard_gym.engine.state import BLUE, RED
from smac_hard_gym.engine.units import UNITS, WEAPON_HEAL
from smac_hard_gym.render import raster
from smac_hard_gym.render.background import terrain_image
from smac_hard_gym.render.font import text_mask, text_size

DEFAULT_SCALE = 16  # pixels per map cell: a 32x32 SMAC map becomes 512x512 plus the header
MAX_SCALE = 64

SIDE_RGB = {RED: (214, 48, 49), BLUE: (38, 112, 230)}
SIDE_NAMES = {RED: "RED", BLUE: "BLUE"}
ATTACK_RGB = {RED: (255, 150, 60), BLUE: (110, 200, 255)}  # an attack line takes its shooter's side tint
HEAL_RGB = (70, 240, 110)
BURST_RGB, BURST_EDGE_RGB, BURST_ALPHA = (255, 200, 40), (255, 120, 0), 0.5
GLYPH_RGB = (255, 255, 255)
AIR_OUTLINE_RGB = (235, 235, 235)
DEAD_RGB = {RED: (90, 30, 30), BLUE: (25, 45, 90)}
BAR_BACK_RGB, HEALTH_RGB, SHIELD_RGB = (25, 25, 25), (70, 215, 80), (100, 210, 255)
HEADER_RGB, TEXT_RGB = (16, 16, 20), (235, 235, 235)
GRID_GAP_RGB = (0, 0, 0)

# One letter per unit family (the *_RL variants share their base unit's letter).
UNIT_GLYPHS = {
    "marine": "M", "marauder": "R", "medivac": "+", "stalker": "S", "zealot": "Z", "colossus": "C",
    "hydralisk": "H", "zergling": "G", "baneling": "B", "spine_crawler": "K",
}
GLYPH_HEIGHT_PER_RADIUS = 1.3  # a glyph is at most 1.3 radii tall: it stays inside the disc's inscribed square

# Per-type drawing facts, looked up by ``utype`` (the row of the unit table).
_RADIUS = np.array([u.radius for u in UNITS])
_HEALTH_MAX = np.array([u.health for u in UNITS])
_SHIELD_MAX = np.array([u.shield for u in UNITS])
_IS_AIR = np.array([u.is_air for u in UNITS])
_HEALS = np.array([u.weapon == WEAPON_HEAL for u in UNITS])
_SPLASH_RADIUS = np.array([u.splash_radius for u in UNITS])
_GLYPH = [UNIT_GLYPHS.get(u.base, "?") for u in UNITS]


def _load_terrain(spec: Any) -> Any:
    if isinstance(spec, (str, os.PathLike)):
        from smac_hard_gym.maps import load_map

        return load_map(spec)
    missing = [name for name in ("name", "size", "pathable", "cliff") if not hasattr(spec, name)]
    if missing:
        raise TypeError(f"spec must be a MapSpec, a map name or an object with name/size/pathable/cliff; "
                        f"{type(spec).__name__} lacks {', '.join(missing)}")
    return spec


class BattleRenderer:
    """Draws one battle of a :class:`~smac_hard_gym.engine.state.BattleState` as an RGB array (H, W, 3) uint8.

    ``spec`` is a :class:`~smac_hard_gym.maps.MapSpec`, a map name, or anything with ``name``, ``size``, ``pathable``
    and ``cliff`` (an :class:`~smac_hard_gym.render.recorder.Episode`'s ``terrain``). ``scale`` is pixels per map
    cell; ``step_mul`` turns a battle's game loop into the step shown when no ``step`` is given.

    >>> renderer = BattleRenderer("3m", scale=8)
    >>> renderer.frame_shape
    (265, 256, 3)
    """

    def __init__(self, spec: Any, scale: int | None = None, step_mul: int = 8) -> None:
        scale = DEFAULT_SCALE if scale is None else scale
        if not isinstance(scale, (int, np.integer)) or isinstance(scale, bool) or not 1 <= scale <= MAX_SCALE:
            raise ValueError(f"scale must be an int pixels-per-cell in 1..{MAX_SCALE}, got {scale!r}")
        if not isinstance(step_mul, (int, np.integer)) or step_mul < 1:
            raise ValueError(f"step_mul must be a positive int, got {step_mul!r}")
        self.spec = _load_terrain(spec)
        self.scale = int(scale)
        self.step_mul = int(step_mul)
        self.map_x, self.map_y = (int(v) for v in self.spec.size)
        self.text_scale = max(1, self.scale // 8)
        self.header = text_size("A", self.text_scale)[0] + 4 * self.text_scale
        self._background = np.empty((self.header + self.map_y * self.scale, self.map_x * self.scale, 3), np.uint8)
        self._background[: self.header] = HEADER_RGB
        self._background[self.header:] = terrain_image(self.spec.pathable, self.spec.cliff, self.scale)

    def __repr__(self) -> str:
        return f"BattleRenderer(map={self.spec.name!r}, scale={self.scale}, frame_shape={self.frame_shape})"

    @property
    def frame_shape(self) -> tuple[int, int, int]:
        return self._background.shape

    def world_to_pixel(self, x: Any, y: Any) -> tuple[Any, Any]:
        """Continuous pixel coordinates (row, col) of world points."""
        row = self.header + (self.map_y - np.asarray(y, np.float64)) * self.scale
        return row, np.asarray(x, np.float64) * self.scale

    # ---------------------------------------------------------------------------------------------------------
    # Frames.

    def render(self, state: Any, battle: int = 0, step: int | None = None, opponent_name: str | None = None,
               title: str | None = None) -> np.ndarray:
        """One frame of battle ``battle``; the header shows ``title`` (default: the map name), the step and the
        opponent's name, and the alive count of each side."""
        n_battles = np.shape(state.x)[0]
        if not isinstance(battle, (int, np.integer)) or not 0 <= battle < n_battles:
            raise ValueError(f"battle must be an int in 0..{n_battles - 1}, got {battle!r}")
        units = self._units(state, int(battle))
        if step is None:
            step = int(np.asarray(state.loop)[battle]) // self.step_mul
        img = self._background.copy()
        self._draw_bursts(img, units)
        self._draw_links(img, units)
        self._draw_units(img, units)
        self._draw_header(img, units, title if title is not None else self.spec.name, int(step), opponent_name)
        return img

    def render_grid(self, state: Any, battles: Any = None, cols: int | None = None, steps: Any = None,
                    opponent_names: Any = None) -> np.ndarray:
        """Frames of several battles tiled row by row (``cols`` per row, default about square); each tile's title
        is ``#b``. ``steps`` and ``opponent_names`` are per listed battle."""
        n_battles = np.shape(state.x)[0]
        battles = list(range(n_battles)) if battles is None else [int(b) for b in np.atleast_1d(battles)]
        if not battles:
            raise ValueError("render_grid needs at least one battle")
        for name, values in (("steps", steps), ("opponent_names", opponent_names)):
            if values is not None and len(values) != len(battles):
                raise ValueError(f"{name} must have one entry per battle ({len(battles)}), got {len(values)}")
        frames = [self.render(state, b, None if steps is None else steps[i],
                              None if opponent_names is None else opponent_names[i], title=f"#{b}")
                  for i, b in enumerate(battles)]
        return tile_frames(frames, cols)

    # ---------------------------------------------------------------------------------------------------------
    # Layers.

    def _units(self, state: Any, b: int) -> dict[str, np.ndarray]:
        utype = np.asarray(state.utype[b], dtype=np.int64)
        row, col = self.world_to_pixel(np.asarray(state.x[b], np.float32), np.asarray(state.y[b], np.float32))
        return {
            "utype": utype, "side": np.asarray(state.side[b], dtype=np.int64),
            "alive": np.asarray(state.alive[b], dtype=bool), "row": row, "col": col,
            "radius": _RADIUS[utype] * self.scale,
            "health": np.asarray(state.health[b], np.float32) / _HEALTH_MAX[utype],
            "shield": np.asarray(state.shield[b], np.float32) / np.maximum(_SHIELD_MAX[utype], 1.0),
            "fired_at": np.asarray(state.fired_at[b], dtype=np.int64),
            "burst": np.asarray(state.burst[b], dtype=bool),
        }

    def _draw_bursts(self, img: np.ndarray, u: dict[str, np.ndarray]) -> None:
        for i in np.flatnonzero(u["burst"]):
            radius = max(_SPLASH_RADIUS[u["utype"][i]] * self.scale, 1.0)
            raster.blend_disc(img, u["row"][i], u["col"][i], radius, BURST_RGB, BURST_ALPHA)
            raster.ring(img, u["row"][i], u["col"][i], radius, max(1, self.scale // 8), BURST_EDGE_RGB)

    def _draw_links(self, img: np.ndarray, u: dict[str, np.ndarray]) -> None:
        n = len(u["utype"])
        width = max(1, self.scale // 12)
        for i in np.flatnonzero((u["fired_at"] >= 0) & (u["fired_at"] < n)):
            j = u["fired_at"][i]
            color = HEAL_RGB if _HEALS[u["utype"][i]] else ATTACK_RGB[int(u["side"][i])]
            raster.line(img, u["row"][i], u["col"][i], u["row"][j], u["col"][j], color, width)

    def _draw_units(self, img: np.ndarray, u: dict[str, np.ndarray]) -> None:
        for i in np.flatnonzero(~u["alive"]):
            arm = max(u["radius"][i] * 0.5, 1.5)
            r, c = u["row"][i], u["col"][i]
            color = DEAD_RGB[int(u["side"][i])]
            raster.line(img, r - arm, c - arm, r + arm, c + arm, color)
            raster.line(img, r - arm, c + arm, r + arm, c - arm, color)
        alive = np.flatnonzero(u["alive"])
        for i in sorted(alive, key=lambda k: _IS_AIR[u["utype"][k]]):  # air units above ground units
            self._draw_unit(img, u, int(i))
        for i in alive:
            self._draw_bars(img, u, int(i))

    def _draw_unit(self, img: np.ndarray, u: dict[str, np.ndarray], i: int) -> None:
        r, c, radius, t = u["row"][i], u["col"][i], u["radius"][i], u["utype"][i]
        raster.fill_disc(img, r, c, radius, SIDE_RGB[int(u["side"][i])])
        if _IS_AIR[t]:
            raster.ring(img, r, c, radius, max(1.0, self.scale / 16), AIR_OUTLINE_RGB)
        glyph_scale = int(GLYPH_HEIGHT_PER_RADIUS * radius // 5)
        if glyph_scale >= 1:
            mask = text_mask(_GLYPH[t], glyph_scale)
            raster.paint_mask(img, mask, int(math.floor(r)) - mask.shape[0] // 2,
                              int(math.floor(c)) - mask.shape[1] // 2, GLYPH_RGB)

    def _draw_bars(self, img: np.ndarray, u: dict[str, np.ndarray], i: int) -> None:
        radius, t = u["radius"][i], u["utype"][i]
        width = max(2.0 * radius, 6.0)
        height = max(1, self.scale // 8)
        left = math.floor(u["col"][i] - width / 2)
        bottom = math.floor(u["row"][i] - radius) - 1
        bars = [(u["health"][i], HEALTH_RGB)]
        if _SHIELD_MAX[t] > 0:
            bars.append((u["shield"][i], SHIELD_RGB))
        for k, (fraction, color) in enumerate(bars):
            top = bottom - (k + 1) * height
            raster.fill_rect(img, top, left, top + height, left + width, BAR_BACK_RGB)
            filled = round(width * float(np.clip(fraction, 0.0, 1.0)))
            raster.fill_rect(img, top, left, top + height, left + filled, color)

    def _draw_header(self, img: np.ndarray, u: dict[str, np.ndarray], title: str, step: int,
                     opponent_name: str | None) -> None:
        ts, pad = self.text_scale, 2 * self.text_scale
        counts = [f"{SIDE_NAMES[s]} {int(np.sum(u['alive'] & (u['side'] == s)))}" for s in (RED, BLUE)]
        right = img.shape[1] - pad
        for side, text in zip((BLUE, RED), reversed(counts), strict=True):  # right-aligned, blue count last
            mask = text_mask(text, ts)
            right -= mask.shape[1]
            raster.paint_mask(img, mask, pad, right, SIDE_RGB[side])
            right -= 2 * ts * 4
        left_text = f"{title} STEP {step}" + (f" VS {opponent_name}" if opponent_name else "")
        room = max((right - pad) // (4 * ts), 0)  # characters that fit before the counts
        raster.paint_mask(img, text_mask(left_text[:room], ts), pad, pad, TEXT_RGB)


def tile_frames(frames: list[np.ndarray], cols: int | None = None, gap: int = 2) -> np.ndarray:
    """Tile equal-sized frames row by row, ``cols`` per row (default: about square), ``gap`` pixels apart."""
    if not frames:
        raise ValueError("tile_frames needs at least one frame")
    shape = frames[0].shape
    if any(f.shape != shape for f in frames):
        raise ValueError(f"all frames must share one shape, got {sorted({f.shape for f in frames})}")
    n = len(frames)
    cols = math.ceil(math.sqrt(n)) if cols is None else cols
    if not isinstance(cols, (int, np.integer)) or cols < 1:
        raise ValueError(f"cols must be a positive int, got {cols!r}")
    cols = min(int(cols), n)
    rows = math.ceil(n / cols)
    h, w = shape[:2]
    out = np.empty((rows * h + (rows - 1) * gap, cols * w + (cols - 1) * gap, 3), dtype=np.uint8)
    out[:] = GRID_GAP_RGB
    for k, frame in enumerate(frames):
        r, c = divmod(k, cols)
        out[r * (h + gap): r * (h + gap) + h, c * (w + gap): c * (w + gap) + w] = frame
    return out
