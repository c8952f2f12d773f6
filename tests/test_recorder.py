"""Recording: one frame per simulated frame to MP4 / GIF / PNGs, deterministic, atomic, interruptible."""
from __future__ import annotations

import os

import imageio_ffmpeg
import numpy as np
import pytest
from PIL import Image

from driftframe.components.body import Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework.recorder import output_format, record
from driftframe.framework.world import World
from driftframe.systems.movement import MovementSystem
from driftframe.systems.render import RenderSystem, attach

pytestmark = pytest.mark.gl

W, H = 96, 64


@pytest.fixture
def scene(ctx):
    """scene() -> a fresh world: a ship flying past moving rocks, a chase camera, rendering attached."""
    worlds = []

    def build(size):
        w = World()
        worlds.append(w)
        w.add_system(MovementSystem())
        ship = w.create_entity(Transform((0.0, 0.0, 0.0)), Velocity((0.0, 0.5, 3.0)), ModelRef("ship"))
        w.create_entity(Camera(target=ship, mode="chase", smoothing=0.2))
        rng = np.random.default_rng(7)
        for p, v in zip(rng.uniform(-12, 12, (25, 3)), rng.normal(0, 2, (25, 3))):
            w.create_entity(Transform(p + [0, 0, 25]), Velocity(v), ModelRef("sphere"))
        return w

    def with_render(size=(W, H)):
        w = build(size)
        attach(w, ctx, size)
        # a big white marker high in the sky: it must come out in the top rows of every format
        w.resources["model_cache"].variant("marker", "sphere", scale=8.0, colour=(1.0, 1.0, 1.0))
        w.create_entity(Transform((0.0, 40.0, 90.0)), Velocity((0.0, 0.0, 3.0)), ModelRef("marker"))
        return w

    yield with_render
    for w in worlds:
        w.close()


def mp4_frames(path):
    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    w, h = meta["size"]
    return meta, [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in gen]


def listing(d):
    return sorted(os.listdir(d))


def test_mp4_has_one_frame_per_simulated_frame_at_the_target_size(scene, tmp_path):
    w = scene()
    out = tmp_path / "run.mp4"
    res = record(w, out, frames=24, progress=False)
    assert (res.path, res.format, res.frames, res.requested, res.interrupted) == (out, "mp4", 24, 24, False)
    assert w.step_count == 24
    meta, frames = mp4_frames(out)
    assert len(frames) == 24 and meta["size"] == (W, H) and meta["fps"] == 60.0
    assert listing(tmp_path) == ["run.mp4"]                         # no temporary left over


def test_same_scene_gives_byte_identical_recordings(scene, tmp_path):
    for ext in ("mp4", "gif", "frames"):
        a, b = tmp_path / f"a.{ext}", tmp_path / f"b.{ext}"
        if ext == "frames":
            a, b = tmp_path / "a_frames", tmp_path / "b_frames"
        record(scene(), a, frames=12, progress=False)
        record(scene(), b, frames=12, progress=False)
        if ext == "frames":
            assert listing(a) == listing(b) and len(listing(a)) == 12
            for name in listing(a):
                assert (a / name).read_bytes() == (b / name).read_bytes()
        else:
            assert a.read_bytes() == b.read_bytes(), ext


def test_png_frames_are_the_rendered_frames_in_order_and_right_way_up(scene, tmp_path):
    out = tmp_path / "frames"
    record(scene(), out, frames=5, steps_per_frame=2, progress=False)
    assert listing(out) == [f"frame_{i:06d}.png" for i in range(5)]
    ref = scene()
    render = ref.get_system(RenderSystem)
    for i in range(5):
        ref.step(2)
        ref.render()
        expected = render.read_rgba()[..., :3]
        got = np.asarray(Image.open(out / f"frame_{i:06d}.png"))
        np.testing.assert_array_equal(got, expected)
    top = got[: H // 2].astype(int).sum(axis=-1)
    assert (top > 600).any()                                        # the white marker is in the top half


def test_mp4_and_gif_come_out_the_right_way_up(scene, tmp_path):
    w = scene()
    record(w, tmp_path / "v.mp4", frames=3, progress=False)
    _, frames = mp4_frames(tmp_path / "v.mp4")
    for f in frames:
        white = f.astype(int).min(axis=-1) > 180                  # only the marker is white
        ys = np.nonzero(white)[0]
        assert len(ys) and ys.max() < H // 2
    gif = Image.open(_record_gif(scene, tmp_path))
    assert gif.n_frames == 3 and gif.size == (W // 2, H // 2)      # reduced size by default
    for k in range(gif.n_frames):
        gif.seek(k)
        rgb = np.asarray(gif.convert("RGB")).astype(int)
        ys = np.nonzero(rgb.min(axis=-1) > 180)[0]
        assert len(ys) and ys.max() < H // 4


def _record_gif(scene, tmp_path):
    out = tmp_path / "v.gif"
    res = record(scene(), out, frames=3, progress=False)
    assert res.size == (W // 2, H // 2)
    return out


def test_interrupt_leaves_a_valid_shorter_video_and_says_so(scene, tmp_path, capsys):
    def ctrl_c_at_step_10(world, step):
        if step == 10:
            raise KeyboardInterrupt

    for name in ("cut.mp4", "cut.gif", "cut_frames"):
        out = tmp_path / name
        res = record(scene(), out, frames=40, progress=False, before_step=ctrl_c_at_step_10)
        assert res.interrupted and res.frames == 10 and res.requested == 40 and res.path == out
        if name.endswith(".mp4"):
            assert len(mp4_frames(out)[1]) == 10
        elif name.endswith(".gif"):
            assert Image.open(out).n_frames == 10
        else:
            assert len(listing(out)) == 10
        assert "interrupted after 10 of 40 frames" in capsys.readouterr().err
    assert listing(tmp_path) == ["cut.gif", "cut.mp4", "cut_frames"]


def test_failure_leaves_nothing_behind(scene, tmp_path):
    def crash(world, step):
        if step == 6:
            raise RuntimeError("scripted input failed")

    for name in ("x.mp4", "x.gif", "x_frames"):
        with pytest.raises(RuntimeError, match="scripted input failed"):
            record(scene(), tmp_path / name, frames=20, progress=False, before_step=crash)
    assert listing(tmp_path) == []
    # an earlier good recording at the same path survives a failed re-recording untouched
    good = tmp_path / "keep.mp4"
    record(scene(), good, frames=4, progress=False)
    before = good.read_bytes()
    with pytest.raises(RuntimeError):
        record(scene(), good, frames=20, progress=False, before_step=crash)
    assert good.read_bytes() == before and listing(tmp_path) == ["keep.mp4"]


def test_bad_paths_and_formats_fail_before_anything_is_rendered(scene, tmp_path):
    w = scene()
    (tmp_path / "a_file").write_text("x")
    cases = [
        (tmp_path / "clip.avi", ValueError, r"unknown output format '.avi'.*use .mp4, .gif, or a directory"),
        (tmp_path / "still.png", ValueError, "a .png path is a single image"),
        (tmp_path / "missing" / "clip.mp4", FileNotFoundError, "does not exist"),
        (tmp_path / "a_file" / "clip.mp4", NotADirectoryError, "is not a directory"),
        (tmp_path / "a_file", FileExistsError, "exists and is not a directory"),
    ]
    if os.geteuid() != 0:                                          # root may write anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        cases.append((locked / "clip.mp4", PermissionError, "is not writable"))
    for path, err, msg in cases:
        with pytest.raises(err, match=msg):
            record(w, path, frames=3, progress=False)
    with pytest.raises(ValueError, match="frames must be an int >= 1, got 0"):
        record(w, tmp_path / "ok.mp4", frames=0)
    with pytest.raises(ValueError, match="fps must be a finite number > 0"):
        record(w, tmp_path / "ok.mp4", frames=3, fps=float("nan"))
    with pytest.raises(ValueError, match="preset must be one of .*got 'quick'"):
        record(w, tmp_path / "ok.mp4", frames=3, preset="quick")
    assert w.step_count == 0                                       # nothing was stepped or rendered
    assert w.get_system(RenderSystem).frame == 0
    assert sorted(p for p in listing(tmp_path) if p != "locked") == ["a_file"]


def test_odd_sizes_are_refused_for_h264_before_rendering(scene, tmp_path):
    w = scene(size=(95, 64))
    with pytest.raises(ValueError, match="even width and height, got 95x64"):
        record(w, tmp_path / "odd.mp4", frames=2, progress=False)
    assert w.step_count == 0
    record(w, tmp_path / "odd.gif", frames=2, progress=False)      # GIF and PNG take any size


def test_png_directory_is_replaced_but_a_foreign_directory_is_refused(scene, tmp_path):
    out = tmp_path / "frames"
    record(scene(), out, frames=6, progress=False)
    record(scene(), out, frames=3, progress=False)
    assert listing(out) == [f"frame_{i:06d}.png" for i in range(3)]
    other = tmp_path / "mine"
    other.mkdir()
    (other / "notes.txt").write_text("keep me")
    with pytest.raises(FileExistsError, match="holds other files"):
        record(scene(), other, frames=2, progress=False)
    assert listing(other) == ["notes.txt"]


def test_progress_bar_shows_on_stderr_and_can_be_turned_off(scene, tmp_path, capsys):
    record(scene(), tmp_path / "p.gif", frames=3, progress=True)
    assert "3/3" in capsys.readouterr().err
    record(scene(), tmp_path / "q.gif", frames=3, progress=False)
    assert capsys.readouterr().err == ""


def test_output_format_follows_the_suffix(tmp_path):
    assert output_format("a/b.mp4") == "mp4" and output_format("B.GIF") == "gif"
    assert output_format("frames/") == "png" and output_format("frames") == "png"
    assert output_format(tmp_path) == "png"
    with pytest.raises(ValueError, match="unknown output format '.webm'"):
        output_format("x.webm")


def test_recording_needs_rendering_attached(tmp_path):
    w = World()
    try:
        with pytest.raises(LookupError, match="attach"):
            record(w, tmp_path / "x.mp4", frames=1)
    finally:
        w.close()
