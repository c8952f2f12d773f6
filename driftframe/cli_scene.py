"""``driftframe record`` and ``driftframe play``: running one scene, off-screen to a file or in a window.

Every option is checked, and every output path tried, before the costly part (building the scene,
compiling kernels, opening a window) starts; a bad one is a :class:`~driftframe.cli_parser.UsageError`.
"""
from __future__ import annotations

import gc
import math
import os
import sys
from decimal import Decimal

from driftframe.cli_compile import _load_kernels
from driftframe.cli_parser import CAMERAS, DEFAULT_SEED, DEFAULT_SKY, SKIES, UsageError

class _SetUp:
    """A command's set-up without Python's cyclic collector, entered for the command and :meth:`done` before its
    long part (the frames, the window).

    The set-up (numba, numpy, av, PIL, the scene, the GL objects) makes tens of thousands of objects that live
    to the end, which the collector's generation 0, 1 and 2 passes would walk again and again before the
    first frame. :meth:`done` then moves them to the permanent generation (:func:`gc.freeze`), so neither
    the frame loop's collections nor the interpreter's last one at exit walks them, and turns the collector
    back on. The few unreachable objects the set-up leaves (collecting them here frees no measurable memory)
    stay, frozen. What it saves: the commit that made it (20711e1) and docs/bench/startup.md.
    """

    def __enter__(self) -> _SetUp:
        self._was_on = gc.isenabled()
        self._open = True
        gc.disable()
        return self

    def done(self) -> None:
        if self._open:
            self._open = False
            gc.freeze()
            if self._was_on:
                gc.enable()

    def __exit__(self, *exc) -> None:
        self.done()


def _output_file(option: str, path: str | None, overwrite: bool = False) -> None:
    """A UsageError now, before anything runs, if ``path`` cannot be written (:mod:`framework.output`'s check:
    a missing or read-only folder, an existing file without --overwrite, a name too long)."""
    if path is None:
        return
    from driftframe.framework.output import check_output_file
    try:
        check_output_file(path, overwrite=overwrite, option=option)
    except OSError as e:
        hint = " (or choose another path)" if isinstance(e, FileExistsError) else ""
        raise UsageError(f"{e}{hint}") from None


def _output_names(**named) -> None:
    """A UsageError when an output's name is too long for its file system (before any stat of it fails)."""
    from driftframe.framework.output import check_name
    for option, path in named.items():
        if path is not None:
            try:
                check_name(path, f"{option} {path!r}")
            except OSError as e:
                raise UsageError(str(e)) from None


def _distinct_paths(**named) -> None:
    """A UsageError when two options name one file (``-o out/a.mp4 --hash-log out/a.mp4``)."""
    from driftframe.framework.output import same_paths
    try:
        same_paths({k: v for k, v in named.items()})
    except ValueError as e:
        raise UsageError(str(e)) from None


def _load_demo(name, seed=None, sky: str = "starfield"):
    """Demo ``name`` or the scene ``module:function`` (:func:`driftframe.app.load_scene`); a UsageError
    otherwise. ``seed``: the --seed given; a demo that takes none says so (stderr) instead of ignoring it."""
    from driftframe.app import is_scene_path, load_scene
    if is_scene_path(name):
        _scenes_here()
    try:
        demo = load_scene(name)
    except (LookupError, ValueError) as e:
        raise UsageError(str(e)) from None
    if seed is not None and seed is not DEFAULT_SEED and not getattr(demo, "SEEDED", True):
        if sky is DEFAULT_SKY:
            from driftframe.rendering import default_sky
            sky = default_sky(demo)
        what = "only the starfield sky" if sky == "starfield" else "nothing"
        print(f"driftframe: note: the {name} demo takes no seed (it is the same every run); "
              f"--seed {seed} changes {what}", file=sys.stderr)
    return demo


def _scenes_here() -> None:
    """Scenes are named by import path ('mygame.scene:build'), found in the current folder too, as `python -m`
    would; but after the installed packages: a tqdm.py or av.py lying here must not replace the real one."""
    here = os.getcwd()
    sys.path[:] = [p for p in sys.path if p not in ("", here)] + [here]


def steps_per_frame(fps: float, dt: float) -> int:
    """Whole simulation steps per recorded frame; a UsageError if ``fps`` does not divide 1/dt."""
    from driftframe.framework.recorder import steps_per_frame as whole_steps
    try:
        return whole_steps(fps, dt, name="--fps")
    except ValueError as e:
        raise UsageError(str(e)) from None


def _apply_track(args, demo):
    """``record --track``: load the track, check it is the demo's, take its seed, camera and length."""
    if args.track is None:
        return None
    from driftframe.framework.input import load_track
    track = load_track(args.track)
    info = track.info
    if info.get("demo", args.demo) != args.demo:
        raise UsageError(f"--track {args.track} was flown in {info['demo']!r}, not {args.demo!r}")
    if args.seed is DEFAULT_SEED:
        args.seed = info.get("seed", 0)
    if args.camera is None:
        args.camera = info.get("camera")
    if args.sky is DEFAULT_SKY:
        args.sky = info.get("sky", "lines")
    if args.seconds is None:
        args.seconds = info["steps"] * info["dt"] if "steps" in info and "dt" in info else track.duration
    # the track's own entries, named as its file: a bad one would otherwise fail later, unnamed
    if args.camera is not None and args.camera not in CAMERAS:
        raise UsageError(f"--track {args.track}: camera {args.camera!r} is not one of {', '.join(CAMERAS)}")
    if args.sky not in SKIES:
        raise UsageError(f"--track {args.track}: sky {args.sky!r} is not one of {', '.join(SKIES)}")
    if "dt" in info and not math.isclose(info["dt"], demo_dt(demo), rel_tol=1e-9):
        # a track holds whole steps of its dt: at another dt every hold would cover other steps
        raise UsageError(f"--track {args.track}: dt {info['dt']!r} is not {args.demo}'s step "
                         f"{demo_dt(demo)!r} s; the track was flown at another step")
    return track


def _open_save(args):
    """``record --from SAVE``: the save read and checked (a :class:`SaveFile`), of this scene; its seed is
    taken unless --seed says otherwise. None without --from."""
    if args.from_save is None:
        return None
    from driftframe.framework.inputfile import InputFileError
    from driftframe.framework.save import SaveError, SaveFile
    try:
        saved = SaveFile(args.from_save)
    except (SaveError, InputFileError) as e:
        raise UsageError(f"--from {e}") from None
    scene = saved.manifest.get("scene") or {}
    if scene.get("name") != args.demo:
        raise UsageError(f"--from {args.from_save}: the save is of scene {scene.get('name')!r}, not {args.demo!r}")
    if args.seed is DEFAULT_SEED:
        args.seed = scene.get("seed", 0)
    return saved


#: Longest recording the command line starts: 1,000,000 frames (4.6 h at 60 fps), 10,000,000 fixed steps.
MAX_FRAMES = 1_000_000
MAX_STEPS = 10_000_000


def _sci(d: Decimal) -> str:
    """``6e+309``: three significant digits, no trailing zeros, for numbers a float cannot hold."""
    mantissa, exponent = f"{d:.2e}".split("e")
    return f"{mantissa.rstrip('0').rstrip('.')}e{exponent}"


def frame_count(seconds: float, fps: float, steps: int) -> int:
    """Frames for ``seconds`` at ``fps``; a UsageError naming the estimate when it is beyond the bounds."""
    estimate = seconds * fps                          # float: 1e308 * 60 is inf, never an OverflowError
    frames = max(1, round(estimate)) if math.isfinite(estimate) and estimate <= MAX_FRAMES else None
    if frames is None or frames * steps > MAX_STEPS:  # (a tiny --fps makes one frame of very many steps)
        exact = Decimal(seconds) * Decimal(fps)       # the count even where a float overflows
        count = f"{max(1, round(estimate)):,}" if estimate < 1e18 else _sci(exact)
        raise UsageError(f"--seconds {seconds:g} at {fps:g} fps is about {count} frames "
                         f"({_sci(max(exact, Decimal(1)) * steps)} fixed steps); a recording may have at most "
                         f"{MAX_FRAMES:,} frames ({MAX_FRAMES / fps / 3600:.3g} h at {fps:g} fps) and "
                         f"{MAX_STEPS:,} steps")
    return frames


def cmd_record(args) -> int:
    with _SetUp() as setup:
        return _record(args, setup)


def _record(args, setup: _SetUp) -> int:
    from driftframe.app import attach_rendering, make_world
    from driftframe.framework.recorder import X264_PRESET, OutputExistsError, check_output, output_format, record

    demo = _load_demo(args.demo, args.seed, args.sky)
    out = args.output or os.path.join("out", f"{_file_stem(args.demo)}.mp4")
    _distinct_paths(**{"-o": out, "--hash-log": args.hash_log, "--track": args.track, "--from": args.from_save})
    _output_names(**{"-o": out, "--hash-log": args.hash_log})
    track = _apply_track(args, demo)
    if args.sky is DEFAULT_SKY:
        from driftframe.rendering import default_sky
        args.sky = default_sky(demo)
    saved = _open_save(args)
    _output_file("--hash-log", args.hash_log, args.overwrite)
    seconds = args.seconds if args.seconds is not None else demo.SECONDS
    try:
        fmt = output_format(out)
    except ValueError as e:
        raise UsageError(str(e)) from None
    if fmt != "mp4" and (args.crf is not None or args.preset is not None):
        raise UsageError(f"--preset and --crf are for MP4 output, not {fmt.upper()} ({out!r})")
    k = steps_per_frame(args.fps, demo_dt(demo))
    frames = frame_count(seconds, args.fps, k)
    if args.output is None and not os.path.isdir("out"):
        try:
            os.makedirs("out", exist_ok=True)         # the default folder is ours to make; -o DIR/ must exist
        except OSError as e:
            raise UsageError(f"cannot create the default output folder 'out' here ({e.strerror}); "
                             "give -o FILE") from None
    if args.motion_blur > 1:
        from driftframe.systems.motion_blur import SubframePoses
        poses = SubframePoses()
    else:
        poses = None
    log = None
    try:
        check_output(out, overwrite=args.overwrite, format=fmt)    # before the costly part: build, compile
        _load_kernels(args.demo, args.seed, args.quiet, nv12=fmt == "mp4")   # a first run's compiling, before the bar
        world, demo = make_world(args.demo, seed=args.seed, track=track)
        try:
            if saved is not None:
                from driftframe.framework.save import SaveError
                try:
                    world.restore(saved)
                except SaveError as e:
                    raise UsageError(f"--from {e}") from None
            attach_rendering(world, size=args.size, camera=args.camera, sky=args.sky)
            if args.hash_log:
                from driftframe.framework.hashlog import attach_hash_log
                log = attach_hash_log(world, args.hash_log, overwrite=args.overwrite)
            setup.done()
            result = record(world, out, frames=frames, fps=args.fps, steps_per_frame=k, progress=not args.quiet,
                            overwrite=args.overwrite, motion_blur=args.motion_blur, interpolate=poses,
                            preset=args.preset or X264_PRESET, crf=args.crf, audio=not args.no_audio)
        finally:
            world.close()                           # the hash log is moved into place here, however it ended
    except OutputExistsError as e:                  # early, or at record()'s own check (made meanwhile)
        raise UsageError(f"{e} (or choose another -o)") from None
    failed = log is not None and log.error is not None
    if failed:                                      # a full disk under the log: the video is kept
        print(f"driftframe: error: {log.error}", file=sys.stderr)
    elif log is not None:
        print(f"wrote the hash log {log.path} ({log.lines} steps)", file=sys.stderr)
    if result.path is None:
        print("nothing written (interrupted before the first frame)", file=sys.stderr)
        return 128 + result.signal
    w, h = result.size
    print(f"wrote {result.path} ({result.frames} frames, {result.frames / args.fps:.2f} s of {args.demo} "
          f"at {args.fps:g} fps, {w}x{h}) in {result.seconds:.1f} s "
          f"({result.frames_per_second:.0f} frames/s)")
    return 128 + result.signal if result.interrupted else 1 if failed else 0


def _file_stem(name: str) -> str:
    """A file name for demo or scene ``name``: ``mygame.scene:build`` -> ``mygame.scene-build``."""
    return name.replace(":", "-")


def demo_dt(demo) -> float:
    """The fixed step of a demo module (1/60 s unless it says otherwise)."""
    return getattr(demo, "DT", 1.0 / 60.0)


def cmd_play(args) -> int:
    with _SetUp() as setup:
        return _play(args, setup)


def _play(args, setup: _SetUp) -> int:
    from driftframe.framework.bindings import load_bindings
    from driftframe.window import PlayError, check_display, play
    demo = _load_demo(args.demo, args.seed, args.sky)
    if args.sky is DEFAULT_SKY:
        from driftframe.rendering import default_sky
        args.sky = default_sky(demo)
    if not os.path.isdir(args.screenshots):
        raise UsageError(f"--screenshots: no such directory: {args.screenshots!r}")
    import tempfile

    from driftframe.framework.output import why_not_writable
    try:
        with tempfile.TemporaryFile(dir=args.screenshots):      # (an unnamed file: nothing to clean up)
            pass
    except OSError as e:
        raise UsageError(f"--screenshots: cannot write into {args.screenshots!r} "
                         f"({why_not_writable(args.screenshots, e)})") from None
    _distinct_paths(**{"--state-out": args.state_out, "--save-track": args.save_track,
                       "--hash-log": args.hash_log, "--bindings": args.bindings})
    for option in ("state_out", "save_track", "hash_log"):     # fail now, not when the session ends
        _output_file("--" + option.replace("_", "-"), getattr(args, option), args.overwrite)
    bindings = load_bindings(args.bindings) if args.bindings else None
    try:
        check_display()                              # after the options' own checks, before the costly part
    except PlayError as e:
        raise UsageError(str(e)) from None
    _load_kernels(args.demo, args.seed)             # a first run's compiling, before the window opens
    setup.done()
    try:
        return play(args.demo, size=args.size, seed=args.seed, camera=args.camera, state_out=args.state_out,
                    screenshot_dir=args.screenshots, sky=args.sky, bindings=bindings,
                    save_track=args.save_track,
                    hash_log=args.hash_log, frames=args.frames, overlay=args.overlay,
                    interpolate=not args.no_interpolation, overwrite=args.overwrite, sound=not args.mute)
    except PlayError as e:
        raise UsageError(str(e)) from None
