"""Measuring aliasing: a frame against the same frame supersampled (benchmarks/render_lod.py, tests).

The reference is drawn at FACTOR times the size in each axis and box-filtered in linear light; the
error is the RMS difference in 8-bit sRGB levels after a Gaussian blur of BLUR_SIGMA_PX pixels on
both images. The blur keeps the beats between the weave and the pixel grid (moire spans many pixels)
and drops the weave's own pixel-scale detail, which no representation at 1x can keep exactly.
"""
from __future__ import annotations

import numpy as np

from fraytool.render.color import encode_premultiplied_linear

FACTOR = 4
BLUR_SIGMA_PX = 2.0


def gaussian_blur(image: np.ndarray, sigma: float = BLUR_SIGMA_PX) -> np.ndarray:
    """Separable Gaussian blur (radius 3 sigma, edges clamped) of an (H, W, C) image, float64."""
    r = int(np.ceil(3.0 * sigma))
    x = np.arange(-r, r + 1)
    k = np.exp(-0.5 * (x / sigma) ** 2)
    k /= k.sum()
    out = np.asarray(image, dtype=np.float64)
    for axis in (0, 1):
        pad = [(0, 0)] * out.ndim
        pad[axis] = (r, r)
        p = np.pad(out, pad, mode="edge")
        acc = np.zeros_like(out)
        n = out.shape[axis]
        for i, w in enumerate(k):
            acc += w * np.take(p, np.arange(i, i + n), axis=axis)
        out = acc
    return out


def blurred_rms(a: np.ndarray, b: np.ndarray, sigma: float = BLUR_SIGMA_PX) -> float:
    """RMS difference [levels] of two (H, W, >=3) 8-bit images after the same Gaussian blur (colour only)."""
    d = gaussian_blur(a[..., :3], sigma) - gaussian_blur(b[..., :3], sigma)
    return float(np.sqrt(np.mean(d * d)))


def box_downsample(linear_rgba: np.ndarray, factor: int = FACTOR) -> np.ndarray:
    """(H f, W f, 4) linear premultiplied RGBA -> (H, W, 3) 8-bit sRGB, averaged over f x f blocks."""
    Hf, Wf = linear_rgba.shape[:2]
    H, W = Hf // factor, Wf // factor
    box = linear_rgba[:H * factor, :W * factor].reshape(H, factor, W, factor, -1).mean(axis=(1, 3))
    return encode_premultiplied_linear(box.astype(np.float32), 8, False)
