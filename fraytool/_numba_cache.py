"""Drop numba's on-disk cache of a fraytool kernel file when it, or a file it depends on, changed.

numba's ``cache=True`` checks only the file that defines a kernel, not the files of the kernels it
calls: after an edit of ``segments.py``, the cached tearing and self-collision kernels that call it
would silently keep the old code. So each source file that defines kernels is keyed on the files its
kernels can see when they compile: itself and the fraytool modules it imports at module level,
transitively (a kernel calls kernels and reads module-level constants of those modules; nothing else
reaches a compiled kernel). When that key changes, the file's cache files (``<stem>.*.nbi``,
``<stem>.*.nbc``) are deleted before any kernel is loaded; the other files' stay. An edit of a docstring
in ``golden/`` recompiles nothing; an edit of ``collision/ccd.py`` recompiles the kernels that call CCD
(docs/testing.md, "The kernel cache").

A first, cheap check hashes every source file of the package: when nothing changed since the stamp, no
import graph is read. Where numba keeps the files: ``__pycache__`` beside each source file, or, when
the environment sets ``NUMBA_CACHE_DIR``, one folder per source folder inside it, named as numba names
it (``<folder>_<sha1 of the folder's path>``, numba's UserProvidedCacheLocator); the stamp then lives
there too (one per fraytool checkout), so a cache folder shared between checkouts or switched between
runs is judged on its own.
"""
from __future__ import annotations

import ast
import hashlib
import json
import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Callable

_STAMP = "numba_sources.json"
"""{"package": digest of every source, "kernels": {kernel file: digest of the files it depends on}}."""


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
    """Delete the cache files of each kernel file whose dependencies' digest differs from the stamp's
    (`kernel_dependencies`); every kernel file's when there is no readable stamp.

    Best effort: an unwritable cache directory is left alone (numba then caches elsewhere).
    """
    global COLD
    user = _user_cache_dir()
    files = sorted(package_dir.rglob("*.py"))
    sources = sorted({path.parent for path in files})
    sim = package_dir.resolve() / "sim"
    sim_sources = [q for q in sources if q.resolve() == sim or sim in q.resolve().parents]
    sim_folders = [q / "__pycache__" for q in sim_sources] if user is None else cache_folders_of(sim_sources, user)
    writable = os.access(user if user is not None and user.exists() else package_dir, os.W_OK)
    # (a cache we cannot write to caches elsewhere: nothing to tell then)
    COLD = writable and not any(any(f.glob("*.nbi")) for f in sim_folders if f.is_dir())
    texts = {path.relative_to(package_dir).as_posix(): path.read_bytes() for path in files}
    whole = _digest(texts, sorted(texts))
    if user is None:
        stamp = package_dir / "__pycache__" / _STAMP
    else:
        checkout = hashlib.sha1(os.path.abspath(package_dir).encode()).hexdigest()[:12]
        stamp = user / f"fraytool-{checkout}-{_STAMP}"
    try:
        old = json.loads(stamp.read_text())
        if not isinstance(old, dict) or not isinstance(old.get("kernels"), dict):
            raise ValueError("not a stamp")
    except (OSError, ValueError):
        old = {"package": None, "kernels": {}}
    if old.get("package") == whole:
        return
    kernels = {rel: _digest(texts, deps) for rel, deps in kernel_dependencies(package_dir, texts).items()}
    stale = [rel for rel, d in kernels.items() if old["kernels"].get(rel) != d]
    try:
        for rel in stale:
            path = package_dir / rel
            folder = path.parent / "__pycache__" if user is None else cache_folders_of([path.parent], user)[0]
            if folder.is_dir():
                for cached in list(folder.glob(f"{path.stem}.*.nbi")) + list(folder.glob(f"{path.stem}.*.nbc")):
                    cached.unlink(missing_ok=True)
        stamp.parent.mkdir(parents=True, exist_ok=True)
        stamp.write_text(json.dumps({"package": whole, "kernels": kernels}, sort_keys=True))
    except OSError:
        pass
    sim_kernels = [rel for rel in kernels if rel.startswith("sim/")]
    if sim_kernels and all(rel in stale for rel in sim_kernels):  # every simulation kernel compiles again
        COLD = writable


def _digest(texts: dict[str, bytes], names) -> str:
    h = hashlib.sha256()
    for name in names:
        h.update(name.encode())
        h.update(hashlib.sha256(texts[name]).digest())
    return h.hexdigest()


KERNEL_DECORATORS = ("njit", "jit", "vectorize", "guvectorize", "stencil")


def kernel_dependencies(package_dir: Path, texts: dict[str, bytes] | None = None) -> dict[str, list[str]]:
    """Each source file (relative to the package, posix) that defines a numba kernel -> the files its
    kernels depend on: itself and the package's modules it imports at module level, transitively."""
    if texts is None:
        texts = {p.relative_to(package_dir).as_posix(): p.read_bytes() for p in sorted(package_dir.rglob("*.py"))}
    name = package_dir.name
    by_module = {}
    for rel in texts:
        parts = rel[:-3].split("/")
        if parts[-1] == "__init__":
            parts = parts[:-1]
        by_module[".".join([name, *parts])] = rel
    graph, kernels = {}, []
    for rel, text in texts.items():
        try:
            tree = ast.parse(text)
        except SyntaxError:
            graph[rel] = set()
            continue
        graph[rel] = _module_imports(tree, rel, name, by_module)
        if _defines_kernel(tree):
            kernels.append(rel)
    out = {}
    for rel in kernels:
        seen, todo = {rel}, [rel]
        while todo:
            for dep in graph[todo.pop()]:
                if dep not in seen:
                    seen.add(dep)
                    todo.append(dep)
        out[rel] = sorted(seen)
    return out


def _defines_kernel(tree: ast.AST) -> bool:
    for fn in ast.walk(tree):
        if isinstance(fn, ast.FunctionDef):
            for d in fn.decorator_list:
                target = d.func if isinstance(d, ast.Call) else d
                if (target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")) in KERNEL_DECORATORS:
                    return True
    return False


def _module_imports(tree: ast.Module, rel: str, package: str, by_module: dict[str, str]) -> set[str]:
    """The package's files a module imports at module level (inside a top-level if or try too)."""
    here = ".".join([package, *rel[:-3].split("/")])
    out = set()
    stack = list(tree.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.If, ast.Try, ast.With)):
            stack.extend(node.body + getattr(node, "orelse", []) + getattr(node, "finalbody", [])
                         + [s for h in getattr(node, "handlers", []) for s in h.body])
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
            out.update(by_module[n] for n in names if n in by_module)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the module's package (an __init__'s `here` ends in .__init__)
                base = ".".join(here.split(".")[:-node.level] + ([base] if base else []))
            for a in node.names:
                target = by_module.get(f"{base}.{a.name}") or by_module.get(base)
                if target is not None:
                    out.add(target)
    return out


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
