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


def read_bytes_capped(path, cap: int, what: str) -> bytes:
    """The bytes of the regular file ``path``; an :class:`InputFileError` naming it if it cannot be used.

    ``what`` says what the file is for ("track", "bindings", "batch spec"):
    ``flight.json: the track is 200 MiB; the limit is 32 MiB``.
    Refused: a missing or unreadable file, a directory, a FIFO, a socket, a
    device, a file longer than ``cap`` bytes.
    """
    where = os.fspath(path)
    try:
        fd = os.open(where, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise InputFileError(f"{where}: cannot read the {what} ({e.strerror or e})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = ("a directory" if stat.S_ISDIR(st.st_mode) else
                    "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else
                    "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else
                    "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
            raise InputFileError(f"{where}: cannot read the {what}: it is {kind}, not a regular file")
        if st.st_size > cap:
            raise InputFileError(f"{where}: the {what} is {_size_words(st.st_size)}; the limit is "
                                 f"{_size_words(cap)}")
        chunks, got = [], 0
        while got <= cap:                    # the size can change while we read: stop at cap + 1 bytes
            chunk = os.read(fd, min(1 << 20, cap + 1 - got))
            if not chunk:
                break
            chunks.append(chunk)
            got += len(chunk)
        if got > cap:
            raise InputFileError(f"{where}: the {what} is over the limit of {_size_words(cap)}")
        return b"".join(chunks)
    except OSError as e:
        raise InputFileError(f"{where}: cannot read the {what} ({e.strerror or e})") from None
    finally:
        os.close(fd)


def read_text_capped(path, cap: int, what: str) -> str:
    """:func:`read_bytes_capped`, decoded as UTF-8 (a leading BOM dropped); bad bytes named by offset."""
    data = read_bytes_capped(path, cap, what)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        raise InputFileError(f"{os.fspath(path)}: the {what} is not UTF-8 text (byte {data[e.start]:#04x} at "
                             f"offset {e.start}, line {line}); is it a binary file?") from None

