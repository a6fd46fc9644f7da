"""Size checks before any work starts: :func:`require_memory` and :func:`require_disk` compare what a run would
need with what the machine has, and refuse (:class:`~cliutil.errors.BadInput`) what cannot fit.

The memory a run may use is the least of the machine's free memory (``MemAvailable``), the room left under this
process's cgroup memory limit (a container's or systemd unit's cap: v2 ``memory.max``, v1
``memory.limit_in_bytes``, page cache counted as free) and, per process, the room left under its address-space
limit (``ulimit -v``): a run that passed the machine's free memory would otherwise be killed under such a cap."""

from __future__ import annotations

import math
import os
import resource
import shutil
from pathlib import Path

from cliutil.errors import BadInput

GIB = 1024 ** 3
#: Where cgroup v2 (the unified hierarchy; ``unified/`` on hybrid systems) and v1's memory controller are mounted.
CGROUP_V2_MOUNTS = (Path("/sys/fs/cgroup"), Path("/sys/fs/cgroup/unified"))
CGROUP_V1_MEMORY = Path("/sys/fs/cgroup/memory")
#: Per cgroup version: the limit file, the usage file and the ``memory.stat`` keys of the page cache the kernel
#: reclaims before it kills (file-backed pages on the LRU lists; v1's ``total_`` keys count the whole subtree).
CGROUP_FILES = {2: ("memory.max", "memory.current", ("active_file", "inactive_file")),
                1: ("memory.limit_in_bytes", "memory.usage_in_bytes", ("total_active_file", "total_inactive_file"))}


def meminfo_available_bytes() -> int:
    """Memory this machine can give a new allocation now: ``MemAvailable`` (Linux), else physical memory."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def cgroup_room_bytes(proc_cgroup: Path = Path("/proc/self/cgroup"), v2_mounts=CGROUP_V2_MOUNTS,
                      v1_memory: Path = CGROUP_V1_MEMORY) -> float:
    """Bytes this process's cgroup (and each cgroup above it) can still charge before its memory limit: limit
    - usage + reclaimable page cache, the least over the levels; ``inf`` without a limit or a readable cgroup.

    The cgroup's path (``/proc/self/cgroup``: ``0::PATH`` for v2, ``N:memory:PATH`` for v1) is looked up under
    the mount; a path that is not there (a container sees its own cgroup as the mount's root) is walked up."""
    try:
        lines = proc_cgroup.read_text(encoding="ascii").splitlines()
    except OSError:
        return math.inf
    room = math.inf
    for line in lines:
        number, controllers, path = (line.split(":", 2) + ["", ""])[:3]
        if number == "0" and controllers == "":
            room = min([room, *(_levels_room(mount, path, 2) for mount in v2_mounts)])
        elif "memory" in controllers.split(","):
            room = min(room, _levels_room(v1_memory, path, 1))
    return room


def _levels_room(mount: Path, path: str, version: int) -> float:
    """The least room over the cgroup ``path`` under ``mount`` and every level above it that exists there."""
    folder = mount / path.strip("/")
    room = math.inf
    while True:
        room = min(room, _cgroup_room(folder, version))
        if folder == mount or mount not in folder.parents:
            return room
        folder = folder.parent


def _cgroup_room(folder: Path, version: int) -> float:
    """Limit - usage + reclaimable page cache of one cgroup folder (``inf``: no limit, or not a cgroup)."""
    limit_name, usage_name, cache_keys = CGROUP_FILES[version]
    try:
        limit_text = (folder / limit_name).read_text(encoding="ascii").strip()
        usage = int((folder / usage_name).read_text(encoding="ascii"))
        stat = dict(line.split() for line in (folder / "memory.stat").read_text(encoding="ascii").splitlines())
        limit = math.inf if limit_text == "max" else int(limit_text)
        cache = sum(int(stat.get(key, 0)) for key in cache_keys)
    except (OSError, ValueError):
        return math.inf
    if limit >= 2 ** 62:  # v1 writes "no limit" as the largest page-aligned 64-bit number
        return math.inf
    return max(0, limit - usage + cache)


def available_memory_bytes() -> float:
    """Memory a run may take now: the least of :func:`meminfo_available_bytes` and :func:`cgroup_room_bytes`."""
    return min(meminfo_available_bytes(), cgroup_room_bytes())


def address_space_room_bytes() -> float:
    """Bytes this process may still map under its address-space limit (``ulimit -v``, ``RLIMIT_AS``) beyond what
    it maps now (``VmSize``); ``inf`` without a limit."""
    limit = resource.getrlimit(resource.RLIMIT_AS)[0]
    if limit == resource.RLIM_INFINITY:
        return math.inf
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            mapped = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmSize:"))
    except (OSError, ValueError, IndexError, StopIteration):
        mapped = 0
    return max(0, limit - mapped)


def require_memory(bytes_per_process: float, what: str, processes: int = 1) -> None:
    """Raise :class:`BadInput` if ``what`` (e.g. ``--width 1000000 --height 600``), ``processes`` processes of
    ``bytes_per_process`` each, needs more memory than is free (:func:`available_memory_bytes`), or if one of them
    would map more than a process may (:func:`address_space_room_bytes`: the limit every process started here
    inherits)."""
    available = available_memory_bytes()
    if processes * bytes_per_process > available:
        raise BadInput(f"{what} needs about {format_bytes(processes * bytes_per_process)} of memory; "
                       f"this machine has {format_bytes(available)} available")
    room = address_space_room_bytes()
    if processes and bytes_per_process > room:
        each = " per process" if processes > 1 else ""
        raise BadInput(f"{what} needs about {format_bytes(bytes_per_process)} of memory{each}; the address-space "
                       f"limit (ulimit -v) leaves a process here {format_bytes(room)}")


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
