"""Calling a numba kernel past its dispatcher, for call sites whose argument types never change.

numba's dispatcher types every argument on every call, each array inside a bundle included (the engine's serial
step takes about 40 arrays in its bundles, the state's 25 among them: about 6 us, as long as 3m's eight game loops at
B=1). Once a call has compiled, the overload it ran can be called directly; the caller vouches that later arguments
have the same types.
"""

from __future__ import annotations

from typing import Any

__all__ = ["compiled_entry"]


def compiled_entry(kernel: Any, args: tuple) -> Any:
    """The overload numba's dispatcher picks for ``args`` (already compiled), as a function that does not type its
    arguments again; None without the JIT (NUMBA_DISABLE_JIT) or before that overload exists."""
    overloads = getattr(kernel, "overloads", None)
    if overloads is None:
        return None
    compiled = overloads.get(tuple(kernel.typeof_pyval(a) for a in args))
    return None if compiled is None else compiled.entry_point
