"""Saving and loading frames: FrameRecord (.npz), FrameStore (folder, manifest, checkpoint)."""
from fraytool.io.frame_record import FrameRecord, atomic_save_npz, atomic_write_bytes
from fraytool.io.frame_store import FrameStore

__all__ = ["FrameRecord", "FrameStore", "atomic_save_npz", "atomic_write_bytes"]
