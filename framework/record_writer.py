"""The recorder's writer thread: frames are encoded and written while the caller steps and draws the next."""
from __future__ import annotations

import queue
import threading

from driftframe.framework.record_sinks import _Sink


class _Audio:
    """A block of samples on the writer's queue (frames are plain bytes)."""

    __slots__ = ("samples",)

    def __init__(self, samples):
        self.samples = samples


class _Writer:
    """Feeds a sink from a bounded queue on a background thread, so encoding overlaps rendering.

    GL stays on the caller's thread (a context works only there); the thread
    only sees bytes. An error in the thread is re-raised in the caller at the
    next ``put`` or at ``close``.

    When the thread runs matters more than what it costs: moderngl's
    read-back holds the GIL while llvmpipe rasterises (on every core), so
    this thread hands frames on, and x264 (which encodes without the GIL)
    works, while the caller steps and draws on one core. What was tried
    instead, and the figures: ``docs/design/recorder.md``, "Writer thread".
    """

    #: Frames queued for the thread at most (plus the one it is writing).
    DEPTH = 3

    def __init__(self, sink: _Sink):
        self.sink = sink
        self._q: queue.Queue = queue.Queue(maxsize=self.DEPTH)
        self._error: BaseException | None = None
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="driftframe-recorder", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while True:
            item = self._q.get()
            if item is None:
                return
            if self._error is None:
                try:
                    if type(item) is _Audio:
                        self.sink.write_audio(item.samples)
                    else:
                        self.sink.write(item)
                except BaseException as e:   # noqa: BLE001 - handed to the caller
                    self._error = e

    def put(self, raw) -> None:
        if self._error is not None:
            raise self._error
        self._q.put(raw)

    def put_audio(self, samples) -> None:
        """A block of sound samples for the sink's sound track, after the frame put before it."""
        if self._error is not None:
            raise self._error
        self._q.put(_Audio(samples))

    def close(self) -> None:
        """Wait until every queued frame is written; re-raise the thread's error if any. Idempotent."""
        if not self._closed:
            self._closed = True
            self._q.put(None)
            self._thread.join()
        if self._error is not None:
            raise self._error
