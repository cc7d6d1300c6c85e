"""FrameStore: the folder of a simulation's frames, its manifest and its resume checkpoint.

    <out>/frames/manifest.json     scene hash, seed, version, counts, frames complete, checksum
    <out>/frames/topology.npz      static Model arrays (written once)
    <out>/frames/frame_000000.npz  one FrameRecord per frame (frame 0 = initial state)
    <out>/frames/checkpoint.npz    full-precision State after the last complete frame

Every file is written atomically. The write order per frame is record, checkpoint, manifest, so
after a kill the manifest never counts a frame whose record is missing, and resuming from the
checkpoint recomputes at most the frame in flight, bit for bit.

Every .npz carries `scene_hash` and `checksum` (SHA-256 over the scene hash and every array's name,
dtype, shape and bytes); the manifest carries a checksum of its own text. `survey()` finds missing,
truncated, corrupted and foreign files; fraytool.sim.run recovers from them by re-simulating (the
simulation is deterministic, so frames that verify are never rewritten with other bits).
"""
from __future__ import annotations

import hashlib
import os
import json
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from fraytool.files import not_a_regular_file, regular_files_only

from fraytool import __version__
from fraytool.errors import OutputError
from fraytool.io.failure import LAST_GOOD_STATE, UNSTABLE_JSON
from fraytool.io.frame_record import FrameRecord, atomic_save_npz, atomic_write_bytes, is_temp_name, sweep_temp_files

MANIFEST = "manifest.json"
TOPOLOGY = "topology.npz"
CHECKPOINT = "checkpoint.npz"
PREVIOUS_CHECKPOINT = "checkpoint.previous.npz"
"""The checkpoint before the one being written, put back if the write fails (FrameStore.write_frame)."""
MAX_FRAMES = 1_000_000
"""Most frames a store counts (as the largest [time] frames)."""
MAX_PROBLEMS = 50
"""Most problems a survey lists one by one."""
STORE_FORMAT = 2
"""2: every file carries a checksum."""

_FRAME_RE = re.compile(r"frame_\d{6}\.npz")
_OURS = {MANIFEST, TOPOLOGY, CHECKPOINT, UNSTABLE_JSON, LAST_GOOD_STATE}


def frame_filename(frame: int) -> str:
    return f"frame_{frame:06d}.npz"


def arrays_checksum(arrays: dict[str, np.ndarray], scene_hash: str) -> str:
    h = hashlib.sha256(scene_hash.encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(memoryview(a).cast("B") if a.size else b"")  # the bytes of a.tobytes(), not a copy
    return h.hexdigest()


def _manifest_checksum(data: dict) -> str:
    body = {k: v for k, v in data.items() if k != "checksum"}
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


class DamagedFile(OutputError):
    """A file of the store is missing, truncated, corrupted or from another scene."""

    def __init__(self, path: Path, reason: str):
        self.path, self.reason = Path(path), reason
        super().__init__(f"{path}: {reason}")


def load_verified(path: Path, scene_hash: Optional[str]) -> dict[str, np.ndarray]:
    """The arrays of a checksummed .npz (without `scene_hash` and `checksum`); DamagedFile if it is
    missing, unreadable, fails its checksum, or (scene_hash given) belongs to another scene."""
    path = Path(path)
    why = not_a_regular_file(path)
    if why is not None and why != "no such file":
        raise DamagedFile(path, why)
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except FileNotFoundError:
        raise DamagedFile(path, "missing") from None
    except Exception as exc:  # zipfile, pickle and format errors of a truncated or foreign file
        raise DamagedFile(path, f"truncated or unreadable ({type(exc).__name__})") from None
    stored_hash = arrays.pop("scene_hash", None)
    checksum = arrays.pop("checksum", None)
    if stored_hash is None or checksum is None:
        raise DamagedFile(path, "has no checksum (not written by this fraytool)")
    stored_hash = str(stored_hash)
    if arrays_checksum(arrays, stored_hash) != str(checksum):
        raise DamagedFile(path, "checksum mismatch (corrupted)")
    if scene_hash is not None and stored_hash != scene_hash:
        raise DamagedFile(path, f"from another scene (scene hash {stored_hash}, expected {scene_hash})")
    return arrays


def save_verified(path: Path, arrays: dict[str, np.ndarray], scene_hash: str) -> None:
    arrays = {k: np.asarray(v) for k, v in arrays.items()}
    atomic_save_npz(path, {**arrays, "scene_hash": np.asarray(scene_hash),
                           "checksum": np.asarray(arrays_checksum(arrays, scene_hash))})


@dataclass
class Survey:
    """What a frame store holds, checked file by file (FrameStore.survey)."""
    manifest: Optional[dict]
    """The manifest if it is intact, else None."""
    good_frames: int
    """Frames 0..good_frames-1 exist and verify."""
    checkpoint_frame: Optional[int]
    """Frame of an intact checkpoint, else None."""
    topology_ok: bool
    problems: list[str] = field(default_factory=list)
    """One line per damaged file: path and what is wrong."""

    @property
    def clean(self) -> bool:
        return not self.problems

    def resumable_from_checkpoint(self) -> bool:
        return self.checkpoint_frame is not None and self.checkpoint_frame == self.good_frames - 1


class FrameStore:
    def __init__(self, out_dir: Path):
        self.out_dir = Path(out_dir)
        self.dir = self.out_dir / "frames"
        self._scene_hash: Optional[str] = None
        self._manifest: Optional[dict] = None

    # -- reading -------------------------------------------------------------------------------
    def manifest(self) -> Optional[dict]:
        """The manifest if it parses and its checksum holds, else None."""
        try:
            data = json.loads(regular_files_only(self.dir / MANIFEST).read_text())
        except (OSError, ValueError):
            return None
        if not isinstance(data, dict) or data.get("checksum") != _manifest_checksum(data):
            return None
        fc = data.get("frames_complete")
        if not isinstance(fc, int) or isinstance(fc, bool) or not 0 <= fc <= MAX_FRAMES \
                or not isinstance(data.get("scene_hash"), str):
            return None  # a manifest that checks out but whose fields make no sense is damaged
        return data

    def manifest_problem(self) -> Optional[str]:
        path = self.dir / MANIFEST
        if not path.exists():
            return f"{path}: missing"
        why = not_a_regular_file(path)
        if why is not None:
            return f"{path}: {why}"
        try:
            data = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            return f"{path}: unreadable ({type(exc).__name__})"
        if not isinstance(data, dict) or "checksum" not in data:
            return f"{path}: has no checksum (not written by this fraytool)"
        if data["checksum"] != _manifest_checksum(data):
            return f"{path}: checksum mismatch (corrupted)"
        if self.manifest() is None:
            return f"{path}: fields out of range (frames_complete, scene_hash)"
        return None

    def owned(self) -> bool:
        """True if the frames folder is fraytool's to clear: an intact manifest, or (a manifest lost to
        a full disk or a kill) only files with fraytool's names whose .npz files verify, and no
        manifest.json that is valid JSON of someone else."""
        if self.manifest() is not None:
            return True
        for p in self.dir.iterdir():
            if p.name == MANIFEST:
                try:
                    json.loads(regular_files_only(p).read_text())
                    return False  # valid JSON, not ours
                except (OSError, ValueError):
                    continue  # a damaged manifest of ours
            if is_temp_name(p.name) or p.name in (UNSTABLE_JSON,):
                continue
            if not (p.is_file() and (p.name in _OURS or _FRAME_RE.fullmatch(p.name))):
                return False
            try:
                load_verified(p, None)
            except DamagedFile:
                return False
        return True

    def frame_path(self, frame: int) -> Path:
        return self.dir / frame_filename(frame)

    def matches(self, scene_hash: str) -> bool:
        m = self.manifest()
        return m is not None and m.get("scene_hash") == scene_hash

    def frames_complete(self) -> int:
        """Number of complete frames on disk (0 if none or no intact manifest)."""
        m = self.manifest()
        return int(m["frames_complete"]) if m else 0

    def scene_hash(self) -> Optional[str]:
        m = self.manifest()
        return m.get("scene_hash") if m else self._scene_hash

    def load_checkpoint(self) -> tuple[int, dict[str, np.ndarray]]:
        """(frame, state arrays) of the last checkpoint (State.from_arrays makes the State)."""
        arrays = load_verified(self.dir / CHECKPOINT, self.scene_hash())
        return int(arrays.pop("frame")), arrays

    def load_frame(self, frame: int) -> FrameRecord:
        arrays = load_verified(self.frame_path(frame), self.scene_hash())
        if int(arrays["frame"]) != frame:
            raise DamagedFile(self.frame_path(frame), f"holds frame {int(arrays['frame'])}")
        return FrameRecord.from_arrays(arrays)

    def load_topology(self) -> dict[str, np.ndarray]:
        return load_verified(self.dir / TOPOLOGY, self.scene_hash())

    def survey(self, scene_hash: Optional[str] = None, frames: Optional[int] = None) -> Survey:
        """Check the manifest, the topology, frames 0..frames-1 (default: the frames the manifest
        counts, or every frame file there is without one) and the checkpoint, against `scene_hash`
        (default: the manifest's)."""
        problems = []
        from fraytool.io.lock import held_by_live_process

        live_writer = held_by_live_process(self.out_dir)
        manifest = self.manifest()
        if manifest is None and (self.dir.exists() or frames):
            problems.append(self.manifest_problem())
        digest = scene_hash or (manifest or {}).get("scene_hash")
        if manifest is not None and scene_hash is not None and manifest.get("scene_hash") != scene_hash:
            problems.append(f"{self.dir / MANIFEST}: from another scene (scene hash "
                            f"{manifest.get('scene_hash')}, expected {scene_hash})")
            manifest = None
        topology_ok = True
        try:
            load_verified(self.dir / TOPOLOGY, digest)
        except DamagedFile as exc:
            topology_ok = False
            problems.append(str(exc))
        if frames is None:
            frames = int(manifest["frames_complete"]) if manifest else _count_frame_files(self.dir)
        frames = min(frames, MAX_FRAMES)
        good = 0
        while good < frames:
            try:
                self._check_frame(good, digest)
            except DamagedFile as exc:
                problems.append(str(exc))
                break
            good += 1
        on_disk = _frame_numbers(self.dir)
        for k in range(good + 1, frames):  # name the other damaged frames (missing ones as one line)
            if k not in on_disk:
                continue
            try:
                self._check_frame(k, digest)
            except DamagedFile as exc:
                problems.append(str(exc))
        missing = [k for k in range(good + 1, frames) if k not in on_disk]
        if missing:
            problems.append(f"{self.dir}: {len(missing)} more frame file(s) between {good + 1} and {frames - 1} missing: "
                            f"{_frame_list(missing)}")
        if len(problems) > MAX_PROBLEMS:
            problems = problems[:MAX_PROBLEMS] + [f"... and {len(problems) - MAX_PROBLEMS} more"]
        checkpoint_frame = None
        if self.dir.exists():
            try:
                checkpoint_frame = int(load_verified(self.dir / CHECKPOINT, digest)["frame"])
            except DamagedFile as exc:
                if good or (self.dir / CHECKPOINT).exists():
                    problems.append(str(exc))
        if manifest is not None and checkpoint_frame is not None and checkpoint_frame != good - 1 \
                and good == int(manifest["frames_complete"]) and not live_writer:
            problems.append(f"{self.dir / CHECKPOINT}: is after frame {checkpoint_frame}, "
                            f"the manifest counts {good} frames")
        return Survey(manifest, good, checkpoint_frame, topology_ok, problems)

    def _check_frame(self, frame: int, digest: Optional[str]) -> None:
        arrays = load_verified(self.frame_path(frame), digest)
        if int(arrays["frame"]) != frame:
            raise DamagedFile(self.frame_path(frame), f"holds frame {int(arrays['frame'])}")

    # -- writing (the caller holds the folder's OutputLock) ------------------------------------
    def sweep_temp_files(self) -> list[Path]:
        """Delete temp files of dead writers (the caller holds the folder's lock)."""
        return sweep_temp_files(self.dir)

    @property
    def previous_dir(self) -> Path:
        """Where a fresh run keeps the frames it replaces until it completes (frames.previous/)."""
        return self.out_dir / "frames.previous"

    def start(self, topology: dict[str, np.ndarray], scene_hash: str, info: dict) -> None:
        """Begin a fresh run: set the old frames aside, write the topology (Model.arrays()) and an
        empty manifest.

        The old frames move to frames.previous/ and stay there until the new run completes
        (`drop_previous`); a run that fails on I/O (a full disk) puts them back (`restore_previous`),
        so the previous good output is untouched. Only files fraytool writes are ever deleted, and
        only from a frames folder that fraytool made; a folder holding anything else is left as it is
        and the run stops with an OutputError (exit 1)."""
        if self.dir.is_symlink() or (self.dir.exists() and not self.dir.is_dir()):
            raise OutputError(f"{self.dir}: is in the way of the frames folder (not a folder fraytool made); "
                             "move it or choose another output folder with -o")
        if self.dir.exists():
            if not self.owned():
                raise OutputError(f"{self.dir}: holds files fraytool did not write (no {MANIFEST}); "
                                 "not deleting them: move them or choose another output folder with -o")
            self.drop_previous()  # a leftover of an earlier fresh run that was killed
            if not self.previous_dir.exists():
                self.dir.rename(self.previous_dir)
            else:  # someone's files stayed there: clear ours in place instead
                _delete_ours(self.dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self._scene_hash = scene_hash
        self.write_topology(topology)
        self._write_manifest({**info, "scene_hash": scene_hash, "fraytool_version": __version__,
                              "store_format": STORE_FORMAT, "frames_complete": 0})

    def drop_previous(self) -> None:
        """Delete fraytool's files in frames.previous/ (and the folder, if nothing else is left)."""
        if self.previous_dir.is_dir() and not self.previous_dir.is_symlink():
            _delete_ours(self.previous_dir)
            try:
                self.previous_dir.rmdir()
            except OSError:
                pass  # other files stay where they are

    def restore_previous(self) -> bool:
        """After a failed fresh run: delete its frames and put the previous ones back. True if done."""
        if not self.previous_dir.is_dir():
            return False
        if self.dir.is_dir():
            _delete_ours(self.dir)
            try:
                self.dir.rmdir()
            except OSError:
                return False
        self.previous_dir.rename(self.dir)
        return True

    def reopen(self, scene_hash: str, info: dict, frames_complete: int, topology: dict[str, np.ndarray],
               rewrite_topology: bool) -> None:
        """Continue writing a store after survey(): a fresh manifest counting the frames that verify
        (kept fields of an intact manifest win over `info`), the topology rewritten if damaged."""
        self._scene_hash = scene_hash
        self.dir.mkdir(parents=True, exist_ok=True)
        if rewrite_topology:
            self.write_topology(topology)
        kept = self.manifest() or {}
        kept.pop("unstable", None)
        self._write_manifest({**info, **kept, "scene_hash": scene_hash, "fraytool_version": __version__,
                              "store_format": STORE_FORMAT, "frames_complete": frames_complete})

    def write_topology(self, topology: dict[str, np.ndarray]) -> None:
        save_verified(self.dir / TOPOLOGY, topology, self._scene_hash)

    def _write_manifest(self, data: dict) -> None:
        data = {k: v for k, v in data.items() if k != "checksum"}
        data["checksum"] = _manifest_checksum(data)
        text = json.dumps(data, indent=2, sort_keys=True).encode()
        atomic_write_bytes(self.dir / MANIFEST, lambda f: f.write(text))
        self._manifest = data

    def write_frame(self, record: FrameRecord, checkpoint: Optional[dict[str, np.ndarray]],
                    write_record: bool = True) -> None:
        """Write a frame's record, then the checkpoint (State.arrays() after it), then the manifest.
        `write_record=False` (recovery) keeps a record on disk that already verifies."""
        digest = self._scene_hash or self.scene_hash()
        if write_record:
            save_verified(self.frame_path(record.frame), record.arrays(), digest)
        m = dict(self._manifest or self.manifest() or {})
        m["frames_complete"] = record.frame + 1
        if checkpoint is None:
            self._write_manifest(m)
            return
        ckpt, prev = self.dir / CHECKPOINT, self.dir / PREVIOUS_CHECKPOINT
        had = ckpt.exists()
        if had:
            os.replace(ckpt, prev)  # kept until the manifest counts the new checkpoint's frame
        try:
            save_verified(ckpt, {**checkpoint, "frame": np.asarray(record.frame)}, digest)
            self._write_manifest(m)
        except BaseException:
            # a failed write (a full disk) leaves the checkpoint the manifest counts, not one ahead of it
            if had:
                os.replace(prev, ckpt)
            else:
                ckpt.unlink(missing_ok=True)
            raise
        prev.unlink(missing_ok=True)

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


def _delete_ours(folder: Path) -> None:
    for p in folder.iterdir():
        if p.is_file() and (p.name in _OURS or _FRAME_RE.fullmatch(p.name) or is_temp_name(p.name)):
            p.unlink()


def _frame_numbers(folder: Path) -> set[int]:
    if not folder.is_dir():
        return set()
    return {int(p.name[6:12]) for p in folder.iterdir() if _FRAME_RE.fullmatch(p.name)}


def _count_frame_files(folder: Path) -> int:
    """Without a manifest: the frames 0, 1, 2, ... on disk without a gap (a stray frame_999999.npz
    does not make a million frames to check)."""
    numbers = _frame_numbers(folder)
    k = 0
    while k in numbers:
        k += 1
    return k


def _frame_list(frames: list[int], most: int = 8) -> str:
    """Frame numbers as runs, at most `most` of them: "100", "3-5, 9", "3-5, 9, ... (12 runs)"."""
    runs: list[list[int]] = []
    for k in frames:
        if runs and k == runs[-1][1] + 1:
            runs[-1][1] = k
        else:
            runs.append([k, k])
    text = ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in runs[:most])
    return text + (f", ... ({len(runs)} runs)" if len(runs) > most else "")
