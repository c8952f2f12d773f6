"""Shared fixtures. GL fixtures live further down (marker ``gl``); window tests use ``window``."""
from __future__ import annotations

import os

import pytest

from driftframe.framework.world import World


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
    """The session's GL context, checked for GL errors before and after the test (as moderngl's own tests do)."""
    error = gl_context.error
    assert error == "GL_NO_ERROR", f"GL error pending before the test: {error}"
    yield gl_context
    error = gl_context.error
    assert error == "GL_NO_ERROR", f"GL error left by the test: {error}"
