"""FrameRecord: what one frame of a simulation hands to the renderer (and to tests), saved as .npz.

A record holds only what changes per frame (made from a State by fraytool.sim.record); the static topology (grid size, weave, spring kinds,
rest lengths, bodies' shapes) is saved once per run as topology.npz (`Model.arrays()`).
See docs/architecture.md for the on-disk layout.
"""
from __future__ import annotations

import os
import re
import socket
import tempfile
import time
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np


@dataclass(eq=False)
class FrameRecord:
    frame: int
    time_s: float
    particle_position_m: np.ndarray
    """Shape (particle_count, 3), float32; slots of inactive particles hold their crossing's position."""
    particle_active: np.ndarray
    """Shape (particle_count,), bool."""
    crossing_yarn_level: np.ndarray
    """True where the crossing is a yarn-level mass couple, False at base level; (crossing_count,), bool."""
    spring_particle_a: np.ndarray
    """Shape (spring_count,), int32."""
    spring_particle_b: np.ndarray
    """Shape (spring_count,), int32."""
    spring_alive: np.ndarray
    """Shape (spring_count,), bool."""
    body_position_m: np.ndarray
    """Shape (body_count, 3), float32."""
    body_rotation: np.ndarray
    """Shape (body_count, 3, 3), float32."""

    def arrays(self) -> dict[str, np.ndarray]:
        return {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)}

    @staticmethod
    def from_arrays(arrays: dict[str, np.ndarray]) -> "FrameRecord":
        kw = {f.name: arrays[f.name] for f in fields(FrameRecord)}
        kw["frame"] = int(kw["frame"])
        kw["time_s"] = float(kw["time_s"])
        return FrameRecord(**kw)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: Path, writer) -> None:
    """Write a file atomically: `writer(fileobj)` fills a temp file in the same folder, which gets
    the usual permissions (0666 minus the umask; mkstemp makes 0600), is fsynced and renamed over
    `path`. A killed process leaves either the old file or the new one, never a truncated one."""
    def write_to(name: str) -> None:
        with open(name, "wb") as f:
            writer(f)

    atomic_write_file(path, write_to)


def atomic_write_file(path: Path, write_to) -> None:
    """Write a file atomically through a writer that opens the file itself: `write_to(name)` writes a
    temp file (.NAME.HOST-PID.XXXX.tmp) in the same folder, which is then given the usual permissions
    (0666 minus the umask; mkstemp makes 0600), fsynced and renamed over `path`. An OSError names
    `path`, not the temp file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{_writer_tag()}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        write_to(tmp)
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fchmod(fd, 0o666 & ~_umask())
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        if isinstance(exc, OSError) and exc.errno is not None and exc.filename in (None, tmp):
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from None  # the file, not its temp
        raise


def host_tag() -> str:
    """This machine's name as file names carry it (letters and digits, "_" for anything else)."""
    return "".join(c if c.isalnum() else "_" for c in socket.gethostname()) or "host"


def _writer_tag() -> str:
    """HOST-PID of this process, as temp file names carry it (so a sweep knows whose they are)."""
    return f"{host_tag()}-{os.getpid()}"


_TEMP_NAME = re.compile(r"\..+\.[A-Za-z0-9_]+-[0-9]+\.[A-Za-z0-9_]+\.tmp")


def is_temp_name(name: str) -> bool:
    """Name of a temp file of atomic_write_bytes (".NAME.HOST-PID.XXXXXXXX.tmp")."""
    return _TEMP_NAME.fullmatch(name) is not None


STALE_TEMP_S = 3600.0
"""A temp file of another host's writer (whose pid cannot be checked) is stale after this long."""


def dead_writer(p: Path) -> bool:
    """True if the temp file's writer is dead (this host: pid gone; another host: old)."""
    from fraytool.io.lock import pid_alive

    host, _, pid = p.name[:-4].rsplit(".", 2)[-2].rpartition("-")
    if pid.isdigit() and host == host_tag():
        return not pid_alive(int(pid))
    try:
        return time.time() - p.stat().st_mtime > STALE_TEMP_S
    except FileNotFoundError:
        return False


def sweep_temp_files(folder: Path) -> list[Path]:
    """Delete the temp files of atomic writes in `folder` whose writer is dead (same host: its pid is
    gone; another host: untouched for STALE_TEMP_S); returns what was deleted."""
    folder = Path(folder)
    swept = []
    if folder.is_dir():
        for p in folder.iterdir():
            if is_temp_name(p.name) and p.is_file() and dead_writer(p):
                p.unlink(missing_ok=True)
                swept.append(p)
    return swept


def atomic_save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """np.savez (uncompressed) to `path` atomically."""
    atomic_write_bytes(path, lambda f: np.savez(f, **arrays))
