"""Dynamic scheduling of battles over numba's worker threads.

numba's ``prange`` splits a loop into one fixed block per thread. On a shared machine one thread is often
descheduled for a while; with fixed blocks the other thread then finishes early and waits. Instead, each worker
takes the next few battles from a shared counter until none are left, so a busy core gives its work to an idle one.
numba has no atomic operations on the CPU, hence the small intrinsic below.
"""

from __future__ import annotations

import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic, overload

CHUNKS_PER_THREAD = 32  # battles are handed out in about this many chunks per thread: small enough to balance


def fetch_add(counter: np.ndarray, value: int) -> int:
    """Add ``value`` to ``counter[0]`` and return the value it held before; atomic in compiled code.

    ``counter`` is a 1-D int64 array. This Python body runs only without the JIT (one thread, nothing to race).
    """
    old = int(counter[0])
    counter[0] += value
    return old


@intrinsic
def _atomic_fetch_add(typingctx, counter, value):
    if not (isinstance(counter, types.Array) and counter.dtype == types.int64 and counter.ndim == 1):
        return None
    if not isinstance(value, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        array_type, value_type = signature.args
        array = context.make_array(array_type)(context, builder, args[0])
        pointer = cgutils.get_item_pointer(context, builder, array_type, array, [context.get_constant(types.intp, 0)])
        amount = context.cast(builder, args[1], value_type, types.int64)
        return builder.atomic_rmw("add", pointer, amount, "monotonic")

    return types.int64(counter, value), codegen


@overload(fetch_add, jit_options={"cache": True})
def _fetch_add_compiled(counter, value):
    def implementation(counter, value):
        return _atomic_fetch_add(counter, value)

    return implementation
