"""Read only regular files: a FIFO or a device named where fraytool expects a file (a mask, a tear map, a
mesh, a frame record, a manifest, a golden's image) would block the reader forever or stream without end.
A leaf module (stdlib only), so every layer can ask before it opens a file."""
from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Optional

KINDS = {stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
         stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a folder"}


def not_a_regular_file(path: str | os.PathLike) -> Optional[str]:
    """Why `path` cannot be read as a file ("no such file", "a FIFO (named pipe)", "its name is too long",
    ...), or None for a regular file (a symlink to one is one). Never opens it."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "no such file"
    except OSError as exc:
        if exc.errno == 36:  # ENAMETOOLONG
            return f"its name is too long ({len(os.fsencode(os.path.basename(path)))} bytes in its last part; "\
                   "at most 255)"
        return exc.strerror or type(exc).__name__
    if stat.S_ISREG(mode):
        return None
    return f"not a regular file but {KINDS.get(stat.S_IFMT(mode), 'a special file')}"


def scene_path(file: str, scene_file: str) -> Path:
    """A file named by a scene (a mesh, a mask, a tear map): `~` expanded; absolute as given; else relative
    to the folder of `scene_file` (SceneSpec.source_file), or to the working folder when there is none. The
    one rule for every file a scene names."""
    p = Path(file).expanduser()
    if p.is_absolute():
        return p
    return (Path(scene_file).parent if scene_file else Path.cwd()) / p


def is_regular_file(path: str | os.PathLike) -> bool:
    return not_a_regular_file(path) is None


def regular_files_only(path: Path) -> Path:
    """`path`, or OSError (errno EINVAL) naming why it is not a regular file: for readers whose callers
    already turn an OSError into one clear line."""
    why = not_a_regular_file(path)
    if why is not None:
        raise OSError(22, why, str(path))
    return path
