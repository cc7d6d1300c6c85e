"""Drop numba's on-disk cache of fraytool when any of its source files changed.

numba's ``cache=True`` checks only the file that defines a kernel, not the files of the kernels it
calls: after an edit of ``segments.py``, the cached tearing and self-collision kernels that call it
would silently keep the old code. fraytool's kernels call each other across files and packages, so
the whole cache is keyed on one hash of every source file of the package; when it changes, every
cache file (``*.nbi``, ``*.nbc``) under the package is deleted before any kernel is loaded.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

_STAMP = "numba_sources.sha256"


COLD = False
"""True when this process found no compiled kernels of the simulation on disk (first run after an
install or an update): the first steps then compile them, about a minute (see `cold_start_note`)."""


def cold_start_note() -> str | None:
    """One line to print before a simulation that will compile its kernels (once per process), else None."""
    global COLD
    if not COLD:
        return None
    COLD = False
    return ("fraytool: compiling the simulation kernels (the first run after installing or updating "
            "fraytool; about a minute, cached for later runs)")


def invalidate_stale_numba_cache(package_dir: Path) -> None:
    """Delete ``package_dir/**/__pycache__/*.nb[ic]`` unless the sources hash matches the stamp.

    Best effort: an unwritable cache directory is left alone (numba then caches elsewhere).
    """
    global COLD
    # (a package folder we cannot write to caches elsewhere: nothing to tell then)
    COLD = os.access(package_dir, os.W_OK) and not any((package_dir / "sim").rglob("*.nbi"))
    digest = hashlib.sha256()
    for path in sorted(package_dir.rglob("*.py")):
        digest.update(str(path.relative_to(package_dir)).encode())
        digest.update(path.read_bytes())
    want = digest.hexdigest()
    stamp = package_dir / "__pycache__" / _STAMP
    try:
        if stamp.read_text() == want:
            return
    except OSError:
        pass
    COLD = os.access(package_dir, os.W_OK)
    try:
        for cache in package_dir.rglob("__pycache__"):
            for path in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
                path.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(want)
    except OSError:
        pass
