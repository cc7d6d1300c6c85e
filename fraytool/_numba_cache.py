"""Drop numba's on-disk cache of fraytool when any of its source files changed.

numba's ``cache=True`` checks only the file that defines a kernel, not the files of the kernels it
calls: after an edit of ``segments.py``, the cached tearing and self-collision kernels that call it
would silently keep the old code. fraytool's kernels call each other across files and packages, so
the whole cache is keyed on one hash of every source file of the package; when it changes, every
cache file (``*.nbi``, ``*.nbc``) under the package is deleted before any kernel is loaded.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

_STAMP = "numba_sources.sha256"


def invalidate_stale_numba_cache(package_dir: Path) -> None:
    """Delete ``package_dir/**/__pycache__/*.nb[ic]`` unless the sources hash matches the stamp.

    Best effort: an unwritable cache directory is left alone (numba then caches elsewhere).
    """
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
    try:
        for cache in package_dir.rglob("__pycache__"):
            for path in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
                path.unlink(missing_ok=True)
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(want)
    except OSError:
        pass
