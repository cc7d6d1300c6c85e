"""Motion blur (`fraytool render --motion-blur SHUTTER --motion-samples N`, docs/rendering.md "Motion blur").

The shutter of frame f is open over [t_f, t_f + SHUTTER x frame time]: it opens on the frame. N sub-frames
are drawn at the fractions SHUTTER x k / (N - 1), k = 0 .. N-1, of a frame after t_f, evenly from the
opening to the closing time inclusive, so that sub-frame 0 is the frame itself and a body moving at a
constant speed v leaves a streak whose full length is v x SHUTTER x frame time. Their linear, premultiplied
colours are averaged (the float target), then encoded as any float render is.

The frame records store only frames (not the simulation's sub-steps), so a sub-frame's state is interpolated
between record f and record f+1: each particle's position linearly (an inactive particle's slot holds its
crossing's position, so every slot has one), each body's position linearly and its rotation by slerp (the
short way round). What is discrete comes from record f for every sub-frame: which springs are alive, which
crossings are at yarn level, which particles are active. The scene's last frame has no record after it: its
sub-frames continue the motion from the frame before (record f-1 to f, extrapolated), as the USD export's
velocities take a one-sided difference there; a shot of one frame is not blurred. So frame f's pixels
depend only on records f-1 .. f+1 of the shot, never on which --frames range is rendered. A sub-frame's time
is interpolated as its positions are, and a moving camera ([camera] keys) draws it from its pose at that time
(fraytool.render.camera.camera_at), so the camera's own motion blurs too.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

from fraytool.errors import InputError
from fraytool.geometry.rotations import quaternion_wxyz
from fraytool.io.frame_record import FrameRecord

SHUTTER_RANGE = (0.0, 1.0)
"""--motion-blur: the shutter's open time as a fraction of a frame; 0 is off."""
SAMPLES_RANGE = (2, 64)
"""--motion-samples: sub-frames drawn per frame."""
DEFAULT_SAMPLES = 8


@dataclass(frozen=True)
class MotionBlur:
    shutter: float
    """Fraction of a frame the shutter is open, in (0, 1]."""
    samples: int = DEFAULT_SAMPLES
    """Sub-frames drawn and averaged per frame, 2 to 64."""

    def offsets(self) -> list[float]:
        """The sub-frames' times after the frame, in frames: shutter x k / (N - 1), k = 0 .. N-1."""
        n = self.samples
        return [self.shutter * k / (n - 1) for k in range(n)]

    def settings(self) -> dict:
        """What enters the job digest (only when blur is on)."""
        return {"shutter": self.shutter, "samples": self.samples}


def parse_shutter(value) -> float:
    """--motion-blur SHUTTER: a number from 0 to 1 (a fraction of a frame; 0 turns motion blur off)."""
    text = str(value).strip()
    try:
        shutter = float(text)
    except ValueError:
        shutter = math.nan
    if not (math.isfinite(shutter) and SHUTTER_RANGE[0] <= shutter <= SHUTTER_RANGE[1]):
        raise InputError(f"--motion-blur {text!r}: expected a number from 0 to 1, the fraction of a frame the "
                         "shutter is open (e.g. 0.5; 0 turns motion blur off)")
    return shutter


def parse_samples(value) -> int:
    """--motion-samples N: a whole number from 2 to 64 (sub-frames drawn per frame)."""
    text = str(value).strip()
    lo, hi = SAMPLES_RANGE
    if not (text.isdigit() and lo <= int(text) <= hi):
        raise InputError(f"--motion-samples {text!r}: expected a whole number from {lo} to {hi} (sub-frames drawn "
                         f"and averaged per frame with --motion-blur; default {DEFAULT_SAMPLES})")
    return int(text)


def motion_blur_from(shutter, samples) -> Optional[MotionBlur]:
    """The MotionBlur of the flags' values (None: not given), or None when the shutter is 0 (off).
    --motion-samples is checked even without --motion-blur, and then does nothing."""
    n = parse_samples(samples) if samples is not None else DEFAULT_SAMPLES
    s = parse_shutter(shutter) if shutter is not None else 0.0
    return MotionBlur(s, n) if s > 0.0 else None


def records_needed(frame_end: int, scene_frames: int) -> int:
    """Frame records (0 .. n-1) a blurred render of frames up to frame_end (exclusive) reads: the frame after
    the last one too, unless that is past the scene's end (then the one before serves)."""
    return min(frame_end + 1, scene_frames)


def neighbour(frame: int, scene_frames: int) -> Optional[int]:
    """The other record frame f's sub-frames are interpolated with: f+1, or f-1 for the scene's last frame,
    None for a one-frame scene."""
    if frame + 1 < scene_frames:
        return frame + 1
    return frame - 1 if frame >= 1 else None


def _slerp(qa: np.ndarray, qb: np.ndarray, u: float) -> np.ndarray:
    """Quaternion slerp q_a (q_a* q_b)^u the short way round; u outside [0, 1] extrapolates."""
    if float(qa @ qb) < 0.0:
        qb = -qb
    cos = float(np.clip(qa @ qb, -1.0, 1.0))
    angle = math.acos(cos)
    if angle < 1e-9:
        q = qa + u * (qb - qa)
    else:
        s = math.sin(angle)
        q = (math.sin((1.0 - u) * angle) * qa + math.sin(u * angle) * qb) / s
    return q / np.linalg.norm(q)


def _matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def interpolate_rotation(ra: np.ndarray, rb: np.ndarray, u: float) -> np.ndarray:
    """Rotation matrix a fraction u of the way from ra to rb (slerp; u > 1 extrapolates)."""
    if u == 0.0:
        return np.asarray(ra)
    return _matrix(_slerp(quaternion_wxyz(ra), quaternion_wxyz(rb), u))


def interpolate(base: FrameRecord, a: FrameRecord, b: FrameRecord, u: float) -> FrameRecord:
    """The state a fraction u of the way from record a to record b (u may exceed 1: extrapolated), with the
    discrete state (springs alive, crossing levels, active particles) of `base`."""
    if u == 0.0 and base is a:
        return base
    pos = (a.particle_position_m.astype(np.float64)
           + u * (b.particle_position_m.astype(np.float64) - a.particle_position_m))
    bpos = a.body_position_m.astype(np.float64) + u * (b.body_position_m.astype(np.float64) - a.body_position_m)
    rot = np.array([interpolate_rotation(ra, rb, u) for ra, rb in zip(a.body_rotation, b.body_rotation)])
    return dataclasses.replace(
        base,
        time_s=float(a.time_s + u * (b.time_s - a.time_s)),
        particle_position_m=pos.astype(np.float32),
        body_position_m=bpos.astype(np.float32),
        body_rotation=rot.reshape(np.shape(base.body_rotation)).astype(np.float32),
    )


def sub_frame_records(frame: int, scene_frames: int, load: Callable[[int], FrameRecord],
                      blur: MotionBlur) -> list[FrameRecord]:
    """The N sub-frame states of `frame` (the first is the frame's own record)."""
    record = load(frame)
    other = neighbour(frame, scene_frames)
    if other is None:
        return [record] * blur.samples
    if other > frame:
        a, b, start = record, load(other), 0.0
    else:  # the scene's last frame: continue the motion from the frame before
        a, b, start = load(other), record, 1.0
    out = []
    for s in blur.offsets():
        out.append(record if s == 0.0 else interpolate(record, a, b, start + s))
    return out


def frames_needed(job) -> int:
    """Frame records (0 .. n-1) a render of `job` (fraytool.render.job.RenderJob) reads: up to the end of
    its range, and with motion blur the record after it too, which the last frame's sub-frames are
    interpolated towards (none past the scene's end)."""
    if job.motion_blur is None:
        return job.frames.end
    return records_needed(job.frames.end, job.spec.time.frames)
