"""Comparing rendered images with references (golden-image tests, regression checks).

Three figures decide, all over 8-bit sRGB values:
- RMS: root mean square of the per-channel differences over the whole image; catches changes
  spread everywhere (a colour, gamma, the light).
- Share of pixels whose largest channel difference exceeds PIXEL_THRESHOLD; catches local changes
  the RMS would average away (a moved edge, a missing yarn).
- Share of pixels off by more than NOISE_LEVELS (the rounding of the rasteriser and of sRGB
  encoding: one level); catches a change of shading that moves many pixels by 2-5 levels, which
  the RMS cannot tell from rounding (a 10 % change of the Kajiya-Kay exponent: RMS 0.26-0.50
  against 0.00-0.35 for an unchanged render on another machine, but 1.3-4.3 % of pixels off by more
  than one level against at most 0.01 %; docs/testing.md).
Rasteriser differences between Mesa versions move a few edge pixels slightly; the default
tolerances allow that and nothing more (see docs/rendering.md for how they were chosen).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

RMS_TOLERANCE = 1.0
"""Largest RMS difference accepted [8-bit levels]."""
PIXEL_THRESHOLD = 16
"""A pixel differs when one of its channels differs by more than this [8-bit levels]."""
SHARE_TOLERANCE = 0.002
"""Largest share of differing pixels accepted (0.2 %)."""
NOISE_LEVELS = 1
"""Rounding: a pixel whose channels all differ by at most this is the same [8-bit levels]."""
NOISE_SHARE_TOLERANCE = 0.005
"""Largest share of pixels off by more than NOISE_LEVELS accepted (0.5 %: the edge pixels another Mesa
moves, which SHARE_TOLERANCE bounds at 0.2 %, with room)."""


@dataclass(frozen=True)
class ImageDiff:
    rms: float
    share_over: float
    max_abs: int
    same_size: bool
    rms_tolerance: float = RMS_TOLERANCE
    share_tolerance: float = SHARE_TOLERANCE
    pixel_threshold: int = PIXEL_THRESHOLD
    share_over_noise: float = 0.0
    noise_share_tolerance: float = NOISE_SHARE_TOLERANCE

    @property
    def ok(self) -> bool:
        return (self.same_size and self.rms <= self.rms_tolerance and self.share_over <= self.share_tolerance
                and self.share_over_noise <= self.noise_share_tolerance)

    def describe(self) -> str:
        if not self.same_size:
            return "image sizes differ"
        return (f"RMS {self.rms:.3f} (tolerance {self.rms_tolerance}), "
                f"{100 * self.share_over:.3f} % of pixels differ by more than {self.pixel_threshold} "
                f"(tolerance {100 * self.share_tolerance:.3f} %), {100 * self.share_over_noise:.3f} % by more "
                f"than {NOISE_LEVELS} (tolerance {100 * self.noise_share_tolerance:.3f} %), largest difference "
                f"{self.max_abs}")


def compare_images(expected: np.ndarray, actual: np.ndarray, rms_tolerance: float = RMS_TOLERANCE,
                   pixel_threshold: int = PIXEL_THRESHOLD, share_tolerance: float = SHARE_TOLERANCE) -> ImageDiff:
    """Compare two (H, W, 3) uint8 images."""
    if expected.shape != actual.shape:
        return ImageDiff(float("inf"), 1.0, 255, False, rms_tolerance, share_tolerance, pixel_threshold)
    d = np.abs(expected.astype(np.int16) - actual.astype(np.int16))
    rms = float(np.sqrt(np.mean(d.astype(np.float64) ** 2)))
    per_pixel = d.max(axis=-1)
    share = float(np.mean(per_pixel > pixel_threshold))
    return ImageDiff(rms, share, int(d.max(initial=0)), True, rms_tolerance, share_tolerance, pixel_threshold,
                     float(np.mean(per_pixel > NOISE_LEVELS)))


def amplified_diff(expected: np.ndarray, actual: np.ndarray, gain: float = 8.0) -> np.ndarray:
    """|expected - actual| x gain, clipped to 8 bits (makes small differences visible)."""
    if expected.shape != actual.shape:
        h = max(expected.shape[0], actual.shape[0])
        w = max(expected.shape[1], actual.shape[1])
        a = np.zeros((h, w, 3), np.uint8)
        b = np.zeros((h, w, 3), np.uint8)
        a[: expected.shape[0], : expected.shape[1]] = expected
        b[: actual.shape[0], : actual.shape[1]] = actual
        expected, actual = a, b
    d = np.abs(expected.astype(np.float64) - actual.astype(np.float64)) * gain
    return np.clip(d, 0, 255).astype(np.uint8)


def write_failure_images(folder: Path, expected: np.ndarray | None, actual: np.ndarray) -> Path:
    """Write expected.png, actual.png and diff.png (amplified) into `folder`; returns the folder."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    Image.fromarray(np.ascontiguousarray(actual)).save(folder / "actual.png")
    if expected is not None:
        Image.fromarray(np.ascontiguousarray(expected)).save(folder / "expected.png")
        Image.fromarray(amplified_diff(expected, actual)).save(folder / "diff.png")
    return folder
