"""A private virtual X display (Xvfb) for playing a demo where there is no screen: tests, benchmarks, CI.

Xvfb picks the display number itself (``-displayfd``): it takes the first
free number atomically, through its lock file, and writes it down only once it
accepts connections. Two jobs on one machine, each starting its own server,
therefore never share a display, and so never see each other's windows or key
events (guessing a free number from ``/tmp/.X11-unix`` and waiting for the
socket raced: the socket found could be another job's server).
"""
from __future__ import annotations

import os
import select
import shutil
import subprocess
import time
from contextlib import contextmanager


class XvfbError(RuntimeError):
    """Xvfb is missing or did not start: a one-line message."""


def start_xvfb(size=(1280, 720), timeout=20.0) -> tuple[subprocess.Popen, str]:
    """Start Xvfb with one ``size`` screen; returns the server process and its display name (``":N"``)."""
    if not shutil.which("Xvfb"):
        raise XvfbError("Xvfb is not installed (apt-get install xvfb; `./run tests` installs it)")
    w, h = (int(v) for v in size)
    read, write = os.pipe()
    try:
        server = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", f"{w}x{h}x24",
                                   "-nolisten", "tcp", "-noreset"], pass_fds=(write,),
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    finally:
        os.close(write)
    text = b""
    deadline = time.monotonic() + timeout
    try:
        while not text.endswith(b"\n"):
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([read], [], [], left)[0]:
                raise XvfbError(f"Xvfb did not start within {timeout:g} s")
            chunk = os.read(read, 64)
            if not chunk:                       # it exited before it wrote a display number
                err = server.communicate(timeout=5)[1].decode(errors="replace").strip().splitlines()
                raise XvfbError(f"Xvfb exited with status {server.returncode}: {err[-1] if err else 'no message'}")
            text += chunk
    except BaseException:
        if server.poll() is None:
            server.kill()
            server.wait()
        raise
    finally:
        os.close(read)
    server.stderr.close()
    return server, f":{int(text)}"


def stop_xvfb(server: subprocess.Popen) -> None:
    if server.poll() is None:
        server.terminate()
        try:
            server.wait(10)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


@contextmanager
def virtual_display(size=(1280, 720)):
    """``with virtual_display() as display:`` a private Xvfb display for the block (``DISPLAY=display``)."""
    server, display = start_xvfb(size)
    try:
        yield display
    finally:
        stop_xvfb(server)
