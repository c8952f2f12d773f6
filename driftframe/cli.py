"""The ``driftframe`` command line: list the demos, record one off-screen, or fly one in a window.

Every error a user can cause (an unknown demo, a bad size, an unwritable
path, an existing output, no display) ends in one line on stderr and exit
status 2, never a traceback. A write that fails while recording (a full
disk) is one line and exit status 1. A recording stopped by Ctrl-C, SIGTERM
or SIGHUP keeps the frames written so far and exits with 128 + the signal's
number (130, 143, 129), as the shell reports a process the signal killed;
``play`` keeps its track and hash log the same way (and exits 1 when the X
server goes away). Every output is written whole or not at all
(:mod:`framework.output`) and checked before the costly part starts.
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import time
from decimal import Decimal

from driftframe.framework import __version__

CAMERAS = ("cockpit", "chase", "overhead")
SKIES = ("lines", "starfield")


class UsageError(Exception):
    """A problem with what the user asked for: printed as one line, exit status 2."""


def _positive_float(name):
    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(v) or v <= 0:
            raise argparse.ArgumentTypeError(f"{name} must be a finite number > 0, got {text!r}")
        return v
    return parse


class _DefaultSeed(int):
    """The seed when --seed is not given: 0, but recognisable (``record --track`` takes the track's)."""


DEFAULT_SEED = _DefaultSeed(0)


class _DefaultSky(str):
    """The sky when --sky is not given: the demo's (``SKY``, else the starfield), recognisable
    (``record --track`` takes the track's)."""


DEFAULT_SKY = _DefaultSky("starfield")


def _blur(text):
    from driftframe.framework.recorder import MAX_MOTION_BLUR
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"motion blur must be a whole number of sub-frames, got {text!r}") from None
    if not 1 <= v <= MAX_MOTION_BLUR:
        raise argparse.ArgumentTypeError(f"motion blur must be between 1 and {MAX_MOTION_BLUR} sub-frames, "
                                         f"got {text!r}")
    return v


def _crf(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"crf must be a whole number from 0 (lossless) to 51, got {text!r}") from None
    if not 0 <= v <= 51:
        raise argparse.ArgumentTypeError(f"crf must be a whole number from 0 (lossless) to 51, got {text!r}")
    return v


def _size(text):
    from driftframe.app import parse_size
    try:
        return parse_size(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _keys_epilog() -> str:
    from driftframe.framework.input import keys_help
    return ("keys while playing (change them with --bindings FILE; `driftframe keys` prints the defaults):\n"
            + keys_help())


def _int_at_least(name, low: int = 1):
    """An argparse type: an integer >= ``low`` (1 unless said), named ``name`` in the error."""
    def parse(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer >= {low}, got {text!r}") from None
        if v < low:
            raise argparse.ArgumentTypeError(f"{name} must be an integer >= {low}, got {text!r}")
        return v
    return parse


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


def build_parser() -> argparse.ArgumentParser:
    from driftframe import demos

    p = argparse.ArgumentParser(
        prog="driftframe",
        description="driftframe: Newtonian space-flight scenes built from esper components. "
                    "Record a demo off-screen to video, or fly it in a window.",
        epilog=_keys_epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--version", action="version", version=f"driftframe {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    sub.add_parser("list", help="list the demos, one line each")

    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("demo", metavar="SCENE",
                        help=f"a demo, one of: {', '.join(demos.NAMES)}; or your own scene as module:function "
                             "(e.g. mygame.scene:build), imported from here or from an installed package")
    common.add_argument("--size", type=_size, default=(1280, 720), metavar="WxH",
                        help="frame size in pixels (default 1280x720)")
    common.add_argument("--seed", type=_int_at_least("seed", 0), default=DEFAULT_SEED, metavar="N",
                        help="random seed of the scene (default 0)")
    common.add_argument("--camera", choices=CAMERAS, default=None,
                        help="camera to start with (default: the demo's own)")
    common.add_argument("--sky", choices=SKIES, default=DEFAULT_SKY,
                        help="sky: a starfield made from the seed (the default; the rotation demo: lines) or the "
                             "articles' green line cube")

    rec = sub.add_parser("record", parents=[common], help="record a demo off-screen to MP4, GIF or PNG frames",
                         description="Render DEMO off-screen, one frame per simulated frame, following the "
                                     "demo's scripted input. The same demo, seed and options give identical "
                                     "output on every run.")
    rec.add_argument("--seconds", type=_positive_float("seconds"), default=None, metavar="S",
                     help="simulated seconds to record (default: the demo's own length)")
    rec.add_argument("--fps", type=_positive_float("fps"), default=60.0, metavar="F",
                     help="frames per second; must divide the 60 Hz simulation rate (60, 30, 20, 15, ...)")
    rec.add_argument("-o", "--output", default=None, metavar="FILE",
                     help="FILE.mp4, FILE.gif, or DIR/ (a trailing slash, or an existing directory) for "
                          "numbered PNGs (default out/DEMO.mp4, creating out/)")
    rec.add_argument("--overwrite", action="store_true",
                     help="replace the output and the --hash-log file if they exist (refused otherwise)")
    rec.add_argument("--motion-blur", type=_blur, default=1, metavar="N",
                     help="average N sub-frames, posed between the fixed steps, into each frame "
                          "(default 1: none); a fast spin then blurs instead of strobing")
    from driftframe.framework.recorder import X264_CRF, X264_DEFAULT_CRF, X264_PRESET, X264_PRESETS
    rec.add_argument("--preset", choices=X264_PRESETS, default=None, metavar="NAME",
                     help=f"MP4: x264's speed against file size, one of {', '.join(X264_PRESETS)} (default "
                          f"{X264_PRESET}: fastest; veryfast makes files a third to half the size for about twice "
                          "the encoder's CPU)")
    rec.add_argument("--crf", type=_crf, default=None, metavar="Q",
                     help=f"MP4: quality, 0 (lossless) to 51, lower is better (default: the preset's own, "
                          f"{X264_CRF.get(X264_PRESET, X264_DEFAULT_CRF)} for {X264_PRESET} and "
                          f"{X264_DEFAULT_CRF} for the others, about the same picture)")
    rec.add_argument("--quiet", action="store_true", help="no progress bar")
    rec.add_argument("--no-audio", action="store_true",
                     help="MP4: leave out the sound track (impacts and thrust, synthesised from the events)")
    rec.add_argument("--track", default=None, metavar="FILE",
                     help="fly the track FILE (from `play --save-track`) instead of the demo's script; its "
                          "seed, camera, sky and length are used unless --seed, --camera, --sky, --seconds say "
                          "otherwise")
    rec.add_argument("--hash-log", default=None, metavar="FILE",
                     help="write one 'STEP HASH' line per step (compare two with `driftframe diverge`)")
    rec.add_argument("--from", dest="from_save", default=None, metavar="SAVE",
                     help="start from the save SAVE (world.save, or play's F5) of this scene: its entities, "
                          "step count and state; --seconds more are recorded")

    play = sub.add_parser("play", parents=[common], help="fly a demo in a window with the keyboard",
                          description="Open a window and fly DEMO with the keyboard. The physics runs in "
                                      "fixed 1/60 s steps whatever the frame rate.",
                          epilog=_keys_epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    play.add_argument("--screenshots", default=".", metavar="DIR", help="where F12 saves PNGs (default: here)")
    play.add_argument("--state-out", default=None, metavar="FILE",
                      help="on quit, write the player's state and the camera mode to FILE as JSON")
    play.add_argument("--save-track", default=None, metavar="FILE",
                      help="on quit, write the flight (every step's input) to FILE; "
                           "`driftframe record DEMO --track FILE` re-renders it")
    play.add_argument("--hash-log", default=None, metavar="FILE",
                      help="write one 'STEP HASH' line per step (compare two with `driftframe diverge`)")
    play.add_argument("--overwrite", action="store_true",
                      help="replace --save-track, --hash-log and --state-out files that exist (refused otherwise)")
    play.add_argument("--bindings", default=None, metavar="FILE",
                      help="key and gamepad bindings, TOML (`driftframe keys` prints the defaults)")
    play.add_argument("--frames", type=_int_at_least("frames"), default=None, metavar="N",
                      help="quit after N frames (the closing line gives the frame rate)")
    play.add_argument("--overlay", action="store_true", help="start with the F3 overlay shown")
    play.add_argument("--mute", action="store_true",
                      help="no sound (impacts and thrust through the sound card; none there: a one-line warning)")
    play.add_argument("--no-interpolation", action="store_true",
                      help="draw the state after the last step instead of poses between steps")

    keys = sub.add_parser("keys", help="print the key and gamepad bindings as a TOML file",
                          description="Print the bindings (the defaults, or FILE's) in the TOML format that "
                                      "`driftframe play --bindings FILE` reads.")
    keys.add_argument("--bindings", default=None, metavar="FILE", help="show FILE's bindings over the defaults")

    div = sub.add_parser("diverge", help="the first step where two hash logs differ",
                         description="Compare two --hash-log files line by line; print the first step "
                                     "where the states differ. Exit status 0 when they agree, 1 when not.")
    div.add_argument("log_a", metavar="LOG_A")
    div.add_argument("log_b", metavar="LOG_B")

    batch = sub.add_parser("batch", help="many runs from a TOML grid, on local processes or a Dask cluster",
                           description="Run every combination in SPEC.toml (demo or scene, seeds, overrides, "
                                       "...; see driftframe/batch_file.py) headless or recorded, then write "
                                       "summary.csv, summary.md and summary.png to the output folder. "
                                       "Each run is journalled as it ends (journal.jsonl). Ctrl-C, SIGTERM or "
                                       "SIGHUP stops cleanly: no half-written output is left, the summary of "
                                       "what ran is written, and --resume runs the rest.")
    batch.add_argument("spec", metavar="SPEC.toml", help="the batch file")
    batch.add_argument("-j", "--jobs", type=_jobs, default=None, metavar="N",
                       help="processes running specs: this one and N-1 workers (default: from the cores; 1 runs "
                            "serially in this process)")
    batch.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run on this dask.distributed scheduler (tcp://host:8786) instead of local processes "
                            "(default: $DASK_SCHEDULER_ADDRESS if set and -j is not given)")
    batch.add_argument("--scheduler-file", default=None, metavar="FILE",
                       help="run on the scheduler that `dask scheduler --scheduler-file FILE` describes")
    batch.add_argument("--resume", action="store_true",
                       help="continue a stopped batch: skip the runs that journal.jsonl in the output folder "
                            "lists as finished (same spec, output still there); with --overwrite, outputs it "
                            "does not list are replaced")
    batch.add_argument("--retries", type=_int_at_least("--retries", 0), default=1, metavar="N",
                       help="run again a run whose worker process died, up to N times (default 1)")
    batch.add_argument("-o", "--output", default=None, metavar="DIR",
                       help="folder for the recordings and the summary (default out/SPEC)")
    batch.add_argument("--overwrite", action="store_true",
                       help="replace outputs that exist already (default: refuse them before any run starts)")
    batch.add_argument("--quiet", action="store_true", help="no progress bar")

    new = sub.add_parser("new", help="start a game of your own: a folder with a scene, components, systems, tests",
                         description="Write the folder NAME: pyproject.toml, NAME/scene.py (the scene, "
                                     "`driftframe play NAME.scene:build`), NAME/components.py, NAME/systems.py "
                                     "(one example system) and tests/test_scene.py. Refuses a folder that exists.")
    new.add_argument("name", metavar="NAME", help="the game's name: a Python identifier (its package's name)")

    warm = sub.add_parser("warm", help="compile (or load) every physics kernel now, into the kernel cache",
                          description="Compile every numba kernel for this machine, or load it from the cache "
                                      "if it is there, so that the next play, record or batch starts at once. "
                                      "The cache is per user (the folder is printed; NUMBA_CACHE_DIR moves it).")
    warm.add_argument("--quiet", action="store_true", help="no progress line")
    return p


def _jobs(text):
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"-j must be an integer >= 1, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"-j must be an integer >= 1, got {text!r}")
    return v


def cmd_list(args) -> int:
    from driftframe import demos
    width = max(map(len, demos.NAMES))
    for name in demos.NAMES:
        print(f"{name:<{width}}  {demos.load(name).DESCRIPTION}")
    return 0


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
            from driftframe.systems.render import default_sky
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


def _compile(task, quiet: bool = False) -> None:
    """``task(watch)`` on a helper thread while this, the main thread, shows the compile and waits.

    ``watch`` is a :class:`~framework.kernels.CompileWatch`. A Ctrl-C, SIGTERM
    or SIGHUP during a first run's compile then stops the command here,
    between waits, with the usual message and exit status (the recorder's
    :class:`~framework.recorder.StopSignals` takes them). In the main thread
    it would land inside numba's compiler, which calls back into Python
    through ctypes, where an exception is printed and dropped and the compile
    goes on. The helper is a daemon: it ends with the process.
    """
    import threading

    from driftframe.framework.kernels import CompileWatch
    from driftframe.framework.recorder import Interrupted, StopSignals

    failed: list[BaseException] = []
    watch = CompileWatch()

    def run():
        try:
            with watch:
                task(watch)
        except BaseException as e:   # noqa: BLE001 - handed to the main thread
            failed.append(e)

    helper = threading.Thread(target=run, name="driftframe-kernels", daemon=True)
    shown = _CompileProgress(watch, enabled=not quiet)
    with StopSignals(True) as stop:
        helper.start()
        while helper.is_alive() and stop.requested is None:
            helper.join(0.2)
            shown.tick()
        if stop.requested is not None:
            shown.end(stopped=True)
            raise Interrupted(stop.requested)
    shown.end(stopped=bool(failed))
    if failed:
        raise failed[0]


def _load_kernels(name: str, seed: int, quiet: bool = False, nv12: bool = False) -> None:
    """:func:`driftframe.app.load_kernels` through :func:`_compile`; ``nv12``: the MP4 writer's
    colour conversion kernel too (else a first run compiles it at frame 0, under the progress bar)."""
    from driftframe.app import load_kernels

    def task(watch):
        load_kernels(name, seed=seed)
        if nv12:
            import numpy as np

            from driftframe.framework.yuv import rgba_to_nv12
            rgba_to_nv12(np.zeros((2, 2, 4), np.uint8), 2, 2)
    _compile(task, quiet)


def cmd_record(args) -> int:
    from driftframe.app import attach_rendering, make_world
    from driftframe.framework.recorder import X264_PRESET, OutputExistsError, check_output, output_format, record

    demo = _load_demo(args.demo, args.seed, args.sky)
    out = args.output or os.path.join("out", f"{_file_stem(args.demo)}.mp4")
    _distinct_paths(**{"-o": out, "--hash-log": args.hash_log, "--track": args.track, "--from": args.from_save})
    _output_names(**{"-o": out, "--hash-log": args.hash_log})
    track = _apply_track(args, demo)
    if args.sky is DEFAULT_SKY:
        from driftframe.systems.render import default_sky
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
    from driftframe.framework.bindings import load_bindings
    from driftframe.window import PlayError, check_display, play
    demo = _load_demo(args.demo, args.seed, args.sky)
    if args.sky is DEFAULT_SKY:
        from driftframe.systems.render import default_sky
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
    try:
        return play(args.demo, size=args.size, seed=args.seed, camera=args.camera, state_out=args.state_out,
                    screenshot_dir=args.screenshots, sky=args.sky, bindings=bindings,
                    save_track=args.save_track,
                    hash_log=args.hash_log, frames=args.frames, overlay=args.overlay,
                    interpolate=not args.no_interpolation, overwrite=args.overwrite, sound=not args.mute)
    except PlayError as e:
        raise UsageError(str(e)) from None


def cmd_keys(args) -> int:
    from driftframe.framework.bindings import bindings_toml, load_bindings
    print(bindings_toml(load_bindings(args.bindings) if args.bindings else None), end="")
    return 0


def cmd_diverge(args) -> int:
    from driftframe.framework.hashlog import count_steps, first_divergence
    d = first_divergence(args.log_a, args.log_b)
    if d is None:
        print(f"the logs agree for all {count_steps(args.log_a)} steps")
        return 0
    print(d)
    return 1


def cmd_batch(args) -> int:
    from driftframe.batch_command import cmd_batch as run
    return run(args)


def cmd_new(args) -> int:
    from driftframe.scaffold import ScaffoldError, new
    try:
        root = new(args.name)
    except ScaffoldError as e:
        raise UsageError(str(e)) from None
    print(f"wrote {root}/. Fly it:\n    cd {root}\n    driftframe play {args.name}.scene:build\n"
          f"    driftframe record {args.name}.scene:build -o out/{args.name}.mp4\n    python -m pytest")
    return 0


def cmd_warm(args) -> int:
    from driftframe import warmup
    from driftframe.framework import kernels

    missed: list = []
    _compile(lambda watch: missed.extend(warmup.warm(watch)), args.quiet)
    total = len(kernels.registry(load=False))
    if missed:
        print(f"driftframe: warning: the warm-up did not reach {len(missed)} of {total} kernels "
              f"({', '.join(kernels.kernel_name(d) for d in missed)}); they compile at their first call",
              file=sys.stderr)
    print(f"{total - len(missed)} of {total} kernels ready in {kernels.cache_dir()}")
    return 0


class _CompileProgress:
    """Shows a compile while :func:`_compile` waits: a line saying so, then which kernel, n of m and the time.

    numba reports a compile only when its cache misses, so a warm run shows
    nothing. On a terminal the progress line is rewritten in place (``\\r``) at
    least once a second; into a file or a pipe (a CI log) a whole line is
    written at most every :attr:`LOG_EVERY` seconds, and the last state when
    the compile ends. The summary line follows, before the command goes on.
    """

    LOG_EVERY = 5.0

    def __init__(self, watch, enabled: bool):
        self.watch = watch
        self.enabled = enabled
        self.announced = False
        self.last = (None, 0.0)
        self.width = 0
        self.tty = sys.stderr.isatty()
        self.named = None

    def _write(self, text: str) -> None:
        sys.stderr.write(text)
        sys.stderr.flush()

    def tick(self, force: bool = False) -> None:
        if not self.enabled or self.watch.n == 0:
            return
        if not self.announced:
            from driftframe.framework.kernels import cache_dir
            self.announced = True
            self._write(f"driftframe: compiling the physics kernels for this machine: the first run only "
                        f"(they are cached in {cache_dir()})\n")
        line = f"driftframe: compiling {self.watch.line()}"
        now = time.monotonic()
        if not self.tty:
            # a log file or a pipe (CI): a whole line at most every LOG_EVERY s, and the last state at the end
            if ": " in line.rsplit(" kernels, ", 1)[-1]:
                self.named = line                         # the latest state that names its kernel
            if force:
                line = self.named or line
            if force or now - self.last[1] >= self.LOG_EVERY:
                if line != self.last[0]:
                    self._write(line + "\n")
                self.last = (line, now)
            return
        if line != self.last[0] or now - self.last[1] >= 1.0:
            self._write("\r" + line.ljust(self.width))     # spaces over a longer previous line
            self.width = len(line)
            self.last = (line, now)

    def end(self, stopped: bool) -> None:
        if not self.enabled:
            return
        self.tick(force=True)
        if not self.announced:
            return
        seconds, n, m = self.watch.elapsed(), self.watch.n, self.watch.m
        if self.tty:
            self._write("\n")                             # end the line rewritten in place
        if stopped:
            self._write(f"driftframe: stopped after {seconds:.0f} s of compiling kernels: those finished are "
                        f"cached, the rest are compiled on the next run ({n} of {m} begun)\n")
        else:
            self._write(f"driftframe: compiled {n} kernels in {seconds:.0f} s; "
                        "later runs load them from the cache\n")


class _SignalsInterrupt:
    """SIGTERM and SIGHUP raise an interrupt while a command runs, as Ctrl-C does (where they are not ignored).

    The parts that stop gracefully (recording, playing, compiling) take them
    over with :class:`~framework.recorder.StopSignals`; anywhere else a signal
    ends the command with one line and exit status 128 + n instead of
    killing it without a word.
    """

    def __enter__(self):
        import threading

        from driftframe.framework.stop_signals import STOP_SIGNALS, raise_interrupted    # light: no numpy
        self._old = {}
        if threading.current_thread() is threading.main_thread():
            for s in STOP_SIGNALS:
                if signal.getsignal(s) is signal.SIG_DFL:
                    self._old[s] = signal.signal(s, raise_interrupted)
        return self

    def __exit__(self, *exc):
        for s, old in self._old.items():
            signal.signal(s, old)


def _shell_words(e) -> str:
    """A library message in the command line's words: the library says ``pass overwrite=True (--overwrite)``
    for both; on the command line only the option means anything."""
    return (str(e).replace("pass overwrite=True (--overwrite)", "pass --overwrite")
            .replace("pass --overwrite (overwrite=True)", "pass --overwrite")
            .replace("pass overwrite=True", "pass --overwrite"))


def main(argv: list[str] | None = None) -> int:
    # SIGTERM and SIGHUP end in one line from the start: the imports in _main take a tenth of a second
    with _SignalsInterrupt():
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help()
            return 0
        from driftframe.framework.gl import GLUnavailableError
        from driftframe.framework.kernels import KernelCompileError
        from driftframe.framework.recorder import RecordingError
    except KeyboardInterrupt as e:         # a signal while the modules load: nothing touched yet, no traceback
        signum = getattr(e, "signum", signal.SIGINT)
        print(f"driftframe: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum

    handlers = {"list": cmd_list, "record": cmd_record, "play": cmd_play, "keys": cmd_keys,
                "diverge": cmd_diverge, "batch": cmd_batch, "warm": cmd_warm,
                "new": cmd_new}
    try:
        return handlers[args.command](args)
    except UsageError as e:
        print(f"driftframe: error: {_shell_words(e)}", file=sys.stderr)
        return 2
    except (RecordingError, KernelCompileError) as e:
        print(f"driftframe: error: {_shell_words(e)}", file=sys.stderr)
        return 1
    except GLUnavailableError as e:
        print(f"driftframe: error: {e}", file=sys.stderr)
        return 2
    except (ValueError, LookupError, OSError) as e:
        # raised by the library's own input checks: they name the bad value; no traceback needed
        print(f"driftframe: error: {_shell_words(e)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as e:
        # Ctrl-C, or SIGTERM / SIGHUP turned into an interrupt by the recorder: exit as the signal would
        signum = getattr(e, "signum", signal.SIGINT)
        print(f"driftframe: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum


if __name__ == "__main__":
    sys.exit(main())
