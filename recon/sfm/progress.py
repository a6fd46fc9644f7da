"""Progress from inside SfM's steps: the ``progress(step, done, total)`` callbacks they call.

pycolmap reports nothing while it extracts features or matches pairs, so :class:`DatabaseProgress` counts what it
has written into the database meanwhile; the incremental mapper calls back once per registered image, which
:class:`RegistrationCounter` counts.
"""

from __future__ import annotations

import threading
from pathlib import Path

import pycolmap


def no_progress(step: str, done: int, total: int) -> None:
    """The default progress callback: ``done`` of ``total`` items of ``step`` finished (ignored)."""


def renamed(progress, step: str):
    """``progress`` reporting under another step name (the photos left out of mapping repeat extraction and
    matching)."""
    return lambda _, done, total: progress(step, done, total)


#: Seconds between two looks at the database while pycolmap extracts or matches (it has no callbacks for those).
POLL_S = 0.5


def images_with_keypoints(db: pycolmap.Database) -> int:
    """How many of the database's images have their features extracted."""
    return sum(db.exists_keypoints(image.image_id) for image in db.read_all_images())


class DatabaseProgress:
    """While a pycolmap call that has no callbacks fills the database (extraction, matching), counts what it has
    written, ``count(db)`` minus the count before it started, from a thread every :data:`POLL_S` seconds and
    reports ``progress(step, n, total)`` when the count grows, and once more when the call is over (nothing runs
    when ``progress`` is :func:`no_progress`).

    COLMAP's database is in SQLite's WAL mode, so this second (reading) connection never blocks its writer.
    """

    def __init__(self, database_path: Path, step: str, total: int, count, progress=no_progress):
        self.database_path, self.step, self.total = database_path, step, total
        self.count, self.progress = count, progress
        self.stop = threading.Event()
        self.db = None

    def __enter__(self) -> "DatabaseProgress":
        if self.progress is no_progress:
            return self
        self.db = pycolmap.Database.open(self.database_path)
        self.start, self.last = self.count(self.db), 0
        self.progress(self.step, 0, self.total)
        self.thread = threading.Thread(target=self.poll, daemon=True)
        self.thread.start()
        return self

    def report(self) -> None:
        done = self.count(self.db) - self.start
        if done > self.last:
            self.last = done
            self.progress(self.step, done, self.total)

    def poll(self) -> None:
        while not self.stop.wait(POLL_S):
            self.report()

    def __exit__(self, *exc) -> None:
        if self.db is None:
            return
        self.stop.set()
        self.thread.join()
        if exc[0] is None:
            self.report()
        self.db.close()


class RegistrationCounter:
    """Counts the images the incremental mapper registers (its callbacks carry no data: 2 at the initial pair, 1
    per next image) and reports ``progress("map", n, total)``, never above ``total``."""

    def __init__(self, total: int, progress=no_progress):
        self.total, self.progress, self.count = total, progress, 0
        progress("map", 0, total)

    def add(self, images: int) -> None:
        self.count = min(self.count + images, self.total)
        self.progress("map", self.count, self.total)
