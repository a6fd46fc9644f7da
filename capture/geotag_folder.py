"""Geotag a folder of photos from flight-log files: what ``aerostereo-ingest geotag``, ``check`` and
``aerostereo.geotag`` share (read the logs and the photos, geotag, refuse a result the logs took no part in)."""

from __future__ import annotations

from collections.abc import Iterable
from os import PathLike

from cliutil.errors import BadInput

from .geotag import GeotagResult, geotag_photos
from .geotag_limits import DEFAULT_MAX_GAP_S, DEFAULT_MAX_MISFIT_M
from .logs import read_track
from .logs.photos import PhotoInfo, read_photos
from .track import ReadReport, Track


def geotag_folder(photos_dir: str | PathLike, logs: Iterable[str | PathLike], *, clock_offset="auto",
                  max_gap_s: float = DEFAULT_MAX_GAP_S, max_misfit_m: float = DEFAULT_MAX_MISFIT_M,
                  start_time_s: float | None = None, srt_utc_offset_h: float = 0.0
                  ) -> tuple[GeotagResult, ReadReport]:
    """Geotag the JPEG photos of ``photos_dir`` from the flight logs ``logs`` (any kind
    :func:`capture.logs.read_track` reads; ``start_time_s`` and ``srt_utc_offset_h`` as there) with
    :func:`capture.geotag.geotag_photos` (``clock_offset``: ``"auto"`` or seconds, telemetry UTC - camera clock;
    ``max_gap_s``, ``max_misfit_m`` as there). Returns the result and the photos' read report (which photos could
    not be read). :class:`BadInput` when no photo can be read, or no photo could be tagged from the logs."""
    tracks = [read_track(path, start_time_s=start_time_s, srt_utc_offset_h=srt_utc_offset_h) for path in logs]
    photos, photo_report = read_photo_folder(photos_dir)
    return geotag_tracks(photos, tracks, clock_offset=clock_offset, max_gap_s=max_gap_s,
                         max_misfit_m=max_misfit_m), photo_report


def read_photo_folder(photos_dir: str | PathLike) -> tuple[list[PhotoInfo], ReadReport]:
    """The readable JPEG photos of ``photos_dir`` and the read report; :class:`BadInput` when there is none."""
    photos, photo_report = read_photos(photos_dir)
    if not photos:
        raise BadInput(f"{photos_dir}: no readable JPEG photos")
    return photos, photo_report


def geotag_tracks(photos: list[PhotoInfo], tracks: list[Track], *, clock_offset="auto",
                  max_gap_s: float = DEFAULT_MAX_GAP_S, max_misfit_m: float = DEFAULT_MAX_MISFIT_M) -> GeotagResult:
    """:func:`capture.geotag.geotag_photos` of photos and tracks already read; :class:`BadInput` when no photo could
    be tagged from the tracks (every one fell back to its own EXIF/XMP)."""
    result = geotag_photos(photos, tracks, clock_offset=clock_offset, max_gap_s=max_gap_s, max_misfit_m=max_misfit_m)
    if len(result.from_photos) == len(result.tags):
        reasons = "; ".join(f"{name}: {reason}" for name, reason in (result.untagged + result.from_photos)[:3])
        raise BadInput(f"no photo could be geotagged from the logs ({reasons})")
    return result
