"""Overlap encoding with rendering: frames go through a bounded queue to writer threads.

PNG encoding (OpenCV) and EXR writing (OpenEXR) release the GIL, so a writer thread encodes
frame ``i`` while the main thread renders frame ``i + 1``. The queue is bounded so a slow
disk slows the renderer down instead of filling the memory. The first error raised by a
writer thread is re-raised in the caller at the next ``submit`` or at ``close`` (an ``OSError``, such as
a full disk, as it is; anything else wrapped in a ``RuntimeError``).
"""

from __future__ import annotations

import queue
import threading

from sim.dataset.writer import FrameRecord, KittiDatasetWriter

_STOP = object()
#: Frames queued for writing by default (each holds every view's rgb and depth).
MAX_PENDING_FRAMES = 4


class AsyncFrameWriter:
    """Context manager that writes :class:`FrameRecord` objects with ``threads`` background threads.

    >>> with AsyncFrameWriter(writer) as frames:   # doctest: +SKIP
    ...     for record in rendered():
    ...         frames.submit(record)
    """

    def __init__(self, writer: KittiDatasetWriter, max_pending: int = MAX_PENDING_FRAMES, threads: int = 1):
        if max_pending < 1 or threads < 1:
            raise ValueError(f"max_pending and threads must be >= 1, got {max_pending} and {threads}")
        self.writer = writer
        self.written = 0
        self._queue: queue.Queue = queue.Queue(maxsize=max_pending)
        self._error: BaseException | None = None
        self._lock = threading.Lock()
        self._closed = False
        self._threads = [threading.Thread(target=self._work, name=f"frame-writer-{n}", daemon=True)
                         for n in range(threads)]
        for thread in self._threads:
            thread.start()

    def _work(self) -> None:
        while True:
            record = self._queue.get()
            if record is _STOP:
                return
            if self._error is not None:
                continue  # drain the queue without writing after the first failure
            try:
                self.writer.write_frame(record)
                with self._lock:
                    self.written += 1
            except BaseException as error:  # noqa: BLE001 -- handed to the caller
                with self._lock:
                    self._error = self._error or error

    def _raise_pending_error(self) -> None:
        if isinstance(self._error, OSError):  # it names the file (a full disk): the caller reports it as it is
            raise self._error
        if self._error is not None:
            raise RuntimeError(f"writing a frame failed: {self._error}") from self._error

    def submit(self, record: FrameRecord) -> None:
        """Queue a frame (blocks while ``max_pending`` frames wait); raises an earlier writer error."""
        if self._closed:
            raise RuntimeError("AsyncFrameWriter is closed")
        self._raise_pending_error()
        self._queue.put(record)

    def close(self) -> None:
        """Write every queued frame, stop the threads and raise the first writer error, if any."""
        if not self._closed:
            self._closed = True
            for _ in self._threads:
                self._queue.put(_STOP)
            for thread in self._threads:
                thread.join()
        self._raise_pending_error()

    def __enter__(self) -> "AsyncFrameWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
            return
        try:
            self.close()
        except (RuntimeError, OSError):
            pass  # the exception already in flight is the one to report
