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
