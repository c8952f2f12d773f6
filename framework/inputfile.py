"""Reading a user's input file: bounded in size, only regular files, every error naming the file.

Every reader of a file a user names (tracks, bindings, gamepad mappings,
hash logs, batch specs) goes through :func:`read_text_capped` or
:func:`read_bytes_capped`. A FIFO would block the read forever and a device
such as ``/dev/zero`` never ends (a whole-file read of it grew memory by
700 MB/s), so both are refused before any byte is read; a regular file is
read up to ``cap`` bytes and refused, by name, when it is longer. The
opening is non-blocking, so a FIFO swapped in after a check cannot block
the open either.

The caps of the readers (the numbers are in the modules that use them and
in docs/GUIDE.md) are sized from the largest legitimate file, with room.
"""
from __future__ import annotations

import os
import stat


class InputFileError(ValueError):
    """An input file that cannot be read: the message names the file (and what it was for)."""


def _size_words(n: int) -> str:
    for unit, size in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n} bytes"


def _kind(mode: int) -> str:
    return ("a directory" if stat.S_ISDIR(mode) else
            "a FIFO (named pipe)" if stat.S_ISFIFO(mode) else
            "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else
            "a socket" if stat.S_ISSOCK(mode) else "not a regular file")


def open_regular(path, cap: int, what: str):
    """``path`` opened for reading in binary, if it is a regular file of at most ``cap`` bytes.

    For readers that go line by line (hash logs); the caller still stops
    at ``cap`` bytes, as the file can grow while it is read.
    """
    where = os.fspath(path)
    try:
        fd = os.open(where, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise InputFileError(f"{where}: cannot read the {what} ({e.strerror or e})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise InputFileError(f"{where}: cannot read the {what}: it is {_kind(st.st_mode)}, not a regular file")
        if st.st_size > cap:
            raise InputFileError(f"{where}: the {what} is {_size_words(st.st_size)}; the limit is "
                                 f"{_size_words(cap)}")
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_bytes_capped(path, cap: int, what: str) -> bytes:
    """The bytes of the regular file ``path``; an :class:`InputFileError` naming it if it cannot be used.

    ``what`` says what the file is for ("track", "bindings", "batch spec"):
    ``flight.json: the track is 200 MiB; the limit is 32 MiB``.
    Refused: a missing or unreadable file, a directory, a FIFO, a socket, a
    device, a file longer than ``cap`` bytes.
    """
    where = os.fspath(path)
    with open_regular(path, cap, what) as f:
        try:
            data = f.read(cap + 1)          # the size can change after the check: never more than cap + 1
        except OSError as e:
            raise InputFileError(f"{where}: cannot read the {what} ({e.strerror or e})") from None
    if len(data) > cap:
        raise InputFileError(f"{where}: the {what} is over the limit of {_size_words(cap)}")
    return data


def read_text_capped(path, cap: int, what: str) -> str:
    """:func:`read_bytes_capped`, decoded as UTF-8 (a leading BOM dropped); bad bytes named by offset."""
    data = read_bytes_capped(path, cap, what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise InputFileError(f"{os.fspath(path)}: the {what} is not UTF-8 text (byte {data[e.start]:#04x} at "
                             f"offset {e.start}, line {line}); is it a binary file?") from None

