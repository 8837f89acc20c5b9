"""A tiny 3x5 bitmap font, so frames carry text without a font file or Pillow (and look the same everywhere).

Glyphs are upper case; lower-case text is drawn upper case and unknown characters as ``?``. Each glyph is five rows of
three cells, ``#`` on; characters advance four cells (one blank column between them).
"""

from __future__ import annotations

import numpy as np

GLYPH_ROWS, GLYPH_COLS, ADVANCE = 5, 3, 4

_GLYPHS = {
    "A": ".#. #.# ### #.# #.#", "B": "##. #.# ##. #.# ##.", "C": ".## #.. #.. #.. .##",
    "D": "##. #.# #.# #.# ##.", "E": "### #.. ##. #.. ###", "F": "### #.. ##. #.. #..",
    "G": ".## #.. #.# #.# .##", "H": "#.# #.# ### #.# #.#", "I": "### .#. .#. .#. ###",
    "J": "..# ..# ..# #.# .#.", "K": "#.# #.# ##. #.# #.#", "L": "#.. #.. #.. #.. ###",
    "M": "#.# ### ### #.# #.#", "N": "##. #.# #.# #.# #.#", "O": ".#. #.# #.# #.# .#.",
    "P": "##. #.# ##. #.. #..", "Q": ".#. #.# #.# ##. .##", "R": "##. #.# ##. #.# #.#",
    "S": ".## #.. .#. ..# ##.", "T": "### .#. .#. .#. .#.", "U": "#.# #.# #.# #.# ###",
    "V": "#.# #.# #.# #.# .#.", "W": "#.# #.# ### ### #.#", "X": "#.# #.# .#. #.# #.#",
    "Y": "#.# #.# .#. .#. .#.", "Z": "### ..# .#. #.. ###",
    "0": "### #.# #.# #.# ###", "1": ".#. ##. .#. .#. ###", "2": "##. ..# .#. #.. ###",
    "3": "##. ..# .#. ..# ##.", "4": "#.# #.# ### ..# ..#", "5": "### #.. ##. ..# ##.",
    "6": ".## #.. ### #.# ###", "7": "### ..# .#. .#. .#.", "8": "### #.# ### #.# ###",
    "9": "### #.# ### ..# ##.",
    " ": "... ... ... ... ...", "-": "... ... ### ... ...", "_": "... ... ... ... ###",
    ":": "... .#. ... .#. ...", ".": "... ... ... ... .#.", ",": "... ... ... .#. #..",
    "/": "..# ..# .#. #.. #..", "#": "#.# ### #.# ### #.#", "+": "... .#. ### .#. ...",
    "(": ".#. #.. #.. #.. .#.", ")": ".#. ..# ..# ..# .#.", "=": "... ### ... ### ...",
    "?": "##. ..# .#. ... .#.", "%": "#.# ..# .#. #.. #.#", "<": "..# .#. #.. .#. ..#",
    ">": "#.. .#. ..# .#. #..", "|": ".#. .#. .#. .#. .#.", "*": "... #.# .#. #.# ...",
}


def _bitmap(rows: str) -> np.ndarray:
    return np.array([[ch == "#" for ch in row] for row in rows.split()], dtype=bool)


GLYPHS: dict[str, np.ndarray] = {ch: _bitmap(rows) for ch, rows in _GLYPHS.items()}


def glyph(ch: str) -> np.ndarray:
    """The (5, 3) bool bitmap of one character."""
    return GLYPHS.get(ch.upper(), GLYPHS["?"])


def text_mask(text: str, scale: int = 1) -> np.ndarray:
    """Bool mask of ``text`` in one line, each font cell drawn as ``scale`` x ``scale`` pixels."""
    if scale < 1:
        raise ValueError(f"text scale must be >= 1, got {scale!r}")
    width = max(len(text) * ADVANCE - 1, 0)
    mask = np.zeros((GLYPH_ROWS, width), dtype=bool)
    for i, ch in enumerate(text):
        mask[:, i * ADVANCE: i * ADVANCE + GLYPH_COLS] = glyph(ch)
    return np.repeat(np.repeat(mask, scale, axis=0), scale, axis=1)


def text_size(text: str, scale: int = 1) -> tuple[int, int]:
    """(height, width) in pixels of ``text`` drawn at ``scale``."""
    return GLYPH_ROWS * scale, max(len(text) * ADVANCE - 1, 0) * scale
