"""The one place a GL context is made; the render target and its read-back."""
from __future__ import annotations

import moderngl
import numpy as np
import pytest

from driftframe.framework import gl


def test_missing_driver_error_names_what_is_missing_and_the_packages():
    missing = gl.missing_pieces(can_load=lambda so: so != "libEGL_mesa.so.0", find_dri=lambda: False)
    msg = gl.explain_failure(Exception("eglGetDisplay failed"), missing)
    assert "Mesa's EGL driver (libEGL_mesa.so.0)" in msg
    assert "swrast_dri.so" in msg
    assert "apt-get install -y --no-install-recommends libegl-mesa0 libgl1-mesa-dri" in msg
    assert "eglGetDisplay failed" in msg


def test_create_context_turns_a_loader_failure_into_a_clear_error(monkeypatch):
    def fail(**kwargs):
        raise Exception("libEGL.so: cannot open shared object file")

    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    monkeypatch.setattr(gl, "_can_load", lambda so: so not in ("libEGL.so.1", "libGL.so.1"))
    monkeypatch.setattr(gl, "_find_dri_driver", lambda: True)
    with pytest.raises(gl.GLUnavailableError) as info:
        gl.create_context()
    msg = str(info.value)
    assert "the EGL loader (libEGL.so.1)" in msg and "the GL dispatch library (libGL.so.1)" in msg
    assert "apt-get install -y --no-install-recommends libegl1 libgl1" in msg
    assert info.value.__cause__ is None          # no traceback from inside the loader


def test_a_real_loader_failure_becomes_a_clear_error():
    with pytest.raises(gl.GLUnavailableError) as info:
        gl.create_context(libegl="libEGL_driftframe_missing.so.1")
    msg = str(info.value)
    assert msg.startswith("Could not create an off-screen OpenGL context")
    assert "libEGL_driftframe_missing.so.1" in msg and "libgl1-mesa-dri" in msg


def test_create_context_with_all_libraries_present_still_names_the_packages(monkeypatch):
    monkeypatch.setattr(moderngl, "create_standalone_context",
                        lambda **kw: (_ for _ in ()).throw(Exception("no EGL display")))
    monkeypatch.setattr(gl, "_can_load", lambda so: True)
    monkeypatch.setattr(gl, "_find_dri_driver", lambda: True)
    with pytest.raises(gl.GLUnavailableError, match="libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri"):
        gl.create_context()


def test_wrap_current_context_failure_says_to_make_a_window_current(monkeypatch):
    monkeypatch.setattr(moderngl, "create_context",
                        lambda **kw: (_ for _ in ()).throw(Exception("cannot detect OpenGL context")))
    with pytest.raises(gl.GLUnavailableError, match="make_context_current"):
        gl.wrap_current_context()


@pytest.mark.gl
def test_off_screen_context_offers_opengl_330_or_newer(ctx):
    assert ctx.version_code >= gl.REQUIRE
    assert gl.renderer(ctx) != "unknown"


@pytest.mark.gl
def test_read_rgba_returns_the_top_row_first(ctx):
    target = gl.RenderTarget(ctx, (8, 6))
    try:
        target.use()
        ctx.clear(0.0, 0.0, 1.0, 1.0)
        ctx.scissor = (0, 3, 8, 3)                 # GL's y is from the bottom: this is the top half
        ctx.clear(1.0, 0.0, 0.0, 1.0)
        ctx.scissor = None
        img = target.read_rgba()
        assert img.shape == (6, 8, 4) and img.dtype == np.uint8
        np.testing.assert_array_equal(img[:3].reshape(-1, 4), [[255, 0, 0, 255]] * 24)
        np.testing.assert_array_equal(img[3:].reshape(-1, 4), [[0, 0, 255, 255]] * 24)
        raw = np.frombuffer(target.read_raw(), np.uint8).reshape(6, 8, 4)
        np.testing.assert_array_equal(raw, img[::-1])   # raw is GL order, bottom row first
    finally:
        target.release()


@pytest.mark.gl
def test_read_rows_into_gives_the_rows_read_raw_gives(ctx):
    target = gl.RenderTarget(ctx, (8, 6))
    try:
        target.use()
        for row in range(6):                       # every row its own colour
            ctx.scissor = (0, row, 8, 1)
            ctx.clear(row / 5, 1 - row / 5, 0.5, 1.0)
        ctx.scissor = None
        raw = np.frombuffer(target.read_raw(), np.uint8).reshape(6, 8, 4)
        for first, rows in ((0, 2), (2, 4), (5, 1), (0, 6)):
            out = np.full(rows * 8 * 4, 7, np.uint8)
            target.read_rows_into(out, first, rows)
            np.testing.assert_array_equal(out.reshape(rows, 8, 4), raw[first:first + rows])
        with pytest.raises(ValueError, match="rows 5 \\+ 2 must lie within the target's 6"):
            target.read_rows_into(np.empty(2 * 32, np.uint8), 5, 2)
        with pytest.raises(ValueError, match="rows -1 \\+ 1 must"):
            target.read_rows_into(np.empty(32, np.uint8), -1, 1)
        with pytest.raises(ValueError, match="out must hold 64 bytes \\(2 rows of 8 RGBA pixels\\), got 63"):
            target.read_rows_into(np.empty(63, np.uint8), 0, 2)
    finally:
        target.release()


@pytest.mark.gl
def test_render_target_resizes_and_rejects_bad_sizes(ctx):
    target = gl.RenderTarget(ctx, (16, 8))
    try:
        target.resize((10, 4))
        target.use()
        ctx.clear(0.0, 1.0, 0.0, 1.0)
        assert target.read_rgba().shape == (4, 10, 4)
        assert target.aspect == 2.5
    finally:
        target.release()
        target.release()                           # twice is fine
    for bad in [(0, 10), (10, -1), (1.5, 10), "big", (gl.MAX_SIDE + 1, 1)]:
        with pytest.raises(ValueError, match="render target|size must be"):
            gl.RenderTarget(ctx, bad)


@pytest.mark.gl
def test_context_handle_releases_the_context_only_when_it_owns_it(ctx):
    calls = []
    shared = gl.ContextHandle(ctx, owned=False)
    shared.on_release(lambda: calls.append("system"))
    shared.release()
    assert calls == ["system"]
    assert ctx.version_code >= gl.REQUIRE            # still usable
    own = gl.create_context()
    handle = gl.ContextHandle(own, owned=True)
    handle.release()
    assert handle.ctx is None


def _frames(world, render, n):
    out = []
    for _ in range(n):
        world.step()
        world.render()
        out.append(render.read_rgba())
    return out


@pytest.mark.gl
def test_worlds_with_their_own_contexts_draw_into_their_own_and_survive_each_others_close():
    """GL calls go to the current context: each world makes its own current for its frame, for the
    objects attach makes, for a read-back and for its close. Closing one world used to free its GL
    objects in whichever context was current (the other world's: the same object names), so the
    other then drew garbage (a frame's mean anywhere from 4 to 220 instead of 111)."""
    from driftframe.app import attach_rendering, make_world

    def alone(name, n):
        w, _ = make_world(name)
        try:
            return _frames(w, attach_rendering(w, size=(160, 90)), n)
        finally:
            w.close()

    want_a, want_b = alone("asteroids", 4), alone("swarm", 4)
    a, _ = make_world("asteroids")
    b, _ = make_world("swarm")
    try:
        ra = attach_rendering(a, size=(160, 90))
        rb = attach_rendering(b, size=(160, 90))         # made last: its context is the current one
        for k in range(3):                                 # drawn alternately
            assert np.array_equal(_frames(a, ra, 1)[0], want_a[k])
            assert np.array_equal(_frames(b, rb, 1)[0], want_b[k])
        a.close()
        assert np.array_equal(_frames(b, rb, 1)[0], want_b[3])
    finally:
        a.close()
        b.close()


def test_current_makes_an_off_screen_context_current_and_leaves_it_current(ctx):
    other = gl.create_context()                           # made current by its creation
    try:
        with gl.current(ctx) as c:
            assert c is ctx
            target = gl.RenderTarget(ctx, (4, 4))       # this context's objects
        # still current after the block: its own framebuffer cleared and read with no current() around it
        target.fbo.use()
        ctx.clear(1.0, 0.0, 0.0, 1.0)
        px = np.frombuffer(target.fbo.read(components=4, alignment=1), np.uint8).reshape(-1, 4)
        np.testing.assert_array_equal(px, [[255, 0, 0, 255]] * 16)
        target.release()
    finally:
        other.release()
    with gl.current(None) as nothing:
        assert nothing is None
