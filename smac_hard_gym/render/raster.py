"""Drawing primitives on an RGB image (H, W, 3) uint8, in pixel coordinates, pure NumPy.

Pixel ``(r, c)`` covers ``[r, r+1) x [c, c+1)``; a shape covers the pixels whose centres ``(r+0.5, c+0.5)`` fall inside
it. Everything clips at the image border, so callers never check bounds.
"""

from __future__ import annotations

import numpy as np

Color = tuple[int, int, int]


def _box(img: np.ndarray, r0: float, c0: float, r1: float, c1: float) -> tuple[int, int, int, int]:
    h, w = img.shape[:2]
    return (max(int(np.floor(r0)), 0), max(int(np.floor(c0)), 0),
            min(int(np.ceil(r1)), h), min(int(np.ceil(c1)), w))


def _disc_mask(img: np.ndarray, row: float, col: float, radius: float) -> tuple[tuple[slice, slice], np.ndarray]:
    r0, c0, r1, c1 = _box(img, row - radius, col - radius, row + radius + 1, col + radius + 1)
    rr = np.arange(r0, r1)[:, None] + 0.5 - row
    cc = np.arange(c0, c1)[None, :] + 0.5 - col
    return (slice(r0, r1), slice(c0, c1)), rr * rr + cc * cc <= radius * radius


def fill_rect(img: np.ndarray, r0: float, c0: float, r1: float, c1: float, color: Color) -> None:
    """Fill rows [r0, r1) and columns [c0, c1)."""
    a, b, c, d = _box(img, r0, c0, r1, c1)
    if a < c and b < d:
        img[a:c, b:d] = color


def fill_disc(img: np.ndarray, row: float, col: float, radius: float, color: Color) -> None:
    window, mask = _disc_mask(img, row, col, radius)
    img[window][mask] = color


def ring(img: np.ndarray, row: float, col: float, radius: float, width: float, color: Color) -> None:
    """A circle outline: pixels between ``radius - width`` and ``radius`` from the centre."""
    r0, c0, r1, c1 = _box(img, row - radius, col - radius, row + radius + 1, col + radius + 1)
    rr = np.arange(r0, r1)[:, None] + 0.5 - row
    cc = np.arange(c0, c1)[None, :] + 0.5 - col
    d2 = rr * rr + cc * cc
    inner = max(radius - width, 0.0)
    img[r0:r1, c0:c1][(d2 <= radius * radius) & (d2 > inner * inner)] = color


def blend_disc(img: np.ndarray, row: float, col: float, radius: float, color: Color, alpha: float) -> None:
    """Mix ``color`` into a disc with opacity ``alpha`` (0..1)."""
    window, mask = _disc_mask(img, row, col, radius)
    patch = img[window]
    mixed = (1.0 - alpha) * patch[mask] + alpha * np.asarray(color, dtype=np.float64)
    patch[mask] = np.clip(np.rint(mixed), 0, 255).astype(np.uint8)


def line(img: np.ndarray, r0: float, c0: float, r1: float, c1: float, color: Color, width: int = 1) -> None:
    """A straight segment ``width`` pixels thick, drawn by sampling every half pixel along it."""
    length = float(np.hypot(r1 - r0, c1 - c0))
    t = np.linspace(0.0, 1.0, max(int(length * 2) + 2, 2))
    rows = np.floor(r0 + (r1 - r0) * t).astype(np.int64)
    cols = np.floor(c0 + (c1 - c0) * t).astype(np.int64)
    h, w = img.shape[:2]
    lo = -(width // 2)
    for dr in range(lo, lo + width):
        for dc in range(lo, lo + width):
            rr, cc = rows + dr, cols + dc
            keep = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w)
            img[rr[keep], cc[keep]] = color


def paint_mask(img: np.ndarray, mask: np.ndarray, row: int, col: int, color: Color) -> None:
    """Paint ``color`` where ``mask`` is True, with the mask's top-left corner at pixel (row, col)."""
    h, w = img.shape[:2]
    r0, c0 = max(row, 0), max(col, 0)
    r1, c1 = min(row + mask.shape[0], h), min(col + mask.shape[1], w)
    if r0 >= r1 or c0 >= c1:
        return
    img[r0:r1, c0:c1][mask[r0 - row: r1 - row, c0 - col: c1 - col]] = color
