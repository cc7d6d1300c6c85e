"""16-bit PNG files (`fraytool render --depth 16`), written here because Pillow writes RGB and RGBA
PNGs at 8 bits per channel only.

PNG (ISO/IEC 15948): the signature, an IHDR chunk (bit depth 16, colour type 2 = RGB or 6 = RGBA),
a tEXt chunk with the settings digest (the same key as the 8-bit PNGs, fraytool.render.encode), one
IDAT chunk holding the zlib stream of the scanlines, each prefixed by its filter byte, and IEND.
Samples are big-endian. Rows are filtered with "Up" (type 2: each byte minus the byte above), which
suits smooth renders and costs one subtraction. Any PNG reader reads them (ffmpeg decodes them
exactly); Pillow opens them but reduces them to 8 bits, so `read_png16` reads our own files back at
16 bits (a resumed render rebuilds its video from them).
"""
from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from fraytool.io.frame_record import atomic_write_bytes

SIGNATURE = b"\x89PNG\r\n\x1a\n"
COMPRESS_LEVEL = 3
"""zlib level, as for the 8-bit PNGs."""


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png16(image: np.ndarray, text: dict[str, str] | None = None) -> bytes:
    """The bytes of a 16-bit PNG of an (H, W, 3) RGB or (H, W, 4) RGBA uint16 image, top row first."""
    image = np.asarray(image)
    if image.dtype != np.uint16 or image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"expected an (H, W, 3|4) uint16 image, got {image.shape} {image.dtype}")
    h, w, channels = image.shape
    colour_type = 2 if channels == 3 else 6
    rows = image.astype(">u2").reshape(h, w * channels).view(np.uint8)  # big-endian bytes per row
    up = rows.copy()
    up[1:] -= rows[:-1]  # filter type 2 (Up), modulo 256
    raw = np.empty((h, 1 + rows.shape[1]), np.uint8)
    raw[:, 0] = 2
    raw[:, 1:] = up
    out = [SIGNATURE, _chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, colour_type, 0, 0, 0))]
    for key, value in (text or {}).items():
        out.append(_chunk(b"tEXt", key.encode("latin-1") + b"\0" + value.encode("latin-1")))
    out.append(_chunk(b"IDAT", zlib.compress(raw.tobytes(), COMPRESS_LEVEL)))
    out.append(_chunk(b"IEND", b""))
    return b"".join(out)


def write_png16(path: Path, image: np.ndarray, text: dict[str, str] | None = None) -> None:
    """Write `image` (uint16, (H, W, 3|4)) as a 16-bit PNG atomically."""
    data = encode_png16(image, text)
    atomic_write_bytes(Path(path), lambda f: f.write(data))


def decode_png16(data: bytes) -> np.ndarray:
    """The (H, W, 3|4) uint16 image of a 16-bit RGB or RGBA PNG as `encode_png16` writes it
    (non-interlaced, rows filtered None or Up); ValueError for anything else or a damaged file."""
    if not data.startswith(SIGNATURE):
        raise ValueError("not a PNG file")
    pos, header, idat = len(SIGNATURE), None, []
    while pos + 12 <= len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        if pos + 12 + length > len(data):
            raise ValueError("the file is truncated")
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        if zlib.crc32(kind + body) & 0xFFFFFFFF != crc:
            raise ValueError(f"damaged {kind.decode('latin-1')} chunk (CRC)")
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + length
    else:
        raise ValueError("no IEND chunk: the file is truncated")
    if header is None:
        raise ValueError("no IHDR chunk")
    w, h, bit_depth, colour_type, _, _, interlace = header
    if bit_depth != 16 or colour_type not in (2, 6) or interlace:
        raise ValueError(f"not a 16-bit non-interlaced RGB/RGBA PNG (depth {bit_depth}, colour type {colour_type})")
    channels = 3 if colour_type == 2 else 4
    raw = np.frombuffer(zlib.decompress(b"".join(idat)), np.uint8)
    if raw.size != h * (1 + 2 * w * channels):
        raise ValueError("image data does not match the header")
    raw = raw.reshape(h, 1 + 2 * w * channels)
    filters, rows = raw[:, 0], raw[:, 1:].copy()
    if not np.isin(filters, (0, 2)).all():
        raise ValueError(f"row filters {sorted(set(filters.tolist()) - {0, 2})} are not read here")
    for y in range(1, h):  # Up: add the row above (already decoded), modulo 256
        if filters[y] == 2:
            rows[y] += rows[y - 1]  # (on the first row, Up adds zeros)
    return rows.view(">u2").reshape(h, w, channels).astype(np.uint16)


def read_png16(path: Path) -> np.ndarray:
    """The (H, W, 3|4) uint16 image of a PNG written by `write_png16`."""
    return decode_png16(Path(path).read_bytes())
