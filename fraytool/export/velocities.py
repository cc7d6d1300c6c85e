"""Velocities for the USD export, by finite differences of frame records (which store positions only).

USD `velocities` are in stage units per second of the stage's timeline (a time code lasts
1 / timeCodesPerSecond); the export puts frame k at time code k, so a velocity is the derivative along
the frame number times timeCodesPerSecond. The derivative at frame k is that of the Lagrange polynomial
through frame k and its stencil (`stencil_frames`): the nearest stored frame before and after (the
central difference), at either end of the stored frames the two nearest on the one side (the
second-order one-sided difference, exact for constant acceleration too).

Yarns: the curve points of frame k depend on its particles and on which springs are alive (where the
yarns split into pieces). A neighbour frame's points are computed with its own particles and crossing
levels but with frame k's live springs, so that they are the same points in the same order as frame
k's (fraytool.render.yarns) and differences of them are the points' motion, also while the cloth tears.

Bodies: the linear velocity of the body's origin (its frame record position) and the angular velocity
in world axes, the derivative of the rotation vector of R(k + d) R(k)^T; the velocity of a point p of
the body is v + w x (p - origin). A mesh body's `velocities` are those of its points in the body's own
frame (what USD means by them: the prim's transform carries the rigid motion), so zero unless the mesh
is animated.
"""
from __future__ import annotations

from bisect import bisect_left
from collections import OrderedDict
from dataclasses import dataclass
from typing import Callable, Iterable, Mapping, Sequence

import numpy as np

from fraytool.geometry.rotations import rotation_vector
from fraytool.io.frame_record import FrameRecord
from fraytool.meshes import MeshTable
from fraytool.render.yarns import yarn_pieces


class FrameSource:
    """The frame records velocities may draw on: the sorted frame numbers available and a loader, keeping
    the last few records loaded (each frame is a neighbour of the next and of the one before)."""

    def __init__(self, frames: Iterable[int], load: Callable[[int], FrameRecord], keep: int = 4):
        self.frames = sorted(int(f) for f in frames)
        self._load = load
        self._keep = keep
        self._cache: OrderedDict[int, FrameRecord] = OrderedDict()

    @staticmethod
    def of_records(records: Iterable[FrameRecord]) -> "FrameSource":
        """The records themselves as the only frames available."""
        by_frame = {int(r.frame): r for r in records}
        return FrameSource(by_frame, by_frame.__getitem__, keep=0)

    def get(self, frame: int) -> FrameRecord:
        if frame in self._cache:
            self._cache.move_to_end(frame)
            return self._cache[frame]
        record = self._load(frame)
        if self._keep:
            self._cache[frame] = record
            while len(self._cache) > self._keep:
                self._cache.popitem(last=False)
        return record


def stencil_frames(frame: int, available: Sequence[int]) -> list[int]:
    """The frames the derivative at `frame` is taken over (module docstring), `frame` first: it and the
    nearest available frames before and after; with none on one side, the two nearest on the other;
    just `frame` when no other is available."""
    at = bisect_left(available, frame)
    before = [f for f in available[max(at - 2, 0):at] if f < frame]
    after = [f for f in available[at:at + 3] if f > frame][:2]
    if before and after:
        return [frame, before[-1], after[0]]
    return [frame] + (before[::-1] if before else after)


def derivative_weights(offsets: Sequence[float]) -> np.ndarray:
    """Weights w with f'(0) = sum_i w_i f(x_i) for the nodes x_i = offsets: the derivative at 0 of the
    Lagrange polynomial through the nodes (exact for polynomials of degree < len(offsets)), from the
    moment conditions sum_i w_i x_i^p = [p == 1], p = 0 .. n-1 (Fornberg 1988, eq. 1.2)."""
    x = np.asarray(offsets, dtype=np.float64)
    vandermonde = x[None, :] ** np.arange(len(x))[:, None]
    rhs = np.zeros(len(x))
    if len(x) > 1:
        rhs[1] = 1.0
    return np.linalg.solve(vandermonde, rhs)


@dataclass(frozen=True)
class Stencil:
    """Frame records around one exported frame and the weights that turn values at them into a rate per
    second of the stage's timeline (`records[0]` is the frame itself)."""

    records: tuple[FrameRecord, ...]
    weights_per_s: np.ndarray

    @staticmethod
    def around(record: FrameRecord, source: FrameSource, time_codes_per_second: float) -> "Stencil":
        frames = stencil_frames(int(record.frame), source.frames)
        records = (record,) + tuple(source.get(f) for f in frames[1:])
        offsets = [f - frames[0] for f in frames]      # time codes: frame k is at time code k
        return Stencil(records, derivative_weights(offsets) * time_codes_per_second)

    @property
    def has_motion(self) -> bool:
        """False when the frame had no neighbour to difference with (the velocities are unknown)."""
        return len(self.records) > 1

    def rate(self, values: Callable[[FrameRecord], np.ndarray]) -> np.ndarray:
        """sum_i w_i values(record_i): the rate of change of `values` per second, float64."""
        total = None
        for record, w in zip(self.records, self.weights_per_s):
            if w != 0.0:
                term = w * np.asarray(values(record), dtype=np.float64)
                total = term if total is None else total + term
        return total if total is not None else np.zeros_like(np.asarray(values(self.records[0]), np.float64))


def yarn_point_velocities(topology: Mapping[str, np.ndarray], stencil: Stencil) -> np.ndarray:
    """Velocity [m/s of the stage's timeline] of every yarn curve point of the stencil's frame, in the
    order of its YarnPieces points, (N, 3): every record's points with the frame's own live springs."""
    alive = stencil.records[0].spring_alive

    def points(record: FrameRecord) -> np.ndarray:
        return yarn_pieces(topology, record.particle_position_m, record.crossing_yarn_level, alive).points

    return stencil.rate(points)


def body_velocities(stencil: Stencil) -> tuple[np.ndarray, np.ndarray]:
    """(linear velocity [m/s] of each body's origin, angular velocity [rad/s] in world axes), each (B, 3),
    per second of the stage's timeline."""
    here = np.asarray(stencil.records[0].body_rotation, np.float64)

    def turned(record: FrameRecord) -> np.ndarray:  # the rotation vector from this frame's orientation
        rotation = np.asarray(record.body_rotation, np.float64)
        return np.array([rotation_vector(r @ h.T) for r, h in zip(rotation, here)]).reshape(-1, 3)

    return stencil.rate(lambda r: r.body_position_m), stencil.rate(turned)


def mesh_vertex_velocities(meshes: MeshTable, m: int, stencil: Stencil) -> np.ndarray:
    """Velocity of mesh m's vertices in its body's frame [m/s of the stage's timeline], (V_m, 3): the
    rate of its key-frame animation at the records' simulated times (zero for a mesh of one key)."""
    return stencil.rate(lambda record: meshes.vertices_at(m, float(record.time_s)))
