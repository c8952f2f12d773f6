"""The ``driftframe`` command line's parser: its commands, their options, and the options' checks.

Each option's type names the option and the bad value in its error (argparse prints it and exits 2).
"""
from __future__ import annotations

import argparse
import math

from driftframe.framework import __version__

CAMERAS = ("cockpit", "chase", "overhead", "frame")     # components.camera.MODES (not imported: a light parser)
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


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose epilog can be the key bindings, made only when the help is printed.

    ``keys_epilog=True``: :func:`_keys_epilog` at ``format_help``. Building it in the parser imported
    framework.input (and numpy with it) for every command, which only ``--help`` uses.
    """

    def __init__(self, *args, keys_epilog: bool = False, **kwargs):
        super().__init__(*args, **kwargs)
        self._keys_epilog = keys_epilog

    def format_help(self) -> str:
        if self._keys_epilog and self.epilog is None:
            self.epilog = _keys_epilog()
        return super().format_help()


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


def build_parser() -> argparse.ArgumentParser:
    from driftframe import demos

    p = _Parser(
        prog="driftframe",
        description="driftframe: Newtonian space-flight scenes built from esper components. "
                    "Record a demo off-screen to video, or fly it in a window.",
        keys_epilog=True, formatter_class=argparse.RawDescriptionHelpFormatter)
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
                          keys_epilog=True, formatter_class=argparse.RawDescriptionHelpFormatter)
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
    batch.add_argument("-j", "--jobs", type=_int_at_least("-j"), default=None, metavar="N",
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
