"""FrameRecord: what one frame of a simulation hands to the renderer (and to tests), saved as .npz.

A record holds only what changes per frame (made from a State by fraytool.sim.record); the static topology (grid size, weave, spring kinds,
rest lengths, bodies' shapes) is saved once per run as topology.npz (`Model.arrays()`).
See docs/architecture.md for the on-disk layout.
"""
from __future__ import annotations

import os
import tempfile
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

    def save(self, path: Path) -> None:
        atomic_save_npz(path, {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)})

    @staticmethod
    def load(path: Path) -> "FrameRecord":
        with np.load(path) as data:
            kw = {f.name: data[f.name] for f in fields(FrameRecord)}
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
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            writer(f)
            f.flush()
            os.fchmod(f.fileno(), 0o666 & ~_umask())
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def atomic_save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    """np.savez (uncompressed) to `path` atomically."""
    atomic_write_bytes(path, lambda f: np.savez(f, **arrays))
