"""sRGB <-> linear RGB (IEC 61966-2-1). Scene colours are sRGB; lighting happens in linear RGB."""
from __future__ import annotations

from typing import Sequence

import numpy as np

WIREFRAME_BASE_SRGB = (0.62, 0.30, 0.85)
"""Purple: springs at base-model crossings (Fig. 8)."""
WIREFRAME_YARN_SRGB = (0.25, 0.55, 1.00)
"""Blue: springs at yarn-level crossings (Fig. 8)."""


def srgb_to_linear(c: Sequence[float] | np.ndarray) -> np.ndarray:
    """Decode sRGB components in [0, 1] to linear RGB."""
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: Sequence[float] | np.ndarray) -> np.ndarray:
    """Encode linear RGB components in [0, 1] to sRGB."""
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1.0 / 2.4) - 0.055)


def straight_alpha_srgb(premultiplied: np.ndarray) -> np.ndarray:
    """(H, W, 4) uint8 read from the sRGB framebuffer of an --alpha render (sRGB-encoded linear colour
    premultiplied by alpha, linear alpha) -> (H, W, 4) uint8 straight alpha, sRGB colour, as PNG
    stores it: colour = encode(decode(c) / alpha); fully transparent pixels are black."""
    rgba = premultiplied.astype(np.float32) / 255.0
    alpha = rgba[..., 3:4]
    lin = srgb_to_linear(rgba[..., :3])
    straight = np.where(alpha > 0.0, lin / np.maximum(alpha, 1e-6), 0.0)
    out = np.empty_like(premultiplied)
    out[..., :3] = np.clip(np.rint(linear_to_srgb(np.clip(straight, 0.0, 1.0)) * 255.0), 0, 255)
    out[..., 3] = premultiplied[..., 3]
    return out


def encode_premultiplied_linear(rgba: np.ndarray, bits: int, alpha: bool) -> np.ndarray:
    """(H, W, 4) float linear colour premultiplied by linear alpha (the float framebuffer, an EXR) ->
    straight (unassociated) alpha with sRGB colour, as PNG and video store it: (H, W, 4) with `alpha`,
    else (H, W, 3) (the colour as it is: an opaque render has alpha 1); uint8 for `bits` 8, uint16
    for 16. colour = encode(c / alpha); fully transparent pixels are black."""
    if bits not in (8, 16):
        raise ValueError(f"bits must be 8 or 16, got {bits}")
    scale = float((1 << bits) - 1)
    dtype = np.uint8 if bits == 8 else np.uint16
    rgba = np.asarray(rgba, dtype=np.float32)
    colour = rgba[..., :3]
    if alpha:
        a = np.clip(rgba[..., 3:4], 0.0, 1.0)
        colour = np.where(a > 0.0, colour / np.maximum(a, 1e-12), 0.0)
    out = np.empty(rgba.shape[:2] + (4 if alpha else 3,), dtype=dtype)
    out[..., :3] = np.rint(linear_to_srgb(colour) * scale)
    if alpha:
        out[..., 3] = np.rint(a[..., 0] * scale)
    return out


def over_background(rgba: np.ndarray, background_srgb) -> np.ndarray:
    """(H, W, 4) uint8 or uint16 straight-alpha sRGB composited over an sRGB colour in linear light ->
    (H, W, 3) of the same type."""
    scale = float(np.iinfo(rgba.dtype).max)
    f = rgba.astype(np.float32) / scale
    a = f[..., 3:4]
    lin = srgb_to_linear(f[..., :3]) * a + srgb_to_linear(np.asarray(background_srgb, np.float32)) * (1.0 - a)
    return np.clip(np.rint(linear_to_srgb(lin) * scale), 0, scale).astype(rgba.dtype)


MAX_YARN_COLORS = 32
"""Entries of the yarn shader's palette (shaders/yarn.vert u_yarn_colors)."""
THREAD_SRGB = (0.13, 0.13, 0.15)
"""sRGB colour of a seam's stitches (a dark thread)."""


def yarn_palette(render, panels=()) -> np.ndarray:
    """The yarn colours by colour index, sRGB, shape (MAX_YARN_COLORS, 3): index 2 p is panel p's weft and
    2 p + 1 its warp (a panel's own warp_color / weft_color, else [render]'s), index 2 P (P panels) the
    seams' thread; panels past the palette's room repeat the last panels' colours. With one panel and no
    colours of its own: [render] weft_color, warp_color, as before panels."""
    out = np.empty((MAX_YARN_COLORS, 3))
    out[:] = THREAD_SRGB
    panels = list(panels) or [None]
    for p, panel in enumerate(panels[: (MAX_YARN_COLORS - 1) // 2]):
        weft = getattr(panel, "weft_color", None) or render.weft_color
        warp = getattr(panel, "warp_color", None) or render.warp_color
        out[2 * p], out[2 * p + 1] = weft, warp
    return out


def color_index(kind: np.ndarray, panel: np.ndarray) -> np.ndarray:
    """Palette index of a yarn piece from its kind (0 weft, 1 warp) and panel: 2 panel + kind, kept inside
    the palette (yarn_palette)."""
    limit = (MAX_YARN_COLORS - 1) // 2 - 1
    return (2 * np.minimum(panel, limit) + kind).astype(np.float32)
