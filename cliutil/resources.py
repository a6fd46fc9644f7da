"""Size checks before any work starts: :func:`require_memory` and :func:`require_disk` compare what a run would
need with what the machine has, and refuse (:class:`~cliutil.errors.BadInput`) what cannot fit."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from cliutil.errors import BadInput

GIB = 1024 ** 3


def available_memory_bytes() -> int:
    """Memory this machine can give a new allocation now: ``MemAvailable`` (Linux), else physical memory."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def require_memory(bytes_needed: float, what: str) -> None:
    """Raise :class:`BadInput` if ``what`` (e.g. ``--width 1000000 --height 600``) needs more memory than is free."""
    available = available_memory_bytes()
    if bytes_needed > available:
        raise BadInput(f"{what} needs about {format_bytes(bytes_needed)} of memory; "
                       f"this machine has {format_bytes(available)} available")


def require_disk(folder: Path, bytes_needed: float, what: str) -> None:
    """Raise :class:`BadInput` if writing ``bytes_needed`` under ``folder`` (or its nearest existing parent)
    would not fit on that disk."""
    existing = Path(folder).absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    free = shutil.disk_usage(existing).free
    if bytes_needed > free:
        raise BadInput(f"{what} needs about {format_bytes(bytes_needed)} on disk; {existing} has {format_bytes(free)} free")


def format_bytes(count: float) -> str:
    """``1.5 GiB``, ``730 MiB``, ``1,020 KiB``, ``3 B``, ``888,178 PiB`` (binary units, three significant digits
    below 1000 of a unit, whole numbers above; ``inf`` stays ``inf B``)."""
    for unit, size in (("PiB", 1024 ** 5), ("TiB", 1024 ** 4), ("GiB", GIB), ("MiB", 1024 ** 2), ("KiB", 1024)):
        if count >= size:
            value = count / size
            return f"{value:,.0f} {unit}" if value >= 1000 else f"{value:.3g} {unit}"
    return f"{count:.0f} B"
