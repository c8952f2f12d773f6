"""Recording: one frame per simulated frame to MP4 / GIF / PNGs, deterministic, atomic, interruptible."""
from __future__ import annotations

import os

import numpy as np
import pytest
from PIL import Image
from videos import mp4_frames

from driftframe.components.body import Transform, Velocity
from driftframe.components.camera import Camera
from driftframe.components.render import ModelRef
from driftframe.framework.gl import RenderTarget
from driftframe.framework.model_cache import ModelCache
from driftframe.framework.recorder import output_format, record
from driftframe.framework.world import World
from driftframe.systems.movement import MovementSystem
from driftframe.rendering import attach
from driftframe.systems.render import RenderSystem

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
        w.resources[ModelCache].variant("marker", "sphere", scale=8.0, colour=(1.0, 1.0, 1.0))
        w.create_entity(Transform((0.0, 40.0, 90.0)), Velocity((0.0, 0.0, 3.0)), ModelRef("marker"))
        return w

    yield with_render
    for w in worlds:
        w.close()


def listing(d):
    return sorted(os.listdir(d))


def gif_delays(path):
    """Each frame's delay in 1/100 s (Pillow reports milliseconds)."""
    with Image.open(path) as im:
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out.append(im.info["duration"] // 10)
        return out


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
        record(scene(), a, frames=12, progress=False, format="png" if ext == "frames" else None)
        record(scene(), b, frames=12, progress=False, format="png" if ext == "frames" else None)
        if ext == "frames":
            assert listing(a) == listing(b) and len(listing(a)) == 12
            for name in listing(a):
                assert (a / name).read_bytes() == (b / name).read_bytes()
        else:
            assert a.read_bytes() == b.read_bytes(), ext


def test_png_frames_are_the_rendered_frames_in_order_and_right_way_up(scene, tmp_path):
    out = tmp_path / "frames"
    record(scene(), str(out) + "/", frames=5, steps_per_frame=2, progress=False)
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
    # 60 fps: frame ends at 2, 3, 5 cs; the 1 cs frame is merged into the one before it
    assert gif.n_frames == 2 and gif.size == (W // 2, H // 2)      # reduced size by default
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
        res = record(scene(), out, frames=40, progress=False, before_step=ctrl_c_at_step_10,
                     format="png" if name.endswith("frames") else None)
        assert res.interrupted and res.frames == 10 and res.requested == 40 and res.path == out
        if name.endswith(".mp4"):
            assert len(mp4_frames(out)[1]) == 10
        elif name.endswith(".gif"):
            assert gif_delays(out) and sum(gif_delays(out)) == 17      # 10 frames at 60 fps: 16.7 cs
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
            record(scene(), tmp_path / name, frames=20, progress=False, before_step=crash,
                   format="png" if name.endswith("frames") else None)
    assert listing(tmp_path) == []
    # an earlier good recording at the same path survives a failed re-recording untouched
    good = tmp_path / "keep.mp4"
    record(scene(), good, frames=4, progress=False)
    before = good.read_bytes()
    with pytest.raises(RuntimeError):
        record(scene(), good, frames=20, progress=False, before_step=crash, overwrite=True)
    assert good.read_bytes() == before and listing(tmp_path) == ["keep.mp4"]


def test_record_makes_the_outputs_folder(scene, tmp_path):
    # issue 23: the GUIDE's first program records to out/mine.mp4 in a new folder; it failed with
    # "directory 'out' does not exist"
    w = scene()
    out = tmp_path / "new" / "deeper" / "clip.gif"
    res = record(w, out, frames=2, progress=False)
    assert res.path == out and out.stat().st_size > 0
    w.close()


def test_bad_paths_and_formats_fail_before_anything_is_rendered(scene, tmp_path):
    w = scene()
    (tmp_path / "a_file").write_text("x")
    cases = [
        (tmp_path / "clip.avi", ValueError, r"unknown output format '.avi'.*use .mp4, .gif, or a directory"),
        (tmp_path / "still.png", ValueError, "a .png path is a single image"),
        (tmp_path / "a_file" / "sub" / "clip.mp4", OSError, "cannot create its directory"),
        (tmp_path / "a_file" / "clip.mp4", NotADirectoryError, "is not a directory"),
        (str(tmp_path / "a_file") + "/", FileExistsError, "exists and is not a directory"),
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
    record(scene(), out, frames=6, progress=False, format="png")
    with pytest.raises(FileExistsError, match="holds PNG frames already; pass overwrite=True"):
        record(scene(), out, frames=3, progress=False)
    assert len(listing(out)) == 6
    record(scene(), out, frames=3, progress=False, overwrite=True)
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
    assert output_format("frames/") == "png" and output_format(tmp_path) == "png"
    with pytest.raises(ValueError, match=r"output 'noext' has no suffix: give NAME.mp4 .* 'noext/'"):
        output_format("noext")                      # a forgotten .mp4, not a folder of PNGs
    with pytest.raises(ValueError, match="unknown output format '.webm'"):
        output_format("x.webm")


def test_recording_needs_rendering_attached(tmp_path):
    w = World()
    try:
        with pytest.raises(LookupError, match="attach"):
            record(w, tmp_path / "x.mp4", frames=1)
    finally:
        w.close()


# -- GIF: exact length, streamed ----------------------------------------------------------------
@pytest.mark.parametrize("fps,frames,total_cs", [(60, 30, 50), (30, 9, 30), (20, 7, 35), (12, 5, 42)])
def test_gif_delays_add_up_to_the_exact_length(scene, tmp_path, fps, frames, total_cs):
    out = tmp_path / "t.gif"
    record(scene(), out, frames=frames, fps=fps, steps_per_frame=60 // fps, progress=False)
    delays = gif_delays(out)
    assert sum(delays) == total_cs                   # frames / fps seconds, to the 1/100 s
    assert min(delays) >= 2                          # players slow down anything shorter
    if fps == 30:
        assert set(delays) <= {3, 4}                 # 3.33 cs per frame: 3, 4, 3, 3, 4, 3...


@pytest.mark.parametrize("fps", [np.float32(30.0), np.float64(30.0), np.int64(30)])
def test_fps_as_a_numpy_number_is_the_same_rate(scene, tmp_path, fps):
    # np.float32 is no Python float: Fraction refused it, a TypeError from inside record after every check
    out = tmp_path / "t.gif"
    res = record(scene(), out, frames=9, fps=fps, steps_per_frame=2, progress=False)
    assert res.frames == 9 and sum(gif_delays(out)) == 30


def test_gif_is_written_as_it_records_and_holds_at_most_two_frames(scene, tmp_path, monkeypatch):
    from driftframe.framework import record_sinks

    sinks = []

    class Spy(record_sinks._GifSink):
        def __init__(self, *a, **kw):
            super().__init__(*a, **kw)
            sinks.append(self)

    monkeypatch.setattr(record_sinks, "_GifSink", Spy)
    sizes = {}

    def watch(world, step):
        if step in (10, 30):
            parts = [p for p in tmp_path.iterdir() if p.name.startswith(".long.gif.")]
            assert len(parts) == 1
            sizes[step] = parts[0].stat().st_size

    record(scene(), tmp_path / "long.gif", frames=40, fps=30, steps_per_frame=1, progress=False,
           before_step=watch)
    # the file grows while recording (frames are not kept for a save at the end) ...
    assert 0 < sizes[10] < sizes[30] < (tmp_path / "long.gif").stat().st_size
    # ... and memory holds the frame on screen and the one before it, however long the recording
    assert sinks[0].max_held == 2 and sinks[0].held == 0 and sinks[0].count == 40


# -- outputs: existing, stale, unwritable, full -------------------------------------------------
def test_an_existing_output_is_refused_unless_overwrite(scene, tmp_path):
    from driftframe.framework.recorder import OutputExistsError

    out = tmp_path / "x.mp4"
    out.write_bytes(b"mine")
    w = scene()
    with pytest.raises(OutputExistsError, match=r"x.mp4' exists; pass overwrite=True \(--overwrite\)"):
        record(w, out, frames=2, progress=False)
    assert out.read_bytes() == b"mine" and w.step_count == 0
    out.chmod(0o444)                                 # read-only: not replaced even with overwrite
    with pytest.raises(PermissionError, match="it is read-only"):
        record(w, out, frames=2, progress=False, overwrite=True)
    assert out.read_bytes() == b"mine" and w.step_count == 0
    out.chmod(0o644)
    record(w, out, frames=2, progress=False, overwrite=True)
    assert len(mp4_frames(out)[1]) == 2 and listing(tmp_path) == ["x.mp4"]


def test_check_output_raises_what_record_would_and_creates_nothing(tmp_path):
    from driftframe.framework.recorder import OutputExistsError, check_output

    check_output(tmp_path / "new.mp4")
    check_output(tmp_path / "new.gif")
    assert listing(tmp_path) == []                   # a check, not a preparation: no part file
    (tmp_path / "x.mp4").write_bytes(b"mine")
    with pytest.raises(OutputExistsError, match=r"x.mp4' exists; pass overwrite=True"):
        check_output(tmp_path / "x.mp4")
    check_output(tmp_path / "x.mp4", overwrite=True)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        check_output(tmp_path / "no" / "x.mp4")
    with pytest.raises(IsADirectoryError, match="it is a directory"):
        check_output(tmp_path, format="mp4")
    with pytest.raises(ValueError, match="has no suffix"):
        check_output(tmp_path / "noext")
    assert listing(tmp_path) == ["x.mp4"] and (tmp_path / "x.mp4").read_bytes() == b"mine"


def test_stale_part_files_of_dead_recordings_are_removed(scene, tmp_path):
    import subprocess
    import sys

    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()                                      # a pid that no longer runs
    stale_file = tmp_path / f".x.mp4.{gone.pid}.k3j4.part.mp4"
    stale_dir = tmp_path / f".x.mp4.{gone.pid}.q9z1.old"
    live = tmp_path / f".x.mp4.{os.getppid()}.abcd.part.mp4"   # a running process: its file is kept
    other = tmp_path / f".y.mp4.{gone.pid}.abcd.part.mp4"      # another output's: not ours to judge
    for p in (stale_file, live, other):
        p.write_bytes(b"x")
    stale_dir.mkdir()
    (stale_dir / "frames").mkdir()
    record(scene(), tmp_path / "x.mp4", frames=2, progress=False)
    assert listing(tmp_path) == sorted([live.name, other.name, "x.mp4"])


def test_a_full_disk_is_one_clear_error_and_leaves_nothing(scene, tmp_path, monkeypatch):
    import errno

    from driftframe.framework import recorder
    from driftframe.framework.recorder import RecordingError

    def full(self, raw):
        if self.count == 3:
            raise OSError(errno.ENOSPC, "No space left on device", str(self.tmp / "frame_000003.png"))
        self.count += 1

    monkeypatch.setattr(recorder._PngSink, "write", full)
    with pytest.raises(RecordingError, match=r"cannot write .*'.*f/?': no space left on the device "
                                             r"\(\d+ frames recorded, nothing kept\)"):
        record(scene(), str(tmp_path / "f") + "/", frames=10, progress=False)
    assert listing(tmp_path) == []


@pytest.mark.parametrize("failure, message", [
    ("invalid", r"the H\.264 encoder failed while receiving frames: \[Errno -1094995529\] Invalid data"),
    ("full", r"cannot write .*'.*v\.mp4': no space left on the device \(\d+ frames recorded, nothing kept\)"),
])
def test_the_mp4_encoder_failing_is_one_clear_error_and_leaves_nothing(scene, tmp_path, monkeypatch, failure,
                                                                      message):
    # an error from FFmpeg's libraries (PyAV's exceptions), raised on the writer thread at the 4th frame,
    # reaches the caller as one line; a full disk names the output, as for every format
    import errno

    import av

    from driftframe.framework import recorder
    from driftframe.framework.recorder import RecordingError

    class Failing:                                  # the real stream until its 4th frame
        def __init__(self, stream):
            self.stream, self.frames = stream, 0

        def encode(self, frame=None):
            if frame is not None:
                self.frames += 1
                if self.frames == 4:
                    raise (av.error.InvalidDataError(-1094995529, "Invalid data found when processing input")
                           if failure == "invalid" else av.error.OSError(errno.ENOSPC, "No space left on device"))
            return self.stream.encode(frame)

    real = recorder._H264Sink.__init__

    def init(self, *args, **kw):
        real(self, *args, **kw)
        self._stream = Failing(self._stream)

    monkeypatch.setattr(recorder._H264Sink, "__init__", init)
    with pytest.raises(RecordingError, match=message):
        record(scene(), tmp_path / "v.mp4", frames=10, progress=False)
    assert listing(tmp_path) == []


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc to try writing into it")
def test_a_virtual_file_system_is_named_as_the_reason(scene):
    with pytest.raises(PermissionError, match=r"'/proc' is not writable \(it is on a proc file system"):
        record(scene(), "/proc/x.mp4", frames=2, progress=False)


# -- motion blur ---------------------------------------------------------------------------------
def _spinner(ctx, tmp_path, spin, blur, name):
    """Frames of a ship seen side-on, pitching at ``spin`` rad/s, recorded with ``blur`` sub-frames."""
    from driftframe.components.body import AngularVelocity
    from driftframe.systems.motion_blur import SubframePoses
    from driftframe.systems.spin import SpinSystem

    w = World()
    try:
        w.add_system(SpinSystem())
        eye = w.create_entity(Transform((0.0, 0.0, 0.0)))
        w.create_entity(Camera(target=eye, mode="cockpit"))
        # nose along +x, pitching about x would keep it still: spin about y (the view's vertical axis)
        w.create_entity(Transform((0.0, 0.0, 4.0), fr_quat_y(0.5)), AngularVelocity((0.0, spin, 0.0)),
                        ModelRef("ship"))
        attach(w, ctx, (64, 48), skybox=False)
        out = tmp_path / name
        record(w, out, frames=3, progress=False, format="png", motion_blur=blur,
               interpolate=SubframePoses() if blur > 1 else None)
        frames = [np.asarray(Image.open(out / f"frame_{i:06d}.png")).astype(int) for i in range(3)]
        return frames, w.state_hash()
    finally:
        w.close()


def fr_quat_y(angle):
    from driftframe.framework import frame as fr
    return fr.quat_from_axis_angle((0.0, 1.0, 0.0), angle)


def test_motion_blur_shows_a_spin_at_the_frame_rate_that_sharp_frames_hide(ctx, tmp_path):
    turn_per_frame = 2 * np.pi * 60                  # one revolution per 1/60 s frame
    still, _ = _spinner(ctx, tmp_path, 0.0, 1, "still")
    sharp, hash_sharp = _spinner(ctx, tmp_path, turn_per_frame, 1, "sharp")
    blurred, hash_blurred = _spinner(ctx, tmp_path, turn_per_frame, 4, "blur")
    still_blurred, _ = _spinner(ctx, tmp_path, 0.0, 4, "still_blur")
    lit = still[0].sum(axis=-1) > 0
    assert 20 < lit.sum() < lit.size // 2            # the ship is in the picture, not filling it
    # the wagon-wheel effect: without blur, a whole turn per frame looks exactly like no spin
    for a, b in zip(sharp, still):
        assert np.abs(a - b).max() <= 1
    # with blur each frame shows the turn: the ship smeared over its sweep, not the still ship
    for a, b in zip(blurred, still):
        changed = np.abs(a - b).max(axis=-1) > 20
        assert changed.sum() > 0.3 * lit.sum()
        assert (a.sum(axis=-1) > 0).sum() > lit.sum()  # the sweep covers more pixels than the ship
    # a body that does not move is as sharp as without blur, and the simulation is untouched
    for a, b in zip(still_blurred, still):
        np.testing.assert_array_equal(a, b)
    assert hash_blurred == hash_sharp


def test_motion_blur_needs_a_pose_source_and_a_sane_count(scene, tmp_path):
    w = scene()
    with pytest.raises(TypeError, match="motion_blur needs interpolate="):
        record(w, tmp_path / "b.mp4", frames=2, motion_blur=3)
    with pytest.raises(ValueError, match="motion_blur must be at most 64"):
        record(w, tmp_path / "b.mp4", frames=2, motion_blur=65, interpolate=object())
    assert w.step_count == 0 and listing(tmp_path) == []


@pytest.mark.parametrize("yuv", ["cpu", "gpu", "ffmpeg"])
def test_mp4_colours_survive_the_yuv_conversion(ctx, tmp_path, yuv):
    # a frame of one flat colour: decoding the video must give it back (BT.709, tagged, limited range)
    w = World()
    try:
        eye = w.create_entity(Transform((0.0, 0.0, 0.0)))
        w.create_entity(Camera(target=eye, mode="cockpit"))
        attach(w, ctx, (64, 48), skybox=False, clear_colour=(0.2, 0.5, 0.8))
        out = tmp_path / "flat.mp4"
        record(w, out, frames=2, progress=False, yuv=yuv)
    finally:
        w.close()
    _, frames = mp4_frames(out)
    for f in frames:
        np.testing.assert_allclose(f.reshape(-1, 3).mean(axis=0), (51, 128, 204), atol=2.5)
        assert np.ptp(f.reshape(-1, 3), axis=0).max() <= 2


def test_gpu_yuv_is_refused_where_it_cannot_work(scene, tmp_path):
    with pytest.raises(ValueError, match="yuv='gpu' needs an MP4 output .* width is a multiple of 4, got gif"):
        record(scene(), tmp_path / "x.gif", frames=2, yuv="gpu")
    with pytest.raises(ValueError, match="got mp4 at 98x64"):
        record(scene(size=(98, 64)), tmp_path / "x.mp4", frames=2, yuv="gpu")
    with pytest.raises(ValueError, match="yuv must be one of 'cpu', 'gpu', 'ffmpeg', got 'CPU'"):
        record(scene(), tmp_path / "x.mp4", frames=2, yuv="CPU")
    assert listing(tmp_path) == []


def test_the_three_yuv_paths_give_the_same_pictures_in_the_same_order(scene, tmp_path):
    # a moving scene, more frames than the CPU path has buffers: a buffer reused before its frame reached
    # ffmpeg would show up as a frame out of place, far more than the paths' rounding differences
    decoded = {}
    for yuv in ("cpu", "gpu", "ffmpeg"):
        out = tmp_path / f"{yuv}.mp4"
        record(scene(), out, frames=16, progress=False, yuv=yuv, crf=0)       # crf 0: lossless x264
        decoded[yuv] = np.stack(mp4_frames(out)[1]).astype(np.int16)
    cpu = decoded["cpu"]
    assert len(cpu) == 16
    for other in ("gpu", "ffmpeg"):
        assert len(decoded[other]) == 16
        # mean difference of every frame of one path against every frame of the other
        d = np.abs(cpu[:, None] - decoded[other][None]).mean(axis=(2, 3, 4))
        assert (d.argmin(axis=1) == np.arange(16)).all(), (other, d.argmin(axis=1))    # frame k is frame k
        assert np.diag(d).max() < 1.0, (other, np.diag(d))


def test_a_converted_frame_keeps_its_buffer_until_the_writer_is_done_with_it():
    # a slow sink: the queue fills and the caller converts as fast as it can. A buffer reused while the
    # writer still holds it would change under the sink's feet (it copies only after a pause)
    import time

    from driftframe.framework import recorder
    from driftframe.framework.yuv import rgba_to_nv12

    w, h, n = 8, 4, 24
    frames = [np.full(w * h * 4, k, np.uint8).tobytes() for k in range(n)]
    source = iter(frames)
    grab = recorder._cpu_nv12(lambda: next(source), (w, h), recorder._Writer.DEPTH)

    class Slow(recorder._Sink):
        def write(self, raw):
            time.sleep(0.002)
            self.got.append(bytes(raw))
            self.count += 1

    sink = Slow(None, (w, h), 60)
    sink.got = []
    writer = recorder._Writer(sink)
    for _ in range(n):
        writer.put(grab())
    writer.close()
    assert sink.got == [rgba_to_nv12(f, w, h).tobytes() for f in frames]


def test_a_frame_read_in_bands_is_the_frame_read_whole(scene):
    # the recorder reads the frame back in bands of rows and converts each at once: the same bytes as
    # converting the whole frame, whatever the band size (here 6 rows: 11 bands, the last of 4)
    from driftframe.framework import recorder
    from driftframe.framework.yuv import rgba_to_nv12

    w = scene()
    target = w.resources[RenderTarget]
    grab = recorder._banded_nv12(target, recorder._Writer.DEPTH, band_bytes=6 * W * 4)
    for _ in range(3):
        w.step()
        w.render()
        whole = rgba_to_nv12(target.read_raw(), W, H)
        assert len(np.unique(whole)) > 20                      # a real picture, not a cleared screen
        np.testing.assert_array_equal(grab(), whole)


def test_mp4_defaults_are_the_measured_preset_and_its_crf(scene, tmp_path, monkeypatch):
    from driftframe.framework import record_sinks, recorder

    seen = {}
    real = record_sinks._H264Sink

    def spy(tmp, size, fps, **kw):
        seen.update(kw)
        return real(tmp, size, fps, **kw)

    monkeypatch.setattr(record_sinks, "_H264Sink", spy)
    record(scene(), tmp_path / "a.mp4", frames=2, progress=False)
    assert seen == {"crf": recorder.X264_CRF[recorder.X264_PRESET], "preset": recorder.X264_PRESET,
                    "pixel_format": "nv12", "audio": False}      # (a world without a soundtrack)
    record(scene(), tmp_path / "b.mp4", frames=2, progress=False, preset="veryfast")
    assert seen["crf"] == recorder.X264_DEFAULT_CRF            # a preset without its own crf gets 20
    record(scene(), tmp_path / "c.mp4", frames=2, progress=False, preset="ultrafast", crf=np.int64(30))
    assert seen["crf"] == 30 and type(seen["crf"]) is int


def test_a_stop_signal_ends_the_recording_between_frames(scene, tmp_path, capsys):
    import signal

    def sigterm_at_step_10(world, step):
        if step == 10:
            signal.raise_signal(signal.SIGTERM)      # as `kill` would send it, in the middle of a frame

    w = scene()
    out = tmp_path / "t.mp4"
    before = signal.signal(signal.SIGTERM, signal.SIG_DFL)   # the recorder takes over only a default handler
    try:
        res = record(w, out, frames=40, progress=False, before_step=sigterm_at_step_10)
        assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL        # and puts it back
    finally:
        signal.signal(signal.SIGTERM, before)
    # frame 10 was finished (stepped, drawn, written), then the recording stopped: no half-made frame
    assert (res.interrupted, res.signal, res.frames, w.step_count) == (True, signal.SIGTERM, 11, 11)
    assert len(mp4_frames(out)[1]) == 11 and listing(tmp_path) == ["t.mp4"]
    assert "interrupted after 11 of 40 frames (SIGTERM)" in capsys.readouterr().err
