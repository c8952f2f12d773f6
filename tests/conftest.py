"""Shared fixtures. GL fixtures live further down (marker ``gl``); window tests use ``window``."""
from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest

# `python -m pytest` puts the repository root on sys.path, where framework/, systems/, ... would
# import as bare top-level names (a second copy of every module). driftframe is one package:
# tests see it only as installed, exactly as a user's game does.
_ROOT = Path(__file__).resolve().parent.parent
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != _ROOT]
for _bare in ("framework", "components", "systems", "demos"):
    assert _bare not in sys.modules, f"{_bare!r} was imported as a top-level module"

# pytest keeps each test module's rewritten bytecode in tests/__pycache__ unless bytecode writing is off
# (PYTHONDONTWRITEBYTECODE, set on some machines): then every worker rewrites and compiles all ~90 test modules
# again (~3 s of CPU each). This process only: the environment, and so every child process, keeps the setting
# (tests that edit a copy's sources rely on no stale bytecode there).
sys.dont_write_bytecode = False

from driftframe.framework import access_check
from driftframe.framework.world import World

# the checking mode (framework/access_check.py): a system touching a component, resource or event it does not
# declare is an error in every test of this process (DRIFTFRAME_CHECK_ACCESS=0 turns it off)
access_check.enable(os.environ.get(access_check.ENV, "1") != "0")


_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))


@pytest.fixture(autouse=True)
def _signal_handlers_restored():
    """A test (or the code it calls) must leave the stop signals' handlers and the blocked-signal mask as it
    found them: a child process inherits an ignored or blocked SIGINT (and Python installs no
    KeyboardInterrupt for an ignored one), so a later test's Ctrl-C of a `driftframe` child would go
    unseen, in whichever test shares the process (under two workers, not the same tests every run).
    Restored for the next test either way; the test that changed them fails."""
    before = {s: signal.getsignal(s) for s in _SIGNALS}
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, ())          # blocked signals are inherited too
    yield
    changed = {signal.Signals(s).name: (h, signal.getsignal(s)) for s, h in before.items() if signal.getsignal(s) != h}
    blocked = signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    for s, h in before.items():
        if h is not None:
            signal.signal(s, h)
    assert not changed and blocked == mask, f"signal handlers left changed (before, after): {changed}; " \
                                            f"blocked signals {sorted(mask)} -> {sorted(blocked)}"


@pytest.fixture
def world():
    """A fresh World (dt = 1/60 s) with no systems, closed after the test."""
    w = World()
    yield w
    w.close()


# -- GL (marker ``gl``) ---------------------------------------------------------------------------
@pytest.fixture(scope="session")
def gl_context():
    """One off-screen EGL context for the whole session; skips only when no GL driver exists."""
    from driftframe.framework.gl import GLUnavailableError, create_context

    try:
        ctx = create_context()
    except GLUnavailableError as e:
        if os.environ.get("CI"):      # CI installs Mesa (./run tests): a missing driver there is a failure
            pytest.fail(f"no OpenGL driver in CI: {e}")
        pytest.skip(f"no OpenGL driver: {e}")
    yield ctx
    ctx.release()


@pytest.fixture
def ctx(gl_context):
    """The session's GL context, made current (a test before may have made and released one of its own,
    leaving that one or none current: GL_INVALID_OPERATION here, seen in test_gl after test_cli's in-process
    recordings), checked for GL errors before and after the test (as moderngl's own tests do)."""
    from driftframe.framework.gl import current

    current(gl_context)
    error = gl_context.error
    assert error == "GL_NO_ERROR", f"GL error pending before the test: {error}"
    yield gl_context
    error = gl_context.error
    assert error == "GL_NO_ERROR", f"GL error left by the test: {error}"
