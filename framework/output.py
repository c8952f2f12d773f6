"""One discipline for every file driftframe writes: a temporary file beside the target, moved into place.

Videos, GIFs, PNG folders (:mod:`framework.recorder`), tracks
(:func:`framework.input.save_track`), hash logs (:mod:`framework.hashlog`),
``play --state-out`` and the batch summary all follow the same rules:

* The output is written to ``.NAME.<pid>.<random>.part<suffix>`` in the
  target's folder and moved into place (``rename``, atomic on one file
  system) only when complete: a reader never sees half a file, and a failed
  write leaves the old file (if any) as it was.
* An existing file is never replaced unless the caller says ``overwrite``
  (``--overwrite``). Without it the move is a hard link, which fails if the
  name appeared meanwhile (another process), so nothing is clobbered.
* Only files this run created are ever removed: its own part files, and
  part files of runs whose process is gone (:func:`remove_stale_parts`;
  the pid in the name tells).
* The finished file gets the permissions the umask gives a new file
  (0666 & ~umask; 0777 & ~umask for a folder), as ``open()`` would: the
  part file itself is private (0600) while it is written.
* :func:`check_output_file` finds every problem that can be found before
  any work (a missing or read-only folder, an existing output, a name too
  long for the file system), so a command checks all its outputs before a
  compile or a build.
"""
from __future__ import annotations

import errno
import os
import re
import shutil
import tempfile
from pathlib import Path


class OutputExistsError(FileExistsError):
    """The output exists and ``overwrite`` was not given."""


class OutputError(OSError):
    """An output that cannot be written; the message names the file (``errno`` says why, for callers)."""

    def __init__(self, code: int | None, message: str):
        super().__init__(message)             # one argument: str() is the message alone, no "[Errno 28]"
        self.errno = code


# -- names of part files ------------------------------------------------------------------------
#: Room in a file name for ``.`` + ``.<pid>.<random>.part`` + a suffix around the target's name.
_PART_EXTRA = 40


def _name_max(folder: Path) -> int:
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        return 255


def part_prefix(path: Path) -> str:
    """``.NAME.<pid>.``: the start of this process's part files for ``path`` (NAME cut to fit the file system)."""
    path = Path(path)
    name = path.name
    room = _name_max(path.parent if str(path.parent) else Path(".")) - _PART_EXTRA
    if len(os.fsencode(name)) > room:                # a long name keeps its start: still recognisably its part
        name = os.fsdecode(os.fsencode(name)[:max(1, room)]).rstrip("\ufffd") or "x"
    return f".{name}.{os.getpid()}."


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError):
        return True                                   # someone else's process: leave its files alone
    return True


def remove_stale_parts(path) -> list[Path]:
    """Delete temporary outputs for ``path`` left by runs whose process is gone (SIGKILL, a crash).

    Only files named ``.NAME.<pid>.<random>.part...`` / ``.old`` beside the
    target whose ``<pid>`` is no longer running are removed; a run writing
    the same output in another process keeps its files. Returns what was
    removed.
    """
    path = Path(os.fspath(path))
    parent = path.parent
    prefix = part_prefix(path)
    stem = prefix[:prefix.rindex(".", 0, len(prefix) - 1) + 1]          # ".NAME."
    pattern = re.compile(re.escape(stem) + r"(\d+)\.[^/]*\.(part[^/]*|old)$")
    removed = []
    try:
        names = os.listdir(parent)
    except OSError:
        return removed
    for name in names:
        m = pattern.match(name)
        if m is None or _pid_alive(int(m.group(1))):
            continue
        stale = parent / name
        try:
            if stale.is_dir() and not stale.is_symlink():
                shutil.rmtree(stale)
            else:
                stale.unlink()
            removed.append(stale)
        except OSError:
            pass
    return removed


# -- checks before any work ---------------------------------------------------------------------
def _mount_of(path: Path) -> tuple[str, str] | None:
    """(mount point, file system type) holding ``path``, from /proc/self/mounts; None if unknown."""
    try:
        with open("/proc/self/mounts") as f:
            mounts = [line.split()[1:3] for line in f if len(line.split()) >= 3]
    except OSError:
        return None
    real = os.path.realpath(path)
    best = None
    for mnt, fstype in mounts:
        mnt = mnt.replace("\\040", " ")
        if real == mnt or real.startswith(mnt.rstrip("/") + "/"):
            if best is None or len(mnt) > len(best[0]):
                best = (mnt, fstype)
    return best


def why_not_writable(parent: Path, e: OSError) -> str:
    """The reason a new file cannot be made in ``parent``, in words."""
    if e.errno == errno.EROFS:
        return "it is on a read-only file system"
    if e.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if e.errno in (errno.ENOSPC, errno.EDQUOT):
        return "no space left on the device"
    if e.errno == errno.ENAMETOOLONG:
        return "the file name is too long for the file system"
    if e.errno == errno.ENOENT:
        # the directory exists (checked before), yet a new file there "does not exist": a virtual file system
        where = _mount_of(parent)
        if where is not None:
            return f"it is on a {where[1]} file system ({where[0]}), which does not accept new files"
        return "the file system does not accept new files"
    return e.strerror or str(e)


def no_space(e: BaseException) -> bool:
    """Whether ``e`` is a full disk (or quota, or a file too large for the file system)."""
    return isinstance(e, OSError) and e.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def _label(option: str | None, path) -> str:
    return f"{option} {str(path)!r}" if option else repr(str(path))


def check_name(path, what: str | None = None) -> None:
    """An :class:`OutputError` when ``path``'s last part is longer than its file system allows (255 bytes)."""
    path = Path(os.fspath(path))
    parent = path.parent if str(path.parent) else Path(".")
    n, most = len(os.fsencode(path.name)), _name_max(parent if parent.is_dir() else Path("."))
    if n > most:
        raise OutputError(errno.ENAMETOOLONG, f"cannot write {what or repr(str(path))}: the file name is {n} bytes "
                          f"long, longer than the {most} the file system allows")


def check_output_file(path, *, overwrite: bool = False, option: str | None = None, folder: bool = False,
                      probe: bool = True) -> None:
    """Raise now what writing ``path`` would raise later; leave nothing behind.

    ``option`` (``"--hash-log"``) starts the message. ``folder``: the output
    is a folder of files (PNG frames), not a file. Refused: a missing
    folder, a file where the folder should be, a directory where a file
    should be (and the reverse), an existing output without ``overwrite``, a
    read-only file to replace, a name too long for the file system, and
    (``probe``) a folder where no new file can be made: the check makes and
    removes a part file there, which also finds a read-only file system.
    """
    path = Path(os.fspath(path))
    what = _label(option, path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.exists():
        raise FileNotFoundError(f"cannot write {what}: directory {str(parent)!r} does not exist")
    if not parent.is_dir():
        raise NotADirectoryError(f"cannot write {what}: {str(parent)!r} is not a directory")
    check_name(path, what)
    if folder:
        if path.exists() and not path.is_dir():
            raise FileExistsError(f"cannot write {what}: it exists and is not a directory")
    elif path.is_dir():
        raise IsADirectoryError(f"cannot write {what}: it is a directory")
    elif path.exists() or path.is_symlink():
        if not overwrite:
            raise OutputExistsError(f"{what} exists; pass --overwrite (overwrite=True) to replace it")
        if path.exists() and not path.stat().st_mode & 0o222:
            raise PermissionError(f"cannot replace {what}: it is read-only (make it writable or delete it first)")
    if probe:
        try:
            fd, tmp = tempfile.mkstemp(prefix=part_prefix(path), suffix=".part", dir=parent)
        except OSError as e:
            raise PermissionError(f"cannot write {what}: directory {str(parent)!r} is not writable "
                                  f"({why_not_writable(parent, e)})") from None
        os.close(fd)
        os.unlink(tmp)


def same_paths(named: dict) -> None:
    """A ValueError when two options name the same file: ``{"-o": "out/a.mp4", "--hash-log": ...}``.

    Paths are compared after resolving links and ``..``; ``out/f/`` and
    ``out/f`` are one path. None values are skipped.
    """
    seen: dict[str, str] = {}
    for option, path in named.items():
        if path is None:
            continue
        key = os.path.realpath(os.fspath(path).rstrip("/") or "/")
        if key in seen:
            raise ValueError(f"{seen[key]} and {option} name the same file {str(path)!r}: "
                             "each output needs its own path")
        seen[key] = option


# -- writing ------------------------------------------------------------------------------------
def umask() -> int:
    """The process's umask (read by setting and restoring it)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def new_part(path, *, folder: bool = False, suffix: str | None = None) -> Path:
    """Create this run's part file (or folder) for ``path``, beside it; stale parts of dead runs go first."""
    path = Path(os.fspath(path))
    parent = path.parent if str(path.parent) else Path(".")
    remove_stale_parts(path)
    try:
        if folder:
            return Path(tempfile.mkdtemp(prefix=part_prefix(path), suffix=".part", dir=parent))
        fd, tmp = tempfile.mkstemp(prefix=part_prefix(path), suffix=f".part{path.suffix if suffix is None else suffix}",
                                   dir=parent)
        os.close(fd)
        return Path(tmp)
    except OSError as e:
        raise PermissionError(f"cannot write {str(path)!r}: directory {str(parent)!r} is not writable "
                              f"({why_not_writable(parent, e)})") from None


def publish(tmp: Path, path: Path, *, overwrite: bool, folder: bool = False) -> None:
    """Move the finished part ``tmp`` into place at ``path``, with the umask's permissions.

    Without ``overwrite``, a file that appeared at ``path`` meanwhile is
    kept and :class:`OutputExistsError` raised (the part is removed). A
    folder replaces an existing folder by two renames (the old one is
    deleted after).
    """
    tmp, path = Path(tmp), Path(path)
    mask = umask()
    # mkstemp/mkdtemp made the part private (0600/0700): give it the permissions open() would
    os.chmod(tmp, (0o777 if folder else 0o666) & ~mask)
    if folder:
        for f in tmp.iterdir():
            os.chmod(f, 0o666 & ~mask)
        if path.is_dir():
            old = Path(tempfile.mkdtemp(prefix=part_prefix(path), suffix=".old", dir=path.parent))
            os.replace(path, old / "frames")
            os.replace(tmp, path)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, path)
    elif not overwrite:
        # no clobbering an output that appeared meanwhile: a hard link fails if the name exists
        try:
            os.link(tmp, path)
        except FileExistsError:
            os.unlink(tmp)
            raise OutputExistsError(f"{str(path)!r} appeared while it was being written; pass --overwrite "
                                    "(overwrite=True) to replace it") from None
        except OSError:
            os.replace(tmp, path)                     # no hard links on this file system
            return
        os.unlink(tmp)
    else:
        os.replace(tmp, path)


class PartFile:
    """A file written under the discipline: ``write`` goes to the part file, :meth:`commit` publishes it.

    ``PartFile(path, overwrite=False, what="hash log")``; :meth:`discard`
    removes the part (nothing else). The first failed write (a full disk)
    raises an :class:`OutputError` naming ``path`` and ``what``; the part is
    removed then.
    """

    def __init__(self, path, *, overwrite: bool = False, what: str = "output", mode: str = "w",
                 buffering: int = -1):
        self.path = Path(os.fspath(path))
        self.what = what
        self.overwrite = bool(overwrite)
        check_output_file(self.path, overwrite=self.overwrite, probe=False)
        self.tmp = new_part(self.path)
        try:
            self.file = open(self.tmp, mode, buffering=buffering, **({} if "b" in mode else {"encoding": "utf-8"}))
        except BaseException:
            self.tmp.unlink(missing_ok=True)
            raise

    @property
    def closed(self) -> bool:
        return self.file.closed

    def write(self, data) -> None:
        try:
            self.file.write(data)
        except OSError as e:
            self._failed(e)

    def _failed(self, e: OSError):
        self.discard()
        why = "no space left on the device" if no_space(e) else (e.strerror or str(e))
        raise OutputError(e.errno, f"cannot write the {self.what} {str(self.path)!r}: {why}; "
                                   "its partial file was removed") from None

    def commit(self) -> Path:
        """Flush, close and move into place; returns the path."""
        try:
            self.file.flush()
            os.fsync(self.file.fileno())
            self.file.close()
        except OSError as e:
            self._failed(e)
        publish(self.tmp, self.path, overwrite=self.overwrite)
        return self.path

    def discard(self) -> None:
        try:
            self.file.close()
        except OSError:
            pass
        self.tmp.unlink(missing_ok=True)

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.commit()
        elif not self.file.closed or self.tmp.exists():
            self.discard()


def write_file(path, data, *, overwrite: bool = False, what: str = "output") -> Path:
    """Write ``data`` (str or bytes) to ``path`` under the discipline: a complete file or none."""
    with PartFile(path, overwrite=overwrite, what=what, mode="wb" if isinstance(data, bytes) else "w") as f:
        f.write(data)
    return Path(os.fspath(path))
