"""Offline telemetry readers, each returning a ``capture.track.Track``, and ``read_track`` that picks one.

| source | reader | detected by |
|---|---|---|
| folder of JPEGs | ``photos.read_photos_track`` | a directory |
| DJI SRT subtitles | ``srt.read_srt`` | ``.srt`` suffix or an index + timecode/date opening |
| Litchi flight log CSV | ``flightcsv.read_flight_csv`` | header with ``datetime(utc)`` and ``istakingphoto``/``dronetype``... |
| Airdata CSV | ``flightcsv.read_flight_csv`` | header with ``datetime(utc)`` and ``isPhoto``/``height_above_takeoff`` |
| DUML raw capture / pcap | ``duml.read_duml_track`` | pcap magic, ``.duml`` suffix or a ``.idx`` sidecar |
"""

from __future__ import annotations

from pathlib import Path

from ..track import LOG_KINDS, LogFormatError, Track
from .duml import looks_like_duml, read_duml_track
from .flightcsv import read_flight_csv, sniff_flight_csv
from .photos import read_photos_track
from .srt import looks_like_srt, read_srt


def detect_kind(path) -> str:
    """Which reader fits ``path``, from its content (and suffix); raises LogFormatError if none does."""
    path = Path(path)
    if path.is_dir():
        return "photos"
    if not path.is_file():
        raise LogFormatError(f"{path}: no such file")
    if looks_like_duml(path):
        return "duml"
    with path.open("rb") as handle:
        head = handle.read(4096).decode("utf-8-sig", errors="replace")
    first_line = head.splitlines()[0] if head.strip() else ""
    kind = sniff_flight_csv(first_line)
    if kind:
        return kind
    if looks_like_srt(head) or path.suffix.lower() == ".srt":
        return "srt"
    raise LogFormatError(f"{path}:1: unknown log format (expected a DJI SRT, a Litchi or Airdata CSV, "
                         f"a DUML capture NAME.duml or pcap, or a folder of photos); first line: {first_line[:60]!r}")


def read_track(path, *, kind: str | None = None, start_time_s: float | None = None,
               srt_utc_offset_h: float = 0.0) -> Track:
    """Read any supported log into a ``Track``.

    ``start_time_s`` (UTC seconds since the epoch) anchors SRT styles that carry no date;
    ``srt_utc_offset_h`` is the aircraft clock's UTC offset for SRT styles that do. DUML captures carry
    their own arrival times (index or pcap) and need neither.
    """
    kind = kind or detect_kind(path)
    if kind == "photos":
        return read_photos_track(path)
    if kind == "srt":
        return read_srt(path, start_time_s=start_time_s, utc_offset_h=srt_utc_offset_h)
    if kind in ("litchi", "airdata"):
        return read_flight_csv(path, kind)
    if kind == "duml":
        return read_duml_track(path)
    raise ValueError(f"unknown log kind {kind!r}; known: {LOG_KINDS}")
