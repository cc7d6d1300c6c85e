"""Level of detail: how many tube sides and spline samples a frame needs on screen.

The scene's `[render] tube_sides` and `spline_samples` are the most detail ever used. When the
yarns are small on screen (a 64 x 64 cloth at 1280x720 has yarns under a pixel wide), more
geometry only costs time: llvmpipe's cost grows with the triangle count, and 4x MSAA multiplies it.
So for each frame we take the closest crossing to the camera (where yarns look biggest) and pick
- sides: enough that one facet of the tube spans at most FACET_PX pixels (at least 3);
- samples per segment: enough that one spline sample spans at most SAMPLE_PX pixels (at least 2,
  so the curve stays a spline, unless the scene asks for 1 or the segment spans at most STRAIGHT_PX
  pixels; ribbons also draw segments of up to RIBBON_STRAIGHT_PX as one step where they are not seen
  nearly end-on, `ribbon_steps`).
Samples are then chosen per segment (`segment_samples`), from the nearer of its two control points,
at most the frame's count: in a wide shot the far half of the cloth is drawn with fewer triangles
than the near half, each sample step still at most SAMPLE_PX pixels.
The choice depends only on the frame and the camera, so a frame renders the same whatever range
it is rendered in (farm shards agree).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fraytool.render.camera import Camera
from fraytool.render.tube import body_pairs

FACET_PX = 2.0
"""Largest on-screen width of one tube facet [pixels]."""
SAMPLE_PX = 8.0
"""Largest on-screen length of one spline sample step [pixels]: about the width of a yarn in the shipped
framings (at least 8 px); fig7 frames with 6 look the same and take a quarter more triangles."""


STRAIGHT_PX = 4.0
"""Segments no longer than this on screen [pixels] are drawn straight (one sample step): a yarn's rise
and fall over one spacing (the thickness, about a sixth of the spacing) is then under a pixel."""

RIBBON_STRAIGHT_PX = 8.0
"""The same for ribbons not seen end-on (ribbon_steps), which carry the spline's tangent at a straight
step's middle to the pixels (fraytool.render.ribbon, "Straight steps"): the step's shape is then a pixel
off at most, and its shading keeps the yarn's tilt between two crossings. A fifth to a quarter fewer
yarn triangles on the tablecloth."""


@dataclass(frozen=True)
class Detail:
    sides: int
    samples_per_segment: int
    """The most samples per segment any piece of the frame has."""
    segment_samples: np.ndarray | None = None
    """Samples of each yarn segment (in piece order, fraytool.render.spline), int64; None:
    samples_per_segment for all."""
    tilted: np.ndarray | None = None
    """Ribbons: the segments drawn as straight steps carrying their middle's tangent (ribbon_steps), bool
    per segment; None: every one-sample segment (without a camera, the style's own detail)."""


def pixels_per_metre(camera: Camera, image_height: int, depth_m):
    """On-screen size of one metre seen at view depth `depth_m` (a number or an array; depths nearer
    than the camera's near plane, behind the eye included, count as the near plane)."""
    depth = np.maximum(depth_m, camera.near)
    return image_height / (2.0 * depth * math.tan(math.radians(camera.spec.fov_deg) / 2.0))


def choose_detail(camera: Camera, image_height: int, points: np.ndarray, radius_m: float, spacing_m: float,
                  max_sides: int, max_samples: int) -> Detail:
    """Detail for yarns through `points` (e.g. the crossings of a frame) seen by `camera`."""
    depth = -camera.view_depth(points)
    ahead = depth[depth > camera.near]
    nearest = float(ahead.min()) if ahead.size else camera.near
    ppm = pixels_per_metre(camera, image_height, nearest)
    sides = min(max_sides, max(3, math.ceil(2.0 * math.pi * radius_m * ppm / FACET_PX)))
    samples = min(max_samples, max(2, math.ceil(spacing_m * ppm / SAMPLE_PX)))
    return Detail(sides=int(sides), samples_per_segment=int(max(1, samples)))


def segment_samples(camera: Camera, image_height: int, points: np.ndarray, offsets: np.ndarray, spacing_m: float,
                    max_samples: int) -> np.ndarray:
    """Samples of each segment of the pieces (control points points[offsets[p]:offsets[p+1]], at least
    two each; segments in piece order), from the nearer of its two control points, by the rule of
    choose_detail, at most `max_samples`; one where the segment spans at most STRAIGHT_PX pixels
    (ribbons: ribbon_steps on top)."""
    return samples_for_lengths(segment_lengths_px(camera, image_height, points, offsets, spacing_m), max_samples)


def segment_lengths_px(camera: Camera, image_height: int, points: np.ndarray, offsets: np.ndarray,
                       spacing_m: float) -> np.ndarray:
    """On-screen length [px] of each segment of the pieces (segment_samples), a yarn spacing seen at the
    nearer of its two control points."""
    if len(points) == 0:
        return np.zeros(0)
    depth = -camera.view_depth(points)                                # behind the eye: as near as can be
    i = body_pairs(offsets)                                           # each segment's first point
    nearest = np.minimum(depth[i], depth[i + 1])
    return spacing_m * pixels_per_metre(camera, image_height, nearest)


def samples_for_lengths(length_px: np.ndarray, max_samples: int) -> np.ndarray:
    """segment_samples' rule on the segments' on-screen lengths [px]."""
    samples = np.ceil(length_px / SAMPLE_PX).astype(np.int64)
    # at least 2 (the curve stays a spline), but 1 (a straight step) where the segment spans at most
    # STRAIGHT_PX: the weave's bend over one spacing is then under a pixel
    least = np.where(length_px <= STRAIGHT_PX, 1, min(2, max_samples))
    return np.clip(samples, least, max_samples)


def projected_lengths_px(camera: Camera, image_size: tuple[int, int], points: np.ndarray,
                         offsets: np.ndarray) -> np.ndarray:
    """Each segment's chord as drawn [px]: the distance on screen between its two control points
    (segments as segment_samples'); inf where one is behind the near plane."""
    if len(points) == 0:
        return np.zeros(0)
    W, H = image_size
    view_proj = camera.view_proj(W / H)
    clip = np.asarray(points, dtype=np.float64) @ view_proj[:, :3].T + view_proj[:, 3]
    ahead = clip[:, 3] > camera.near
    w = np.where(ahead, clip[:, 3], 1.0)
    x, y = 0.5 * W * clip[:, 0] / w, 0.5 * H * clip[:, 1] / w
    i = body_pairs(offsets)                                           # each segment's first point
    length = np.hypot(x[i + 1] - x[i], y[i + 1] - y[i])
    return np.where(ahead[i] & ahead[i + 1], length, np.inf)


STEP_SEEN_ACROSS = 0.5
"""A ribbon's segment of 4-8 px is one straight step only where it is drawn at least this share of its
length (about the sine of its angle to the line of sight: 30 degrees). Running towards the eye, the
strip's width turns fast along the yarn's tilt, and a step's strip turns only with its ends: every
such segment a step, the tablecloth's frame 53 at 2560x1440 was 3.24 levels off (ribbons alone; 3.34
with the far field) against 2.64 (3.21) with the spline's middles drawn; with this share 2.67 (3.27),
with 0.7 2.64 (3.27) but 5 % more triangles on the first frames, with 0.3 2.97 (3.35). At 1280x720 no
step of frame 53 runs that close to the line of sight (3.72 with the far field, 4.66 alone, from 3.77
and 4.70 without steps)."""


def ribbon_steps(length_px: np.ndarray, drawn_px: np.ndarray, samples: np.ndarray,
                 seen_across: float = STEP_SEEN_ACROSS) -> tuple[np.ndarray, np.ndarray]:
    """(samples, tilted) per segment for ribbons: `samples` (the rule of samples_for_lengths with
    STRAIGHT_PX) turned to one where the segment spans at most RIBBON_STRAIGHT_PX (`length_px`) and is
    drawn at least `seen_across` times that long (`drawn_px`, projected_lengths_px); those steps, longer
    than STRAIGHT_PX, are `tilted`: they carry their middle's tangent (fraytool.render.ribbon). Shorter
    ones blend their ends' tangents alone, as tubes' do: there the tilt's highlight varies within a
    pixel, and one shading per pixel only aliases it (tablecloth frame 53 drawn with ribbons alone: 5.08
    levels with those tilted too, 4.66 without)."""
    length_px = np.asarray(length_px)
    tilted = (length_px > STRAIGHT_PX) & (length_px <= RIBBON_STRAIGHT_PX) & \
        (np.asarray(drawn_px) >= seen_across * length_px)
    return np.where(tilted, 1, samples), tilted
