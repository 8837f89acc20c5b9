"""Child processes never outlive their parent: the one Linux call every kind of child makes at its start.

:func:`die_with_parent` is called first thing in a child (worker processes, sandboxed scripts, benchmark probes);
:func:`die_with_parent_hook` builds the ``preexec_fn`` for ``subprocess.Popen`` when the child runs another program
(StarCraft II), resolving ``prctl`` before the fork so that nothing is loaded between fork and exec.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable

__all__ = ["die_with_parent", "die_with_parent_hook"]

_PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Linux: ask the kernel to SIGKILL the calling process when its parent dies (elsewhere: nothing)."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL))
        except (OSError, AttributeError):
            pass


def die_with_parent_hook() -> Callable[[], None] | None:
    """Linux: a ``preexec_fn`` that makes the child die with the calling process (and exit at once if that one died
    before the signal was armed); None elsewhere, or when ``prctl`` cannot be found.

    The kernel sends the signal when the *thread* that forked the child ends, so start such children from a thread
    that lives as long as the process (the main thread).
    """
    if not sys.platform.startswith("linux"):
        return None
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl  # resolved before fork: nothing to load in the child
    except (OSError, AttributeError):
        return None
    parent = os.getpid()

    def hook() -> None:
        prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        if os.getppid() != parent:  # the parent died before the signal was armed
            os._exit(1)

    return hook
