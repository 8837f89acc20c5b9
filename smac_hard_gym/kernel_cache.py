"""Whether numba's on-disk cache already holds the kernels a run will call, so commands can say when (and for about
how long) a run compiles them.

The first run on a machine (or after the kernels' source changed) compiles them, which takes tens of seconds with no
output of its own; later runs load them from ``__pycache__`` (or ``NUMBA_CACHE_DIR``) in about a second.
``benchmarks/compile_time.py`` measures what each kernel costs.
"""

from __future__ import annotations

from typing import Any

__all__ = ["kernels_cached", "missing_kernels", "compile_estimate", "compiling_notice", "COMPILING_NOTICE"]

COMPILING_NOTICE = ("compiling the engine's kernels (first run only: numba caches them on disk, later runs start in "
                    "seconds) ...")

# CPU seconds each kernel took to compile on an empty cache (benchmarks/compile_time.py, numba 0.68, one core; a
# loaded machine takes as much CPU, spread over more wall time). An engine overload counts the helpers it compiles on
# the way (the first overload compiles them for all); a parallel driver's counts its own compile only.
COMPILE_CPU_S = {
    "step_battles": 15.0,
    "step_batch": 7.0,
    "encode_batch": 5.0,
    "finish_encode": 6.0,
    "check_decode_batch": 1.0,
    "terrain": 2.5,
    "batch_ops": 1.0,
}


def _engine_overloads(n_units: int | None, parallel: bool) -> list[tuple[str, Any, tuple]]:
    from smac_hard_gym.engine.kernels import GENERIC, step_batch, step_battles, units_marker

    units = GENERIC if n_units is None else units_marker(n_units)
    suffix = "" if n_units is None else f"[{n_units} units]"
    wanted = [("step_battles" + suffix, step_battles, units)]
    if parallel:
        wanted.append(("step_batch" + suffix, step_batch, units))
    return wanted


def missing_kernels(n_units: int | None = None, parallel: bool = False) -> list[str] | None:
    """The kernels a vector env run would compile (names as in ``COMPILE_CPU_S``, an engine overload for a unit
    count with it in brackets): none when numba's cache holds
    them all for their current source; None when it cannot tell (numba's cache internals moved).

    The engine's serial step kernel (``step_battles``) is always needed (the parallel driver calls it per chunk);
    ``parallel``: the batch is stepped on more than one thread (``step_batch`` too); ``n_units``: the engine steps
    with overloads compiled for that many units per battle (``BattleEngine``'s ``specialize``), else the generic
    ones. The feature kernels every vector env calls (encode observations and masks, check and decode actions), the
    terrain's path tables and the batch bookkeeping are map-independent: one compile serves every map.
    """
    try:
        import numba

        from smac_hard_gym.engine import batch_ops, terrain
        from smac_hard_gym.smac import kernels as feature_kernels

        def index(dispatcher: Any) -> dict:
            # numba's index of cached overloads: empty when missing or written for another version of the source
            return dispatcher._cache._cache_file._load_index()

        missing = []
        for name, dispatcher, units in _engine_overloads(n_units, parallel):
            # An overload is keyed by its signature: the last argument's type (``units``) tells generic from
            # per-unit-count overloads.
            if not any(key[0][-1] == numba.typeof(units) for key in index(dispatcher)):
                missing.append(name)
        # (The mask-only kernel, available_actions_batch, serves StarCraft2Env's per-agent queries; a vector env
        # never compiles it, so requiring it made every run look cold.)
        for name in ("encode_batch", "finish_encode", "check_decode_batch"):
            if not index(getattr(feature_kernels, name)):
                missing.append(name)
        groups = {"terrain": (terrain._distance_field, terrain._next_hops_from_fields, terrain._line_of_sight),
                  "batch_ops": (batch_ops.reset_battles,)}  # (count_alive serves benchmarks and tests)
        for name, dispatchers in groups.items():
            if not all(index(d) for d in dispatchers):
                missing.append(name)
        return missing
    except Exception:  # an internal numba API: never let it break a command
        return None


def kernels_cached(n_units: int | None = None, parallel: bool = False) -> bool | None:
    """True when numba's cache holds every kernel ``missing_kernels(n_units, parallel)`` checks, False when a run
    will compile some, None when it cannot tell."""
    missing = missing_kernels(n_units, parallel)
    return None if missing is None else not missing


def compile_estimate(missing: list[str]) -> float:
    """CPU seconds the ``missing`` kernels take to compile (``COMPILE_CPU_S``)."""
    return sum(COMPILE_CPU_S.get(name.split("[")[0], 0.0) for name in missing)


def compiling_notice(missing: list[str] | None) -> str:
    """The line a command prints before it compiles ``missing`` (None: unknown, the generic notice)."""
    if not missing:
        return COMPILING_NOTICE
    seconds = compile_estimate(missing)
    return (f"compiling the engine's kernels: about {seconds:.0f} s of CPU time, longer on a busy machine (first run "
            f"only: numba caches them on disk, later runs start in seconds; {', '.join(missing)}) ...")
