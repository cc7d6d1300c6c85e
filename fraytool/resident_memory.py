"""Resident memory of this process: its size now, its high-water mark, and (Linux) resetting that mark.

Used by `fraytool bench` (bytes_per_crossing) and benchmarks/memory_profile.py. Sizes in bytes.
"""
from __future__ import annotations

import ctypes
import resource
from pathlib import Path


def peak_rss_bytes() -> int:
    """High-water mark of the resident set size: since the process started, or since the last
    successful reset_peak() (Linux reports ru_maxrss in KiB and lowers it on a reset)."""
    status = _status_kib("VmHWM")
    if status is not None:
        return 1024 * status
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024


def rss_bytes() -> int:
    """Resident set size now (falls back to the high-water mark where /proc is missing)."""
    status = _status_kib("VmRSS")
    return 1024 * status if status is not None else peak_rss_bytes()


def reset_peak() -> bool:
    """Lower the high-water mark to the resident size now (writes 5 to /proc/self/clear_refs,
    Linux >= 4.0); False where that is not possible."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return True


def release_freed_memory() -> None:
    """Give the free pages of the C heap back to the system (glibc malloc_trim; nothing elsewhere),
    so that memory freed by earlier work is neither counted in a baseline nor reused unseen."""
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


def _status_kib(field: str):
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return None
