"""Reading what a worker process sends without letting it run code in the parent.

``pickle.loads`` calls whatever callable a pickle names, so a worker whose process was subverted (by a script it
hosts, say) could run any command in the parent through one reply. :func:`safe_loads` is ``pickle.loads`` with an
allow-list (the "restricting globals" recipe of Python's pickle documentation): a reply may hold plain values and
containers, NumPy arrays, scalars, dtypes and generators, gymnasium spaces and enums, and exceptions of Python,
NumPy, gymnasium and this package; any other class or function named in the pickle raises :class:`UnsafeReply`
before anything is called. The parent's own messages to its workers are pickled as usual (the parent is trusted).
"""

from __future__ import annotations

import enum
import importlib
import io
import pickle
from typing import Any

__all__ = ["safe_loads", "UnsafeReply", "TRUSTED_PACKAGES"]

TRUSTED_PACKAGES = ("builtins", "numpy", "gymnasium", "smac_hard_gym", "collections", "copyreg")

# Plain callables a pickle of the allowed values names: value constructors that run no user code.
_FUNCTIONS = {
    ("builtins", name) for name in ("set", "frozenset", "slice", "range", "complex", "bytearray", "bytes", "int",
                                    "float", "str", "bool", "tuple", "list", "dict")
} | {
    ("collections", "OrderedDict"), ("copyreg", "_reconstructor"),
    ("numpy", "dtype"), ("numpy", "ndarray"),
    ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar"),
    ("numpy.core.numeric", "_frombuffer"), ("numpy._core.numeric", "_frombuffer"),
    ("numpy.random._pickle", "__generator_ctor"), ("numpy.random._pickle", "__bit_generator_ctor"),
    ("numpy.random._pickle", "__randomstate_ctor"), ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
}


class UnsafeReply(pickle.UnpicklingError):
    """A worker's reply names a class or function the parent does not call while reading."""


def _allowed_class(value: Any) -> bool:
    """Classes whose reconstruction runs no code of a worker's choosing: exceptions, enums, gymnasium spaces,
    NumPy's dtypes, scalar types and bit generators (all from the trusted packages)."""
    if not isinstance(value, type):
        return False
    if issubclass(value, (BaseException, enum.Enum)):
        return True
    module = value.__module__.split(".")[0]
    if module == "gymnasium":
        from gymnasium import spaces

        return issubclass(value, spaces.Space)
    if module == "numpy":
        import numpy as np

        return issubclass(value, (np.dtype, np.generic, np.random.BitGenerator, np.random.Generator,
                                  np.random.SeedSequence))
    return False


class _Unpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if module.split(".")[0] not in TRUSTED_PACKAGES or "." in name:
            raise UnsafeReply(f"a worker's reply names {module}.{name}, which the parent does not load")
        if (module, name) in _FUNCTIONS:
            return super().find_class(module, name)
        try:
            value = getattr(importlib.import_module(module), name)
        except (ImportError, AttributeError) as err:
            raise UnsafeReply(f"a worker's reply names {module}.{name}, which does not exist here") from err
        if not _allowed_class(value):
            raise UnsafeReply(f"a worker's reply names {module}.{name}, which the parent does not load (a worker "
                              "sends plain values, containers, NumPy arrays, gymnasium spaces and exceptions)")
        return value


def safe_loads(data: bytes) -> Any:
    """``pickle.loads(data)`` restricted to the allow-list above; raises :class:`UnsafeReply` otherwise."""
    return _Unpickler(io.BytesIO(data)).load()
