"""Calling a numba kernel past its dispatcher, for call sites whose argument types never change.

numba's dispatcher types every argument on every call, each array inside a bundle included (the engine's serial
step takes about 40 arrays in its bundles, the state's 25 among them: about 6 us, as long as 3m's eight game loops at
B=1). Once a call has compiled, the overload it ran can be called directly; the caller vouches that later arguments
have the same types.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["compiled_entry", "is_plain", "DirectKernel"]


def compiled_entry(kernel: Any, args: tuple) -> Any:
    """The overload numba's dispatcher picks for ``args`` (already compiled), as a function that does not type its
    arguments again; None without the JIT (NUMBA_DISABLE_JIT) or before that overload exists."""
    overloads = getattr(kernel, "overloads", None)
    if overloads is None:
        return None
    compiled = overloads.get(tuple(kernel.typeof_pyval(a) for a in args))
    return None if compiled is None else compiled.entry_point


def is_plain(array: object, dtype: np.dtype, ndim: int) -> bool:
    """A writable, aligned, C-contiguous ``dtype`` array of ``ndim`` dimensions: the one array type a direct call
    site compiles for (what the engine and the env layers allocate, and what action validation returns)."""
    if type(array) is not np.ndarray or array.dtype is not dtype or array.ndim != ndim:
        return False
    flags = array.flags
    return flags.c_contiguous and flags.writeable and flags.aligned


class DirectKernel:
    """A kernel called past numba's dispatcher (:func:`compiled_entry`) once a ``plain`` call has compiled it.

    The dispatcher types every argument on every call, and typing the bundles (a few dozen fields) costs more than
    encoding a few battles. A call site passes ``plain=True`` only when every argument has the types of its first
    plain call: its own bundles, and arrays checked with :func:`is_plain`; other calls go through the dispatcher.
    """

    def __init__(self, kernel: object) -> None:
        self.kernel = kernel
        self.entry: object = None

    def __call__(self, plain: bool, *args: object) -> object:
        if plain and self.entry is not None:
            return self.entry(*args)
        result = self.kernel(*args)
        if plain:
            self.entry = compiled_entry(self.kernel, args)
        return result
