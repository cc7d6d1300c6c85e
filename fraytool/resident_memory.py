"""Resident memory of this process: its size now, its high-water mark, and (Linux) resetting that mark.

Used by `fraytool bench` (bytes_per_crossing) and benchmarks/memory_profile.py. Sizes in bytes.

`map_large_blocks` sets how this process's C heap holds large blocks; the command line and the
farm's tasks call it before any work.
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


LARGE_BLOCK_BYTES = 1 << 20
"""Blocks of at least this size are mapped from the system on allocation and given back on free
(`map_large_blocks`)."""

M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
"""glibc mallopt parameters (malloc.h)."""


def map_large_blocks(threshold_bytes: int = LARGE_BLOCK_BYTES) -> bool:
    """Have glibc map every block of at least `threshold_bytes` on its own and return it to the system
    when freed (mallopt M_MMAP_THRESHOLD, which also turns off glibc's dynamic threshold), and trim the
    heap's top when twice that is free (M_TRIM_THRESHOLD). False where that is not possible (no glibc).

    Why: by default glibc raises its mapping threshold to the size of any mapped block freed (up to
    32 MiB), so after the first large temporary freed, the next ones come from the heap, whose free
    holes stay resident. Building a 256 x 256 model and stepping it left 400-600 bytes per crossing
    resident that no array held (benchmarks/memory_profile.py: 2368 B/crossing resident after 10
    frames of fig7_square_grab at 256 x 256 against 1745 held in arrays; 1789 with this, peak 1875).
    The cost is a page fault per page of every large allocation, which the per-step kernels do not
    make (they allocate nothing); per frame it is the record's copies, well under a millisecond."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(M_MMAP_THRESHOLD, int(threshold_bytes))
                    and libc.mallopt(M_TRIM_THRESHOLD, 2 * int(threshold_bytes)))
    except (OSError, AttributeError):
        return False


def _status_kib(field: str):
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return None
