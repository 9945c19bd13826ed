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
_signal = _libc.signal
_signal.argtypes = [ctypes.c_int, ctypes.c_void_p]
_signal.restype = ctypes.c_void_p
_SIG_IGN = 1


def die_with_parent() -> None:
    """A `preexec_fn` for subprocess.Popen: SIGKILL this child when its parent thread ends."""
    _prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    # The parent may have died between fork and prctl: then we were re-parented already.
    if os.getppid() == 1:
        os._exit(1)


def helper_of_parent() -> None:
    """A `preexec_fn` for a helper its parent stops itself: it dies with its parent, and ignores
    Ctrl-C, which reaches the terminal's whole process group.  Ignored here, before exec, SIGINT
    stays ignored while the helper's Python starts (Python then installs no KeyboardInterrupt):
    a Ctrl-C in its first second had it print a traceback from its imports.  libc's signal, not
    Python's, which refuses to run outside the main thread (the parent may spawn from another)."""
    die_with_parent()
    _signal(signal.SIGINT, _SIG_IGN)
