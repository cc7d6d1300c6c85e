"""Spring lines for the wireframe view (docs/method.md §6, Fig. 8).

Every live structural and shear spring (and live shear twin) becomes a line between its current
end particles. Bend springs are left out: they run along the structural springs and would only
double the lines. Each line end carries a flag telling whether its crossing is at yarn level; the
line shader colours base-model ends purple and yarn-level ends blue, so regions read as in Fig. 8.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from fraytool.io.frame_record import FrameRecord
from fraytool.kinds import SHEAR, SHEAR_TWIN, STRUCT_WARP, STRUCT_WEFT

DRAWN_KINDS = (STRUCT_WEFT, STRUCT_WARP, SHEAR, SHEAR_TWIN)


@dataclass(frozen=True)
class SpringLines:
    vertices: np.ndarray
    """Line end points, shape (2 L, 4), float32: position [m] (3) and yarn-level flag (1)."""

    @property
    def count(self) -> int:
        return int(self.vertices.shape[0] // 2)


def spring_lines(topology: Mapping[str, np.ndarray], record: FrameRecord) -> SpringLines:
    """Lines of the live drawn springs of one frame."""
    C = int(np.asarray(topology["crossing_count"]).item())
    kind = np.asarray(topology["spring_kind"])
    drawn = np.isin(kind, DRAWN_KINDS) & np.asarray(record.spring_alive, dtype=bool)
    a = np.asarray(record.spring_particle_a)[drawn]
    b = np.asarray(record.spring_particle_b)[drawn]
    ends = np.stack([a, b], axis=1).reshape(-1)
    level = np.asarray(record.crossing_yarn_level, dtype=bool)[ends % C]
    v = np.empty((len(ends), 4), dtype=np.float32)
    v[:, :3] = np.asarray(record.particle_position_m)[ends]
    v[:, 3] = level
    return SpringLines(v)
