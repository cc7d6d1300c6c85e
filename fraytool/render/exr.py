"""OpenEXR frames (`fraytool render --exr`), through OpenEXR's own Python package.

Each frame is one scanline EXR (ZIP compression), top row first, with the channels compositors expect:
- R, G, B, A: half float, **linear** colour (Rec. 709 / sRGB primaries, the scene colours decoded
  from sRGB), **premultiplied** by alpha (OpenEXR's convention, "associated alpha"): exactly what the
  float framebuffer blended in linear light, unclamped (a highlight may exceed 1). Without --alpha,
  A = 1 everywhere and RGB holds the background colour where nothing was drawn.
- Z: 32-bit float, the distance in metres from the camera along its view axis (-z in view space,
  not the distance to the eye), from the resolved depth buffer; +inf where nothing was drawn.
The header carries the digest of the render settings (`fraytool:render-settings`, the key of the
PNGs' tEXt chunk), so an interrupted render keeps the frames it finished.

OpenEXR is imported only when an EXR is written or read: other renders do not need it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from fraytool.io.frame_record import atomic_write_file

SETTINGS_ATTRIBUTE = "fraytool:render-settings"
"""Header attribute (string) holding the digest of the settings a frame was rendered with."""


def write_exr(path: Path, rgba_linear: np.ndarray, depth_m: Optional[np.ndarray], settings_digest: str = "") -> None:
    """Write one frame atomically: (H, W, 4) premultiplied linear RGBA (stored as half) and, if given,
    (H, W) Z in metres (float32). See the module docstring for the conventions."""
    import OpenEXR

    channels = {"RGBA": np.ascontiguousarray(rgba_linear, dtype=np.float16)}
    if depth_m is not None:
        channels["Z"] = np.ascontiguousarray(depth_m, dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    if settings_digest:
        header[SETTINGS_ATTRIBUTE] = settings_digest

    def write_to(name: str) -> None:
        with OpenEXR.File(header, channels) as f:
            f.write(name)

    atomic_write_file(Path(path), write_to)


def exr_settings(path: Path) -> Optional[tuple[str, tuple[int, int]]]:
    """(settings digest, (width, height)) of an EXR written by write_exr, or None if it is missing,
    unreadable or lacks R, G, B, A."""
    import OpenEXR

    if not Path(path).is_file():
        return None  # (the library would print its own message for a missing file)
    try:
        with OpenEXR.File(str(Path(path)), separate_channels=True) as f:
            header = f.header()
            names = set(f.channels())
            lo, hi = header["dataWindow"]
            digest = str(header.get(SETTINGS_ATTRIBUTE, ""))  # read inside: the file owns the header's strings
    except Exception:  # the package raises plain exceptions (RuntimeError, ...) for damaged files
        return None
    if not {"R", "G", "B", "A"} <= names:
        return None
    return digest, (int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1))


def read_exr(path: Path) -> dict[str, np.ndarray]:
    """The channels of an EXR by name, each (H, W), top row first."""
    import OpenEXR

    with OpenEXR.File(str(Path(path)), separate_channels=True) as f:
        return {name: np.array(ch.pixels) for name, ch in f.channels().items()}


def read_exr_rgba(path: Path) -> np.ndarray:
    """(H, W, 4) float32 premultiplied linear RGBA of an EXR written by write_exr."""
    ch = read_exr(path)
    return np.stack([ch[c].astype(np.float32) for c in "RGBA"], axis=-1)
