"""Level of detail: how many tube sides and spline samples a frame needs on screen.

The scene's `[render] tube_sides` and `spline_samples` are the most detail ever used. When the
yarns are small on screen (a 64 x 64 cloth at 1280x720 has yarns under a pixel wide), more
geometry only costs time: llvmpipe's cost grows with the triangle count, and 4x MSAA multiplies it.
So for each frame we take the closest crossing to the camera (where yarns look biggest) and pick
- sides: enough that one facet of the tube spans at most FACET_PX pixels (at least 3);
- samples per segment: enough that one spline sample spans at most SAMPLE_PX pixels (at least 2,
  so the curve stays a spline, unless the scene asks for 1 or the segment spans at most STRAIGHT_PX
  pixels).
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

FACET_PX = 2.0
"""Largest on-screen width of one tube facet [pixels]."""
SAMPLE_PX = 8.0
"""Largest on-screen length of one spline sample step [pixels]: about the width of a yarn in the shipped
framings (at least 8 px); fig7 frames with 6 look the same and take a quarter more triangles."""


STRAIGHT_PX = 4.0
"""Segments no longer than this on screen [pixels] are drawn straight (one sample step): a yarn's rise
and fall over one spacing (the thickness, about a sixth of the spacing) is then under a pixel."""


@dataclass(frozen=True)
class Detail:
    sides: int
    samples_per_segment: int
    """The most samples per segment any piece of the frame has."""
    segment_samples: np.ndarray | None = None
    """Samples of each yarn segment (in piece order, fraytool.render.spline), int64; None:
    samples_per_segment for all."""


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
    choose_detail, at most `max_samples`."""
    off = np.asarray(offsets, dtype=np.int64)
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    depth = -camera.view_depth(points)                                # behind the eye: as near as can be
    starts = np.ones(len(points), dtype=bool)
    starts[off[1:] - 1] = False                                       # a piece's last point starts no segment
    i = np.nonzero(starts)[0]
    nearest = np.minimum(depth[i], depth[i + 1])
    ppm = pixels_per_metre(camera, image_height, nearest)
    length_px = spacing_m * ppm
    samples = np.ceil(length_px / SAMPLE_PX).astype(np.int64)
    # at least 2 (the curve stays a spline), but 1 (a straight step) where the segment spans at most
    # STRAIGHT_PX: the weave's bend over one spacing is then well under a pixel
    least = np.where(length_px <= STRAIGHT_PX, 1, min(2, max_samples))
    return np.clip(samples, least, max_samples)

