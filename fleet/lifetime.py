"""Children that die with the thread that started them.

`PR_SET_PDEATHSIG` makes the kernel SIGKILL a child when the *thread* that forked it exits, so a
SIGKILLed parent leaves no orphan behind.  Callers must spawn from a thread that lives as long as
the child does (the main thread, or one that does not end before the child).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal

_PR_SET_PDEATHSIG = 1

# Resolved once in the parent: the child, between fork and exec, only makes the call.
_libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
_prctl = _libc.prctl
_prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong]
_prctl.restype = ctypes.c_int


def die_with_parent() -> None:
    """A `preexec_fn` for subprocess.Popen: SIGKILL this child when its parent thread ends."""
    _prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    # The parent may have died between fork and prctl: then we were re-parented already.
    if os.getppid() == 1:
        os._exit(1)
