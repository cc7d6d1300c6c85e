"""FrameStore: the folder of a simulation's frames, its manifest and its resume checkpoint.

    <out>/frames/manifest.json     scene hash, seed, version, counts, frames complete
    <out>/frames/topology.npz      static Model arrays (written once)
    <out>/frames/frame_000000.npz  one FrameRecord per frame (frame 0 = initial state)
    <out>/frames/checkpoint.npz    full-precision State after the last complete frame

Every file is written atomically. The write order per frame is record, checkpoint, manifest, so
after a kill the manifest never counts a frame whose record is missing, and resuming from the
checkpoint recomputes at most the frame in flight, bit for bit.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Optional

import numpy as np

from fraytool import __version__
from fraytool.errors import InputError
from fraytool.io.failure import LAST_GOOD_STATE, UNSTABLE_JSON
from fraytool.io.frame_record import FrameRecord, atomic_save_npz, atomic_write_bytes

MANIFEST = "manifest.json"
TOPOLOGY = "topology.npz"
CHECKPOINT = "checkpoint.npz"


def frame_filename(frame: int) -> str:
    return f"frame_{frame:06d}.npz"


class FrameStore:
    def __init__(self, out_dir: Path):
        self.out_dir = Path(out_dir)
        self.dir = self.out_dir / "frames"

    def manifest(self) -> Optional[dict]:
        try:
            return json.loads((self.dir / MANIFEST).read_text())
        except (OSError, ValueError):
            return None

    def frame_path(self, frame: int) -> Path:
        return self.dir / frame_filename(frame)

    def matches(self, scene_hash: str) -> bool:
        m = self.manifest()
        return m is not None and m.get("scene_hash") == scene_hash

    def frames_complete(self) -> int:
        """Number of complete frames on disk (0 if none or no manifest)."""
        m = self.manifest()
        return int(m["frames_complete"]) if m else 0

    def start(self, topology: dict[str, np.ndarray], scene_hash: str, info: dict) -> None:
        """Begin a fresh run: clear old frames, write the topology (Model.arrays()) and an empty manifest.

        Only a frames folder that fraytool made (its manifest says so) is cleared; a folder holding
        anything else is left as it is and the run stops with an InputError."""
        if self.dir.is_symlink() or (self.dir.exists() and not self.dir.is_dir()):
            raise InputError(f"{self.dir}: is in the way of the frames folder (not a folder fraytool made); "
                             "move it or choose another output folder with -o")
        if self.dir.exists():
            if not (self.dir / MANIFEST).is_file() and any(self.dir.iterdir()):
                raise InputError(f"{self.dir}: holds files fraytool did not write (no {MANIFEST}); "
                                 "not deleting them: move them or choose another output folder with -o")
            shutil.rmtree(self.dir)
        self.dir.mkdir(parents=True)
        atomic_save_npz(self.dir / TOPOLOGY, topology)
        self._write_manifest({**info, "scene_hash": scene_hash, "fraytool_version": __version__,
                              "frames_complete": 0})

    def _write_manifest(self, data: dict) -> None:
        text = json.dumps(data, indent=2, sort_keys=True).encode()
        atomic_write_bytes(self.dir / MANIFEST, lambda f: f.write(text))

    def write_frame(self, record: FrameRecord, checkpoint: dict[str, np.ndarray]) -> None:
        """Write a frame's record, then the checkpoint (State.arrays() after it), then the manifest."""
        record.save(self.frame_path(record.frame))
        atomic_save_npz(self.dir / CHECKPOINT, {**checkpoint, "frame": np.asarray(record.frame)})
        m = self.manifest() or {}
        m["frames_complete"] = record.frame + 1
        self._write_manifest(m)

    def update_manifest(self, **fields) -> None:
        m = self.manifest() or {}
        m.update(fields)
        self._write_manifest(m)

    def clear_failure(self) -> None:
        """Forget a failure written by the stability guard (unstable.json and the manifest entry)."""
        for name in (UNSTABLE_JSON, LAST_GOOD_STATE):
            (self.dir / name).unlink(missing_ok=True)
        m = self.manifest()
        if m is not None and "unstable" in m:
            m.pop("unstable")
            self._write_manifest(m)

    def load_checkpoint(self) -> tuple[int, dict[str, np.ndarray]]:
        """(frame, state arrays) of the last checkpoint (State.from_arrays makes the State)."""
        with np.load(self.dir / CHECKPOINT) as data:
            return int(data["frame"]), {k: data[k] for k in data.files if k != "frame"}

    def load_frame(self, frame: int) -> FrameRecord:
        return FrameRecord.load(self.frame_path(frame))

    def load_topology(self) -> dict[str, np.ndarray]:
        with np.load(self.dir / TOPOLOGY) as data:
            return {k: data[k] for k in data.files}
