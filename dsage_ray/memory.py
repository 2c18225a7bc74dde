"""How much memory an evaluation may take: a request far beyond it stops with one line, not an out-of-memory kill.

A level's episodes run side by side (one policy call serves them all), so their arrays grow with ``episodes``; a
mistyped ``--episodes 1000000000`` would otherwise allocate until the kernel kills the process or numpy raises a
``MemoryError`` deep inside a simulator.
"""

from __future__ import annotations

import os
from pathlib import Path

from dsage_ray.errors import ResourceError


def available_bytes() -> int | None:
    """Memory this process can still get: the smaller of the system's available memory and its cgroup's room; None
    where neither can be read."""
    found: list[int] = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                found.append(int(line.split()[1]) * 1024)
    except OSError:
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit != "max":
            used = int(Path("/sys/fs/cgroup/memory.current").read_text())
            found.append(max(int(limit) - used, 0))
    except (OSError, ValueError):
        pass
    if not found:
        try:
            found.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            return None
    return min(found)


#: A request below this is taken to fit without reading the system's memory (it is far below any machine's).
ALWAYS_FITS = 256 * 10**6


def require_memory(nbytes: int, *, what: str, key: str) -> None:
    """Raises :class:`ResourceError` when ``nbytes`` is more than the memory available.

    Args:
        nbytes: An estimate of what the allocation needs.
        what: What needs it (``"50 episodes of a 16×16 maze"``).
        key: The config key or flag that sets its size, named in the message.
    """
    if nbytes < ALWAYS_FITS:  # every evaluation calls this: skip reading /proc for the usual sizes
        return
    available = available_bytes()
    if available is not None and nbytes > available:
        raise ResourceError(f"{what} need about {format_bytes(nbytes)} of memory, and {format_bytes(available)} is "
                            f"available: lower {key}")


def format_bytes(nbytes: float) -> str:
    """``"1.3 TB"``, ``"512 MB"``: a size as people read it."""
    if nbytes < 1000:
        return f"{nbytes:.0f} B"
    for unit in ("KB", "MB", "GB"):
        nbytes /= 1000
        if nbytes < 1000:
            return f"{nbytes:.1f} {unit}"
    return f"{nbytes / 1000:.1f} TB"
