"""A recording's output: its format from the path, the checks made before anything is rendered, and the
part file it is written to and moved into place from (:mod:`framework.output`, shared by every writer).
"""
from __future__ import annotations

import os
from pathlib import Path

from driftframe.framework.output import OutputExistsError, check_name, check_output_file, new_part, publish

FORMATS = ("mp4", "gif", "png")
_SUFFIXES = {".mp4": "mp4", ".gif": "gif"}


class RecordingError(RuntimeError):
    """Writing the output failed (a full disk, the encoder failing); nothing half-written was kept."""


def output_format(path) -> str:
    """``"mp4"``, ``"gif"`` or ``"png"`` (a directory of frames) for ``path``; a clear error otherwise."""
    text = os.fspath(path)
    p = Path(text)
    if text.endswith(("/", os.sep)) or p.is_dir():
        return "png"
    if p.suffix == "":
        raise ValueError(f"output {text!r} has no suffix: give NAME.mp4 or NAME.gif, or {text + '/'!r} "
                         "(a trailing slash) for a directory of numbered PNG frames")
    fmt = _SUFFIXES.get(p.suffix.lower())
    if fmt is None:
        hint = " (a .png path is a single image: give a directory for numbered PNG frames)" \
            if p.suffix.lower() == ".png" else ""
        raise ValueError(f"unknown output format {p.suffix!r} for {text!r}{hint}; "
                         "use .mp4, .gif, or a directory for numbered PNG frames")
    return fmt


def check_output(path, *, overwrite: bool = False, format: str | None = None, probe: bool = True) -> None:
    """Raise what :func:`framework.recorder.record` would raise for ``path`` before it renders anything;
    leave nothing.

    An existing output without ``overwrite``, a missing folder, a directory
    where a file should be (and the reverse), a read-only file to replace, a
    name too long, and (``probe``) a folder where no file can be made (a part
    file is made there and removed: :func:`framework.output.check_output_file`).
    A caller with costly work before ``record`` (building a world, a first
    run's compiling) checks first; ``record`` checks again.
    """
    fmt = format or output_format(path)
    path = Path(os.fspath(path))
    parent = path.parent
    check_name(path)                                  # first: a name too long fails every later stat too
    if not parent.exists():
        raise FileNotFoundError(f"cannot write {str(path)!r}: directory {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise NotADirectoryError(f"cannot write {str(path)!r}: {str(parent)!r} is not a directory")
    if fmt == "png":
        if path.exists() and not path.is_dir():
            raise FileExistsError(f"cannot write PNG frames to {str(path)!r}: it exists and is not a directory")
        if path.is_dir():
            names = os.listdir(path)
            foreign = [n for n in names if not (n.startswith("frame_") and n.endswith(".png"))]
            if foreign:
                raise FileExistsError(f"cannot write PNG frames to {str(path)!r}: it holds other files "
                                      f"({', '.join(sorted(foreign)[:5])}); give an empty or new directory")
            if names and not overwrite:
                raise OutputExistsError(f"{str(path)!r} holds PNG frames already; pass overwrite=True "
                                        "(--overwrite) to replace them")
    elif path.is_dir():
        raise IsADirectoryError(f"cannot write {str(path)!r}: it is a directory")
    elif path.exists() or path.is_symlink():
        if not overwrite:
            raise OutputExistsError(f"{str(path)!r} exists; pass overwrite=True (--overwrite) to replace it")
        if not path.stat().st_mode & 0o222:
            raise PermissionError(f"cannot replace {str(path)!r}: it is read-only (make it writable or "
                                  "delete it first)")
    # the rest (a name too long, a folder where nothing can be made) is the shared check's
    check_output_file(path, overwrite=True, folder=fmt == "png", probe=probe)


def make_parent(path: Path) -> None:
    """Make the output's folder if it is missing (``record(world, "out/mine.mp4")`` in a new folder).

    Called after every other check, so a refused call leaves nothing, as the
    command line makes its default ``out/``.
    """
    check_name(path)                                  # (a name too long: refused before any folder is made)
    if not path.parent.exists() and not path.parent.is_symlink():
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise type(e)(f"cannot write {str(path)!r}: cannot create its directory "
                          f"{str(path.parent)!r} ({e.strerror})") from None


def prepare_path(path: Path, fmt: str, overwrite: bool) -> Path:
    """Check the target and create the temporary output beside it (proving it is writable)."""
    check_output(path, overwrite=overwrite, format=fmt, probe=False)
    return new_part(path, folder=fmt == "png")


def move_into_place(tmp: Path, path: Path, fmt: str, overwrite: bool) -> None:
    """Publish the finished part file (or folder of frames) under its own name."""
    publish(tmp, path, overwrite=overwrite or fmt == "png", folder=fmt == "png")
