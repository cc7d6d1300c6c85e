"""Drop numba's on-disk cache of fraytool when any of its source files changed.

numba's ``cache=True`` checks only the file that defines a kernel, not the files of the kernels it
calls: after an edit of ``segments.py``, the cached tearing and self-collision kernels that call it
would silently keep the old code. fraytool's kernels call each other across files and packages, so
the whole cache is keyed on one hash of every source file of the package; when it changes, every
cache file (``*.nbi``, ``*.nbc``) of the package is deleted before any kernel is loaded.

Where numba keeps them: ``__pycache__`` beside each source file, or, when the environment sets
``NUMBA_CACHE_DIR``, one folder per source folder inside it, named as numba names it
(``<folder>_<sha1 of the folder's path>``, numba's UserProvidedCacheLocator); the stamp of the
sources' hash then lives there too (one per fraytool checkout), so a cache folder shared between
checkouts or switched between runs is judged on its own.
"""
from __future__ import annotations

import hashlib
import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

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


FIRST_USE_NOTE = ("fraytool: compiling kernels this run uses for the first time (a feature's first use after "
                  "installing or updating fraytool: tearing, meshes, rendering...; up to a minute, cached for "
                  "later runs)")


@contextmanager
def first_compile_notice(write: Callable[[str], None]):
    """Within the block, call write(FIRST_USE_NOTE) once, when a fraytool kernel first compiles (a miss of
    numba's on-disk cache): `cold_start_note` covers a cache with nothing of the simulation in it, this a cache
    that holds some kernels but not the ones a scene's features need, which compile mid-run (fig7's tearing
    after a drape: 20-40 s with no word, the progress line's ETA meanwhile meaningless). numba signals a
    compilation with its "numba:compile" event (not sent for a load from the cache)."""
    from numba.core import event

    class _Listener(event.Listener):
        said = False

        def on_start(self, ev) -> None:
            data = ev.data if isinstance(ev.data, dict) else {}
            module = getattr(getattr(data.get("dispatcher"), "py_func", None), "__module__", "") or ""
            if not self.said and module.startswith("fraytool."):
                self.said = True
                write(FIRST_USE_NOTE)

        def on_end(self, ev) -> None:
            pass

    with event.install_listener("numba:compile", _Listener()):
        yield


def _user_cache_dir() -> Path | None:
    """numba's NUMBA_CACHE_DIR, when the environment sets it (numba reads the same variable)."""
    value = os.environ.get("NUMBA_CACHE_DIR", "")
    return Path(value) if value else None


def cache_folders(package_dir: Path, sources: list[Path] | None = None) -> list[Path]:
    """The folders where numba keeps (or would keep) the compiled kernels of the package's sources
    (`sources`: the package's folders holding .py files, found when not given)."""
    user = _user_cache_dir()
    if sources is None:
        sources = sorted({path.parent for path in package_dir.rglob("*.py")})
    if user is None:  # beside the sources (and any other __pycache__ of the package: a removed module's)
        return sorted({folder / "__pycache__" for folder in sources} | set(package_dir.rglob("__pycache__")))
    return cache_folders_of(sources, user)


def cache_folders_of(sources: list[Path], user: Path) -> list[Path]:
    """numba's NUMBA_CACHE_DIR folder of each source folder (UserProvidedCacheLocator's naming)."""
    out = []
    for folder in sources:
        sub = os.path.dirname(os.path.abspath(folder / "_.py"))
        out.append(user / f"{os.path.split(sub)[-1]}_{hashlib.sha1(sub.encode()).hexdigest()}")
    return out


def invalidate_stale_numba_cache(package_dir: Path) -> None:
    """Delete the package's numba cache files (``cache_folders``) unless the sources hash matches the
    stamp.

    Best effort: an unwritable cache directory is left alone (numba then caches elsewhere).
    """
    global COLD
    user = _user_cache_dir()
    files = sorted(package_dir.rglob("*.py"))
    sources = sorted({path.parent for path in files})
    folders = cache_folders(package_dir, sources)
    sim = package_dir.resolve() / "sim"
    sim_sources = [q for q in sources if q.resolve() == sim or sim in q.resolve().parents]
    sim_folders = [q / "__pycache__" for q in sim_sources] if user is None else cache_folders_of(sim_sources, user)
    writable = os.access(user if user is not None and user.exists() else package_dir, os.W_OK)
    # (a cache we cannot write to caches elsewhere: nothing to tell then)
    COLD = writable and not any(any(f.glob("*.nbi")) for f in sim_folders if f.is_dir())
    digest = hashlib.sha256()
    for path in files:
        digest.update(str(path.relative_to(package_dir)).encode())
        digest.update(path.read_bytes())
    want = digest.hexdigest()
    if user is None:
        stamp = package_dir / "__pycache__" / _STAMP
    else:
        checkout = hashlib.sha1(os.path.abspath(package_dir).encode()).hexdigest()[:12]
        stamp = user / f"fraytool-{checkout}-{_STAMP}"
    try:
        if stamp.read_text() == want:
            return
    except OSError:
        pass
    COLD = writable
    try:
        for cache in folders:
            if cache.is_dir():
                for path in list(cache.glob("*.nbi")) + list(cache.glob("*.nbc")):
                    path.unlink(missing_ok=True)
        stamp.parent.mkdir(parents=True, exist_ok=True)
        stamp.write_text(want)
    except OSError:
        pass


def kernels_compiled() -> int:
    """How many times numba compiled a fraytool kernel in this process so far (cache misses of the
    loaded modules' dispatchers; a load from numba's on-disk cache is not counted)."""
    from numba.core.registry import CPUDispatcher

    seen, count = set(), 0
    for name, module in list(sys.modules.items()):
        if not name.startswith("fraytool.") or module is None:
            continue
        for obj in vars(module).values():
            if isinstance(obj, CPUDispatcher) and id(obj) not in seen:
                seen.add(id(obj))
                count += sum(obj.stats.cache_misses.values())
    return count
