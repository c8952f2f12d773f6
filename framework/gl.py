"""The one place that creates an OpenGL context, and the render target frames are drawn into.

Two ways to get a context, both returning a ``moderngl.Context``:

* :func:`create_context` — off-screen, through moderngl's standalone EGL
  backend. No display and no GPU needed: on Mesa it runs on the llvmpipe
  software renderer (OpenGL 4.5 core). This is what tests, benchmarks and the
  recorder use.
* :func:`wrap_current_context` — the context of a window that is already
  current in this thread (e.g. after ``glfw.make_context_current(win)``).

With no usable driver both raise :class:`GLUnavailableError`, whose message
names what is missing and the Debian/Ubuntu packages that provide it, instead
of a traceback from inside the EGL loader.

Several off-screen contexts may live in one process (a world each): GL calls go
to the context that is *current*, so whatever draws, reads or frees GL objects
makes its own current first (:func:`current`: ``with current(ctx):``). The
world does it for its frame (``World.render`` enters its resources'
``frame_scope``, which :class:`ContextHandle` gives), :func:`driftframe.rendering.attach`
for the objects it makes, :class:`RenderTarget` for a read-back, and
:class:`ContextHandle` for the release. A window's context is the window's:
it is current already and is left alone. (Each stays current after the block:
a program with one context sees no change.)

A context works only in the thread that created it, and a process must not
``fork`` once a context exists (the child hangs): use the ``spawn`` start
method for worker processes. Starting a program that ``exec``s is fine.

:class:`RenderTarget` is where a frame goes: an off-screen framebuffer
(RGBA8 colour + 24-bit depth renderbuffers) or a window's default
framebuffer. :meth:`RenderTarget.read_rgba` returns the frame as an
``(H, W, 4)`` uint8 array, top row first (GL reads bottom-up; it is flipped
here). Both are typed resources of a world with rendering
(``world.resources[RenderTarget]``, ``world.resources[ContextHandle]``), as
:func:`driftframe.rendering.attach` stores them; the handle releases the
context with the world only when the world owns it.
"""
from __future__ import annotations

import ctypes
import glob
import os
import weakref
from contextlib import nullcontext

import numpy as np

from driftframe.framework import validate

#: What to install on Debian/Ubuntu for off-screen GL (Mesa's EGL and its software rasteriser).
APT_PACKAGES = ("libegl1", "libgl1", "libegl-mesa0", "libgl1-mesa-dri")
APT_HINT = "apt-get install -y --no-install-recommends " + " ".join(APT_PACKAGES)
#: Oldest OpenGL the shaders need (GLSL 3.30: instanced attributes, layout-free ins/outs).
REQUIRE = 330
#: Largest side of an off-screen target we accept (GL_MAX_RENDERBUFFER_SIZE is >= 16384 on Mesa).
MAX_SIDE = 16384

# (what, shared library, package) checked when context creation fails
_LIBRARIES = (
    ("the EGL loader", "libEGL.so.1", "libegl1"),
    ("the GL dispatch library", "libGL.so.1", "libgl1"),
    ("Mesa's EGL driver", "libEGL_mesa.so.0", "libegl-mesa0"),
)


class GLUnavailableError(RuntimeError):
    """No OpenGL context could be made; the message says what is missing and how to install it."""


def _can_load(soname: str) -> bool:
    try:
        ctypes.CDLL(soname)
        return True
    except OSError:
        return False


def _find_dri_driver() -> bool:
    pattern_dirs = ["/usr/lib/*/dri", "/usr/lib/dri", "/usr/lib64/dri", "/usr/local/lib/*/dri"]
    extra = os.environ.get("LIBGL_DRIVERS_PATH", "")
    pattern_dirs += [d for d in extra.split(":") if d]
    return any(glob.glob(os.path.join(d, name)) for d in pattern_dirs
               for name in ("swrast_dri.so", "kms_swrast_dri.so", "libgallium*.so"))


def missing_pieces(can_load=None, find_dri=None) -> list[tuple[str, str]]:
    """``(what, package)`` for each part of an off-screen GL stack that cannot be found."""
    can_load = can_load or _can_load
    find_dri = find_dri or _find_dri_driver
    missing = [(f"{what} ({so})", pkg) for what, so, pkg in _LIBRARIES if not can_load(so)]
    if not find_dri():
        missing.append(("Mesa's software rasteriser (swrast_dri.so)", "libgl1-mesa-dri"))
    return missing


def explain_failure(error: BaseException, missing: list[tuple[str, str]]) -> str:
    """The message of :class:`GLUnavailableError` for a failed context creation."""
    lines = ["Could not create an off-screen OpenGL context (moderngl, EGL backend)."]
    if missing:
        lines.append("Missing: " + "; ".join(what for what, _ in missing) + ".")
        pkgs = sorted({pkg for _, pkg in missing})
        lines.append(f"Install them with: apt-get install -y --no-install-recommends {' '.join(pkgs)}")
    else:
        lines.append("The EGL and Mesa libraries were found but the driver refused to start.")
        lines.append(f"Check the driver packages ({APT_HINT}) and that OpenGL {REQUIRE // 100}."
                     f"{REQUIRE % 100 // 10} is available.")
    lines.append(f"Underlying error: {type(error).__name__}: {error}")
    return "\n".join(lines)


def create_context(*, require: int = REQUIRE, backend: str = "egl", **settings):
    """A new standalone (off-screen) ``moderngl.Context``; the caller releases it.

    ``backend="egl"`` needs no display. ``settings`` go to
    ``moderngl.create_standalone_context`` (e.g. ``libegl=``,
    ``device_index=``). Raises :class:`GLUnavailableError` naming the missing
    libraries and the apt packages to install when no driver can be used.
    """
    try:
        import moderngl
    except ImportError as e:   # pragma: no cover - moderngl is a hard dependency
        raise GLUnavailableError(f"moderngl is not installed ({e}); pip install 'moderngl>=5.10,<6'") from e
    try:
        ctx = moderngl.create_standalone_context(backend=backend, require=require, **settings)
    except Exception as e:  # glcontext raises bare Exception / OSError from deep inside the loader
        raise GLUnavailableError(explain_failure(e, missing_pieces())) from None
    _OFFSCREEN.add(ctx)
    return ctx


#: The off-screen contexts :func:`create_context` made (weakly: a released, dropped one leaves).
_OFFSCREEN: "weakref.WeakSet" = weakref.WeakSet()


def current(ctx):
    """``with current(ctx):`` the block's GL calls go to ``ctx``, an off-screen context
    (:func:`create_context`); any other (a window's, current already, or None) is left as it is.

    The context stays current after the block: moderngl's own ``with ctx:`` leaves *no* context current
    when it ends (measured: the next call fails with "cannot create renderbuffer"), which would break
    every caller that uses its one context directly, as a program with one context may."""
    if ctx is None or ctx not in _OFFSCREEN:
        return nullcontext()
    ctx.__enter__()                  # (eglMakeCurrent; Mesa returns at once when it is current already)
    return nullcontext(ctx)


def wrap_current_context(*, require: int = REQUIRE):
    """The ``moderngl.Context`` of the window whose GL context is current in this thread.

    Call it after the window library made its context current (glfw:
    ``glfw.make_context_current(window)``). The window owns the context: do
    not release it before closing the window.
    """
    import moderngl
    try:
        return moderngl.create_context(require=require)
    except Exception as e:
        raise GLUnavailableError(
            "Could not use the current window's OpenGL context: make a window's context current first "
            f"(glfw.make_context_current(window)) and check it offers OpenGL >= {REQUIRE / 100:.1f}.\n"
            f"Underlying error: {type(e).__name__}: {e}") from None


def renderer(ctx) -> str:
    """The driver's renderer string, e.g. ``'llvmpipe (LLVM 15.0.6, 256 bits)'``."""
    return str(ctx.info.get("GL_RENDERER", "unknown"))


class ContextHandle:
    """A context stored in ``world.resources``; releases it with the world only if ``owned``.

    ``world.close()`` calls ``release()`` on every resource; a context shared
    by several worlds (tests) or owned by a window must survive that.
    """

    #: Who makes it (named when a world has none: :meth:`World.resource`).
    published_by = "made by attach_rendering(world) (driftframe.rendering.attach)"
    #: Not in a save: a handle, made again when rendering is attached.
    saved = False

    def __init__(self, ctx, *, owned: bool):
        self.ctx = ctx
        self.owned = bool(owned)
        self._on_release: list = []

    def on_release(self, fn) -> None:
        """Call ``fn()`` when this handle is released (systems free their GL objects here)."""
        self._on_release.append(fn)

    def frame_scope(self):
        """What ``World.render`` enters for the frame: this context made current (off-screen ones)."""
        return current(self.ctx)

    def release(self) -> None:
        callbacks, self._on_release = self._on_release, []
        with current(self.ctx):
            for fn in reversed(callbacks):
                fn()
        if self.owned and self.ctx is not None:
            self.ctx.release()
        self.ctx = None


def _check_size(size) -> tuple[int, int]:
    try:
        w, h = size
    except (TypeError, ValueError):
        raise ValueError(f"size must be (width, height) in pixels, got {validate.shown(size)}") from None
    for name, v in (("width", w), ("height", h)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 1 <= v <= MAX_SIDE:
            raise ValueError(f"render target {name} must be an int in [1, {MAX_SIDE}], got {validate.shown(v)}")
    return int(w), int(h)


class RenderTarget:
    """Where frames are drawn: an off-screen RGBA8 + depth framebuffer, or a window's screen.

    ``fbo`` is the ``moderngl.Framebuffer``; ``size`` is ``(width, height)``
    in pixels; ``use()`` binds it and sets the viewport. A later system (a
    HUD) draws into the same frame by calling ``target.use()`` and drawing.
    A system that draws into it declares ``RenderTarget`` in its ``writes``.
    """

    #: Who makes it (named when a world has none: :meth:`World.resource`).
    published_by = "made by attach_rendering(world) (driftframe.rendering.attach)"
    #: Not in a save: GPU objects, made again when rendering is attached.
    saved = False

    def __init__(self, ctx, size=(1280, 720)):
        self.ctx = ctx
        self.size = _check_size(size)
        self.is_screen = False
        self._colour = ctx.renderbuffer(self.size, components=4)
        self._depth = ctx.depth_renderbuffer(self.size)
        self.fbo = ctx.framebuffer(color_attachments=[self._colour], depth_attachment=self._depth)

    @classmethod
    def screen(cls, ctx, size) -> "RenderTarget":
        """The default framebuffer of a window (``ctx`` from :func:`wrap_current_context`)."""
        self = cls.__new__(cls)
        self.ctx = ctx
        self.size = _check_size(size)
        self.is_screen = True
        self._colour = self._depth = None
        self.fbo = ctx.screen
        return self

    @property
    def width(self) -> int:
        return self.size[0]

    @property
    def height(self) -> int:
        return self.size[1]

    @property
    def viewport(self) -> tuple[int, int, int, int]:
        """``(x, y, width, height)`` in pixels, GL's bottom-left origin."""
        return (0, 0, *self.size)

    @property
    def aspect(self) -> float:
        """width / height."""
        return self.size[0] / self.size[1]

    def use(self) -> None:
        """Bind the framebuffer and set the viewport to the whole target."""
        self.fbo.use()
        self.ctx.viewport = self.viewport

    def resize(self, size) -> None:
        """New size (a window was resized); an off-screen target reallocates its buffers."""
        size = _check_size(size)
        if size == self.size:
            return
        if not self.is_screen:
            self._release_buffers()
            self._colour = self.ctx.renderbuffer(size, components=4)
            self._depth = self.ctx.depth_renderbuffer(size)
            self.fbo = self.ctx.framebuffer(color_attachments=[self._colour], depth_attachment=self._depth)
        self.size = size

    def read_raw(self) -> bytes:
        """The frame as RGBA bytes, *bottom row first* (GL order). RGBA reads fastest (no conversion)."""
        with current(self.ctx):
            data = self.fbo.read(viewport=self.viewport, components=4, alignment=1)
        if self.is_screen:
            _ = self.ctx.error   # reading a window's screen leaves a pending GL_INVALID_OPERATION: clear it
        return data

    def read_rows_into(self, out, first_row: int, rows: int) -> None:
        """Rows ``first_row .. first_row + rows - 1`` (GL order, 0 at the bottom) as RGBA into ``out``.

        ``out``: a writable buffer of ``rows * width * 4`` bytes. Reading a
        frame in bands and using each at once keeps it in the CPU's cache
        (the recorder's NV12 path); the first band waits for the frame to
        finish drawing, as :meth:`read_raw` does.
        """
        w, h = self.size
        if isinstance(rows, bool) or not isinstance(rows, (int, np.integer)) or rows < 1 \
                or isinstance(first_row, bool) or not isinstance(first_row, (int, np.integer)) \
                or not 0 <= first_row <= h - rows:
            raise ValueError(f"rows {validate.shown(first_row)} + {validate.shown(rows)} "
                             f"must lie within the target's {h}")
        if memoryview(out).nbytes != rows * w * 4:
            raise ValueError(f"out must hold {rows * w * 4} bytes ({rows} rows of {w} RGBA pixels), "
                             f"got {memoryview(out).nbytes}")
        with current(self.ctx):
            self.fbo.read_into(out, viewport=(0, int(first_row), w, int(rows)), components=4, alignment=1)
        if self.is_screen:
            _ = self.ctx.error   # as in read_raw

    def read_rgba(self) -> np.ndarray:
        """The frame as an ``(H, W, 4)`` uint8 array, top row first (ready for PNG / video)."""
        w, h = self.size
        return np.frombuffer(self.read_raw(), np.uint8).reshape(h, w, 4)[::-1].copy()

    def _release_buffers(self) -> None:
        bound = getattr(self.ctx, "fbo", None)
        if bound is not None and self.fbo is not None and bound.glo == self.fbo.glo:
            # moderngl re-binds "the bound framebuffer" after creating others: never leave it a deleted one
            self.ctx.detect_framebuffer(0).use()
        for obj in (self.fbo, self._colour, self._depth):
            if obj is not None:
                obj.release()
        self.fbo = self._colour = self._depth = None

    def release(self) -> None:
        """Free the off-screen buffers (a window's screen is left alone). Safe to call twice."""
        if not self.is_screen and self.fbo is not None:
            self._release_buffers()
        self.fbo = None
