"""Drop numba's on-disk cache of this package when any of its source files changed.

numba's ``cache=True`` checks only the file that defines a kernel, not the files of the kernels it
calls: after an edit of ``ccd.py``, the cached ``detect.py`` kernel would silently keep the old
narrow phase. The kernels here call each other across files, so we key the whole cache on a hash
of all the package's sources and delete the cache files (``*.nbi``, ``*.nbc``) when it changes.
"""
from __future__ import annotations

import hashlib
from pathlib import Path

_STAMP = "numba_sources.sha256"


def invalidate_stale_numba_cache(package_dir: Path) -> None:
    """Delete ``package_dir/__pycache__/*.nb[ic]`` unless the sources hash matches the stamp.

    Best effort: an unwritable cache directory is left alone (numba then caches elsewhere).
    """
    digest = hashlib.sha256()
    for path in sorted(package_dir.glob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    want = digest.hexdigest()
    cache_dir = package_dir / "__pycache__"
    stamp = cache_dir / _STAMP
    try:
        if stamp.read_text() == want:
            return
    except OSError:
        pass
    try:
        cache_dir.mkdir(exist_ok=True)
        for path in list(cache_dir.glob("*.nbi")) + list(cache_dir.glob("*.nbc")):
            path.unlink(missing_ok=True)
        stamp.write_text(want)
    except OSError:
        pass
