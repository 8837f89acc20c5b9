"""Whether numba's on-disk cache already holds the engine's kernels, so commands can say when a run compiles them.

The first run on a machine (or after the kernels' source changed) compiles them, which takes tens of seconds with no
output of its own; later runs load them from ``__pycache__`` in about a second.
"""

from __future__ import annotations

__all__ = ["kernels_cached", "COMPILING_NOTICE"]

COMPILING_NOTICE = ("compiling the engine's kernels (first run only: numba caches them on disk, later runs start in "
                    "seconds) ...")


def kernels_cached(n_units: int | None = None) -> bool | None:
    """True when the cache holds the engine's step kernel (the serial or the parallel one: which runs depends on the
    batch size) and the feature kernels every env uses, for their current source; False when a run will compile
    them; None when it cannot tell (numba's cache internals moved). ``n_units``: the engine will step big batches
    with kernels compiled for that many units per battle (``BattleEngine``'s ``specialize``): those must be cached
    too."""
    try:
        import hashlib

        from numba.core.serialize import dumps

        from smac_hard_gym.engine import kernels
        from smac_hard_gym.smac import kernels as feature_kernels

        def cached(dispatcher) -> bool:
            # numba's index of cached overloads: empty when missing or written for another version of the source
            index = dispatcher._cache._cache_file._load_index()
            closure = dispatcher.py_func.__closure__
            if not index or closure is None:
                return bool(index)
            # Kernels built by one factory share an index; numba tells them apart by a hash of the closure's values.
            values = hashlib.sha256(dumps(tuple(cell.cell_contents for cell in closure))).hexdigest()
            return any(key[2][1] == values for key in index)

        engine = cached(kernels.step_batch) or cached(kernels.step_battles)
        if n_units is not None:
            engine = cached(kernels.step_kernels_for(n_units)[0])
        return engine and cached(feature_kernels.available_actions_batch) and cached(feature_kernels.finish_encode)
    except Exception:  # an internal numba API: never let it break a command
        return None
