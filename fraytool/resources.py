"""The one place that finds fraytool's data files: shaders and shipped scenes.

In a wheel they are the packages `fraytool.shaders` and `fraytool.scenes` (pyproject maps the
top-level shaders/ and scenes/ folders there); an editable install resolves the same names to the
checkout's folders.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

from fraytool.errors import SceneError


def _package_dir(package: str) -> Path:
    """Folder of a data package (a namespace package: no __init__.py in shaders/ or scenes/)."""
    try:
        spec = importlib.util.find_spec(package)
    except ModuleNotFoundError:
        spec = None
    for location in (spec.submodule_search_locations or []) if spec else []:
        if Path(location).is_dir():
            return Path(location)
    # Running from a source tree without installing: the folders sit beside the package.
    return Path(__file__).resolve().parent.parent / package.split(".")[-1]


def shader_dir() -> Path:
    """Folder holding the GLSL shader files (.vert/.frag)."""
    return _package_dir("fraytool.shaders")


def shader_source(name: str) -> str:
    """Text of one shader file, e.g. shader_source("yarn.frag")."""
    return (shader_dir() / name).read_text(encoding="utf-8")


def scenes_dir() -> Path:
    """Folder holding the scenes shipped with fraytool."""
    return _package_dir("fraytool.scenes")


def shipped_scene(name: str | Path) -> Path | None:
    """The shipped scene a bare name (or a scenes/ path) stands for, or None."""
    p = Path(name)
    rel = p.parts[1:] if p.parts[:1] == ("scenes",) else p.parts
    if not rel or p.is_absolute() or ".." in rel:
        return None
    shipped = scenes_dir().joinpath(*rel)
    for c in (shipped, shipped.with_suffix(".toml")):
        if c.is_file():
            return c
    return None


def find_scene(path: str | Path) -> Path:
    """Resolve a scene argument: an existing file, else a shipped scene by name or scenes/ path."""
    p = Path(path)
    try:
        if p.is_file():
            return p
    except OSError as exc:  # a name too long for the file system, a path through a file, ...
        raise SceneError([f"{str(path)[:200]}: cannot read scene file: {exc.strerror}"]) from None
    found = shipped_scene(p)
    if found is not None:
        return found
    shipped = scenes_dir()
    names = sorted(q.relative_to(shipped).with_suffix("").as_posix() for q in shipped.rglob("*.toml"))
    import difflib

    wanted = p.with_suffix("").as_posix() if p.suffix == ".toml" else p.as_posix()
    wanted = wanted[len("scenes/"):] if wanted.startswith("scenes/") else wanted
    # a scene's start ("fig5", "stress/fast"), else the closest names (a misspelling)
    close = [n for n in names if n.startswith(wanted)][:3] if wanted else []
    close = close or difflib.get_close_matches(wanted, names, n=3, cutoff=0.5)
    hint = f"did you mean {' or '.join(close)}? " if close else ""
    raise SceneError([f"{str(path)[:200]}: scene file not found ({hint}shipped scenes: {', '.join(names) or 'none'})"])
