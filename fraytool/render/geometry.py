"""Frame record -> everything the GPU draws for one frame (yarn tubes, spring lines, bodies).

This is the "geometry" stage of `fraytool bench --render`: NumPy and numba, no GL.
Steps: yarn pieces (fraytool.render.yarns) -> centripetal Catmull-Rom samples (spline) -> fade
alpha and rotation-minimising tube sweep (tube), with the level of detail chosen per frame (lod).
The tube index buffer depends only on how many samples each piece has and on the side count, so it
is cached between frames (it changes when a spring is cut or the detail level changes).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping, Optional

import numpy as np

from fraytool.io.frame_record import FrameRecord
from fraytool.render.camera import Camera
from fraytool.render.farfield import FAR_PX, NEAR_PX, FarField, far_field, grid_arrays
from fraytool.render.lod import (Detail, choose_detail, projected_lengths_px, ribbon_steps, samples_for_lengths,
                                 segment_lengths_px)
from fraytool.render.ribbon import (ribbon_curves, ribbon_triangles, ribbon_vertices, shadow_casters,
                                    translucent_ribbon_triangles)
from fraytool.render.spline import catmull_rom, polyline_tangents
from fraytool.render.tube import VERTEX_FLOATS, fade_alpha, sweep_tubes, translucent_triangles, tube_triangles
from fraytool.render.weave_texture import weave_tiles
from fraytool.render.wireframe import SpringLines, spring_lines
from fraytool.render.yarns import YarnPieces, yarn_pieces, yarn_points
from fraytool.scene.spec import RenderSpec

__all__ = ["VERTEX_FLOATS", "YarnStyle", "YarnMesh", "YarnCurves", "FrameGeometry", "GeometryBuilder", "yarn_curves"]


@dataclass(frozen=True)
class YarnStyle:
    """Geometric render settings resolved against the cloth (defaults that depend on it)."""

    radius_m: float
    """Tube radius [m]."""
    fade_length_m: float
    """Arc length over which a broken end fades to transparent [m]."""
    samples_per_segment: int
    """Most Catmull-Rom samples per segment (the level of detail may use fewer)."""
    sides: int
    """Most tube sides (the level of detail may use fewer)."""
    spacing_m: float
    """Yarn spacing at rest [m] (sets the sampling density the level of detail needs)."""
    shape: str = "tube"
    """"tube" (swept circles) or "ribbon" (view-facing strips shaded as tubes, fraytool.render.ribbon)."""
    light_direction: Optional[tuple] = None
    """Direction towards the key light when the render has shadows (ribbons: the shadow pass's strips
    face it), else None (no shadow strips are built)."""
    far_field: bool = False
    """Draw intact cloth whose yarns are under a few pixels apart as one surface (fraytool.render.farfield):
    the scene's `far_field`, off for a cloth whose weave has no repeat the far field can hold
    (fraytool.render.weave_texture.weave_tiles)."""
    far_field_px: float = 0.5 * (NEAR_PX + FAR_PX)
    """Middle of the blend band [px of yarn spacing on screen]; the band runs from 2/3 to 4/3 of it."""

    @staticmethod
    def from_spec(render: RenderSpec, topology: Mapping[str, np.ndarray]) -> "YarnStyle":
        thickness = float(np.asarray(topology["thickness_m"]).item())
        spacing = float(np.asarray(topology["spacing_m"]).item())
        return YarnStyle(
            radius_m=render.yarn_radius_m if render.yarn_radius_m > 0 else 0.5 * thickness,
            fade_length_m=render.fade_length_m if render.fade_length_m > 0 else 2.0 * spacing,
            samples_per_segment=render.spline_samples,
            sides=render.tube_sides,
            spacing_m=spacing,
            shape=render.yarn_shape,
            light_direction=tuple(float(v) for v in render.light_direction) if render.shadows else None,
            # a cloth whose weave has no repeat of at most 64 crossings is drawn yarn by yarn
            far_field=render.far_field and weave_tiles(topology) is not None,
            far_field_px=render.far_field_px,
        )


@dataclass(frozen=True)
class YarnMesh:
    vertices: np.ndarray
    """Interleaved vertex data, shape (V, VERTEX_FLOATS), float32 (see fraytool.render.tube)."""
    opaque: np.ndarray
    """Triangles whose three vertices are fully opaque, shape (Fo, 3), uint32."""
    translucent: np.ndarray
    """Triangles touching a fading end, shape (Ft, 3), uint32 (drawn sorted, after the opaque ones)."""
    centroid: np.ndarray
    """Centroid of each translucent triangle [m], shape (Ft, 3), float32 (for the depth sort)."""
    pieces: int
    detail: Detail
    shadow_positions: Optional[np.ndarray] = None
    """Ribbons only: vertex positions of the strips turned to face the key light through every other
    sample [m], (V', 3) float32, drawn into the shadow map instead of `vertices` (fraytool.render.ribbon)."""
    shadow_triangles: Optional[np.ndarray] = None
    """Ribbons only: the opaque triangles over `shadow_positions`, (F', 3) uint32."""
    far: Optional[np.ndarray] = None
    """Far weight of each vertex, (V,) float32, where yarns blend into the far-field surface (the blend
    band, fraytool.render.farfield); None: no vertex does."""
    steps: Optional[np.ndarray] = None
    """Ribbons only: the straight-step data of each vertex, (V, STEP_FLOATS) float32 (fraytool.render.ribbon,
    "Straight steps"); None: no step is straight (the shaders then read zeros)."""


@dataclass(frozen=True)
class YarnCurves:
    """The yarn centre lines of a frame as curves (what `fraytool export` writes): the control points
    the renderer's splines pass through, with the renderer's fade at each of them."""

    points: np.ndarray
    """Control points of all pieces [m], shape (N, 3), float64; piece p owns offsets[p]:offsets[p+1]."""
    offsets: np.ndarray
    """Shape (K + 1,), int64."""
    kind: np.ndarray
    """WEFT (0) or WARP (1) per piece (fraytool.render.yarns), shape (K,), int8."""
    yarn: np.ndarray
    """Yarn index per piece (j for a weft, i for a warp), shape (K,), int32."""
    opacity: np.ndarray
    """The fade of broken ends at each control point (1 = opaque), shape (N,), float32."""
    panel: np.ndarray
    """Panel per piece ([[cloth]] entry), -1 for a seam's stitch (a piece of two points), shape (K,), int32."""


def yarn_curves(topology: Mapping[str, np.ndarray], record: FrameRecord, style: YarnStyle) -> YarnCurves:
    """The yarn pieces of a frame (fraytool.render.yarns) and the fade the renderer gives their control
    points: the fade runs along the arc length of the Catmull-Rom samples at the style's full detail,
    and sample k m of a piece is its control point k (fraytool.render.spline)."""
    pieces = yarn_pieces(topology, record.particle_position_m, record.crossing_yarn_level, record.spring_alive)
    m = style.samples_per_segment
    curves = catmull_rom(pieces.points, pieces.offsets, m)
    alpha = fade_alpha(curves.points, curves.offsets, pieces.broken_start, pieces.broken_end, style.fade_length_m)
    counts = np.diff(pieces.offsets)
    piece = np.repeat(np.arange(pieces.count), counts)
    local = np.arange(len(pieces.points)) - pieces.offsets[:-1][piece]
    opacity = alpha[curves.offsets[:-1][piece] + local * m] if len(pieces.points) else np.ones(0, np.float32)
    crossing_panel = np.asarray(topology["crossing_panel"]) if "crossing_panel" in topology else \
        np.zeros(len(np.asarray(topology["crossing_rest_position_m"])), np.int32)
    panel = np.where(pieces.yarn >= 0, crossing_panel[pieces.first_crossing], -1).astype(np.int32)
    return YarnCurves(pieces.points, pieces.offsets, pieces.kind, pieces.yarn, opacity.astype(np.float32), panel)


@dataclass(frozen=True)
class FrameGeometry:
    yarns: Optional[YarnMesh]
    """Shaded yarn tubes (None when only the wireframe is drawn)."""
    lines: Optional[SpringLines]
    """Spring lines for the wireframe view (None when it is off)."""
    body_position_m: np.ndarray
    body_rotation: np.ndarray
    time_s: float = 0.0
    """The frame's simulated time [s] (animated mesh bodies are drawn as they are then)."""
    surface: Optional[FarField] = None
    """The far-field surface (None: every yarn is drawn as a yarn)."""


class GeometryBuilder:
    """Builds FrameGeometry for successive frames of one run (caches the tube index buffer).

    With a camera and image height the detail adapts to the on-screen yarn size (fraytool.render.lod);
    without, the style's full detail is used. A moving camera (keys) is taken at each record's time.
    """

    def __init__(self, topology: Mapping[str, np.ndarray], style: YarnStyle, camera: Optional[Camera] = None,
                 image_height: Optional[int] = None, image_width: Optional[int] = None):
        """`image_width`: the shaded view's width [px] (default: 16:9 of the height); with the far field
        it decides which crossings are on screen."""
        self.topology = topology
        self.style = style
        self.camera = camera
        self.image_height = image_height
        self.image_width = image_width if image_width is not None else (
            None if image_height is None else int(round(image_height * 16 / 9)))
        self._tri_key: Optional[tuple] = None
        self._tri: Optional[np.ndarray] = None

    def camera_at(self, time_s: float) -> Optional[Camera]:
        """The camera a frame of time_s is seen with (None: no camera)."""
        return None if self.camera is None else self.camera.at(time_s)

    def detail(self, pieces: YarnPieces, camera: Optional[Camera] = None) -> Detail:
        """`camera`: the frame's (default: the builder's)."""
        st = self.style
        camera = self.camera if camera is None else camera
        if camera is None or self.image_height is None:
            return Detail(st.sides, st.samples_per_segment)
        frame = choose_detail(camera, self.image_height, pieces.points, st.radius_m, st.spacing_m,
                              st.sides, st.samples_per_segment)
        length_px = segment_lengths_px(camera, self.image_height, pieces.points, pieces.offsets, st.spacing_m)
        per_segment = samples_for_lengths(length_px, frame.samples_per_segment)
        tilted = None
        if st.shape == "ribbon":
            drawn_px = projected_lengths_px(camera, (self.image_width, self.image_height), pieces.points,
                                            pieces.offsets)
            per_segment, tilted = ribbon_steps(length_px, drawn_px, per_segment)
        return Detail(frame.sides, frame.samples_per_segment, per_segment, tilted)

    def _triangles(self, offsets: np.ndarray, sides: int) -> np.ndarray:
        key = (self.style.shape, sides, np.diff(offsets).tobytes())
        if key != self._tri_key:
            self._tri = ribbon_triangles(offsets) if self.style.shape == "ribbon" else tube_triangles(offsets, sides)
            self._tri_key = key
        return self._tri

    def yarn_mesh(self, pieces: YarnPieces, far: Optional[FarField] = None,
                  camera: Optional[Camera] = None) -> YarnMesh:
        """`camera`: the frame's (default: the builder's)."""
        st = self.style
        camera = self.camera if camera is None else camera
        point_far = _point_far_weight(pieces, far, int(np.asarray(self.topology["warp_yarns"]).item())) \
            if far is not None else None
        detail = self.detail(pieces, camera)
        if st.shape == "ribbon":
            return self._ribbon_mesh(pieces, detail, point_far, camera)
        curves = catmull_rom(pieces.points, pieces.offsets, _samples(detail))
        tangents = polyline_tangents(curves.points, curves.offsets)
        alpha = fade_alpha(curves.points, curves.offsets, pieces.broken_start, pieces.broken_end,
                           st.fade_length_m)
        warp = np.repeat(pieces.color_index, np.diff(curves.offsets))  # palette index (fraytool.render.color)
        tri = self._triangles(curves.offsets, detail.sides)
        tube = sweep_tubes(curves.points, tangents, curves.offsets, st.radius_m, detail.sides, alpha, warp,
                           reference_normal=pieces.normal, triangles=tri)
        if (alpha < 1.0).any():
            see_through = translucent_triangles(curves.offsets, detail.sides, alpha)
            opaque, translucent = tri[~see_through], tri[see_through]
        else:
            opaque, translucent = tri, tri[:0]
        centroid = tube.position[translucent].mean(axis=1) if len(translucent) else np.zeros((0, 3), np.float32)
        vertex_far = None
        sample_far = _sample_far_weight(curves, point_far)
        if sample_far is not None:
            ends = np.stack([sample_far[curves.offsets[:-1]], sample_far[curves.offsets[1:] - 1]], axis=1)
            vertex_far = np.concatenate([np.repeat(sample_far, detail.sides),
                                         np.repeat(ends.ravel(), detail.sides + 1)]).astype(np.float32)
        return YarnMesh(tube.vertices, opaque, translucent, centroid, pieces.count, detail, far=vertex_far)

    def _ribbon_mesh(self, pieces: YarnPieces, detail: Detail, point_far: Optional[np.ndarray] = None,
                     camera: Optional[Camera] = None) -> YarnMesh:
        """View-facing strips (fraytool.render.ribbon); the eye is the camera's (its origin without one)."""
        st = self.style
        curves, tangents, steps = ribbon_curves(pieces.points, pieces.offsets, _samples(detail), st.radius_m,
                                                detail.tilted)
        alpha = fade_alpha(curves.points, curves.offsets, pieces.broken_start, pieces.broken_end,
                           st.fade_length_m)
        warp = np.repeat(pieces.color_index, np.diff(curves.offsets))  # palette index (fraytool.render.color)
        camera = self.camera if camera is None else camera
        eye = camera.eye if camera is not None else np.zeros(3)
        vertices = ribbon_vertices(curves.points, tangents, st.radius_m, alpha, warp, eye)
        shadow, shadow_tri = (shadow_casters(curves.points, tangents, curves.offsets, alpha, st.radius_m,
                                             np.asarray(st.light_direction))
                              if st.light_direction is not None else (None, None))
        tri = self._triangles(curves.offsets, 2)
        if (alpha < 1.0).any():
            see_through = translucent_ribbon_triangles(curves.offsets, alpha)
            opaque, translucent = tri[~see_through], tri[see_through]
        else:
            opaque, translucent = tri, tri[:0]
        centroid = (vertices[:, 0:3][translucent].mean(axis=1) if len(translucent)
                    else np.zeros((0, 3), np.float32))
        sample_far = _sample_far_weight(curves, point_far)
        return YarnMesh(vertices, opaque, translucent, centroid, pieces.count,
                        Detail(2, detail.samples_per_segment, detail.segment_samples, detail.tilted),
                        shadow_positions=shadow, shadow_triangles=shadow_tri, steps=steps,
                        far=None if sample_far is None else np.repeat(sample_far, 2).astype(np.float32))

    def build(self, record: FrameRecord, yarns: bool = True, lines: bool = False) -> FrameGeometry:
        """Geometry of one frame; `yarns` / `lines` choose what the shaded and wireframe views need."""
        topo = self.topology
        mesh = None
        surface = None
        if yarns:
            camera = self.camera_at(float(record.time_s))
            points = yarn_points(topo, record.particle_position_m, record.crossing_yarn_level)
            surface = self.far_field(record, points)
            hidden = None if surface is None else (surface.hidden_weft, surface.hidden_warp)
            pieces = yarn_pieces(topo, record.particle_position_m, record.crossing_yarn_level,
                                 record.spring_alive, hidden=hidden, with_places=surface is not None, points=points)
            mesh = self.yarn_mesh(pieces, surface, camera)
        return FrameGeometry(
            yarns=mesh,
            lines=spring_lines(topo, record) if lines else None,
            body_position_m=np.asarray(record.body_position_m, dtype=np.float32),
            body_rotation=np.asarray(record.body_rotation, dtype=np.float32),
            time_s=float(record.time_s),
            surface=surface,
        )

    def far_field(self, record: FrameRecord, points=None) -> Optional[FarField]:
        """The frame's far field (fraytool.render.farfield), or None: off in the style, no camera, or
        no crossing far enough (then the frame is drawn exactly as without it). `points`: the frame's
        yarn_points, if already computed."""
        st = self.style
        if not st.far_field or self.camera is None or self.image_height is None:
            return None
        topo = self.topology
        weft_pt, warp_pt, normal = points if points is not None else \
            yarn_points(topo, record.particle_position_m, record.crossing_yarn_level)
        centre = 0.5 * (weft_pt + warp_pt)
        grid = grid_arrays(topo, centre, normal, record.crossing_yarn_level, record.spring_alive)
        field = far_field(self.camera_at(float(record.time_s)), (self.image_width, self.image_height), *grid,
                          near_px=st.far_field_px * 4.0 / 3.0, far_px=st.far_field_px * 2.0 / 3.0)
        if not field.quads:
            return None
        return field


def _point_far_weight(pieces: YarnPieces, far: FarField, warp_yarns: int) -> Optional[np.ndarray]:
    """Far weight of each control point: the crossing's, where every link of its piece at the point has
    surface quads on both sides (the surface then holds the whole yarn there), else 0; None if all 0."""
    place = pieces.place
    n = len(place)
    if n == 0:
        return None
    W = warp_yarns
    counts = np.diff(pieces.offsets)
    kind = np.repeat(pieces.kind, counts)
    first = np.zeros(n, dtype=bool)
    first[pieces.offsets[:-1]] = True
    last = np.zeros(n, dtype=bool)
    last[pieces.offsets[1:] - 1] = True
    valid = place >= 0
    j, i = np.divmod(np.maximum(place, 0), W)
    cw, cv = far.covered_weft, far.covered_warp
    is_weft = kind == 0
    prev_cov = np.where(is_weft, cw[j, np.clip(i - 1, 0, cw.shape[1] - 1)], cv[i, np.clip(j - 1, 0, cv.shape[1] - 1)])
    next_cov = np.where(is_weft, cw[j, np.minimum(i, cw.shape[1] - 1)], cv[i, np.minimum(j, cv.shape[1] - 1)])
    ok = valid & (first | prev_cov) & (last | next_cov)
    w = np.where(ok, far.weight[np.maximum(place, 0)], 0.0)
    return w if (w > 0.0).any() else None


def _sample_far_weight(curves, point_far: Optional[np.ndarray]) -> Optional[np.ndarray]:
    """Far weight of each spline sample: linear between its control points' (None: none)."""
    if point_far is None or not len(curves.points):
        return None
    return np.interp(np.arange(len(curves.points)), curves.control_index, point_far)


def _samples(detail: Detail):
    """Samples per segment for catmull_rom: per piece when the detail has them."""
    return detail.samples_per_segment if detail.segment_samples is None else detail.segment_samples
