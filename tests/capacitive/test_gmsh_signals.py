"""gmsh's initialize resets signal actions (SIGPIPE to its default: a write to a closed pipe would end the
process); a meshing session leaves them as they were."""

from __future__ import annotations

import ctypes
import faulthandler
import os
import signal
import threading

from twinsense.capacitive.gmsh_mesher import _GMSH_RESETS, _import_gmsh, _session, _sigaction


def _actions() -> dict[str, bytes]:
    """Each signal's handler (SIG_DFL, SIG_IGN or a function's address): the first member of struct
    sigaction on Linux and macOS (the rest of the buffer holds padding the C library may not write)."""
    sigaction = _sigaction()
    out = {}
    for name in _GMSH_RESETS:
        buf = ctypes.create_string_buffer(512)
        assert sigaction(int(getattr(signal, name)), None, buf) == 0
        out[name] = buf.raw[:ctypes.sizeof(ctypes.c_void_p)]
    return out


def _write_to_a_closed_pipe() -> str:
    """What a write to a pipe with no reader does in this process (with SIGPIPE at its default action the
    process would end here, and the test run with it)."""
    r, w = os.pipe()
    os.close(r)
    try:
        os.write(w, b"x")
    except BrokenPipeError:
        return "BrokenPipeError"
    finally:
        os.close(w)
    return "written"


def _session_on(thread: bool) -> dict[str, bytes]:
    """The actions seen inside a fresh gmsh session, opened on this thread or on another one."""
    gmsh = _import_gmsh()
    assert not gmsh.isInitialized()  # a session of its own: initialize runs
    seen = {}

    def run():
        with _session(gmsh, {}):
            seen.update(_actions())

    if thread:
        t = threading.Thread(target=run)
        t.start()
        t.join()
    else:
        run()
    return seen


def test_a_gmsh_session_keeps_sigpipe_ignored_and_the_crash_handlers():
    was = faulthandler.is_enabled()
    faulthandler.enable()  # handlers on SIGSEGV, SIGFPE, SIGBUS and SIGILL, as pytest installs them
    try:
        before = _actions()
        assert signal.getsignal(signal.SIGPIPE) == signal.SIG_IGN  # as Python starts
        for thread in (False, True):  # a mesh may be built on a capture thread
            inside = _session_on(thread)
            after = _actions()
            # Without the fix, all five actions read SIG_DFL inside and after the session.
            assert inside == before
            assert after == before
            assert _write_to_a_closed_pipe() == "BrokenPipeError"
    finally:
        if not was:
            faulthandler.disable()
