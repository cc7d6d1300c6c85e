"""The GL renderer: FrameGeometry -> 8-bit sRGB image (H, W, 3), top row first (or linear float RGBA and depth).

Pipeline per frame
1. Draw into a multisampled SRGB8_ALPHA8 colour + depth framebuffer (samples clamped to
   ctx.max_samples) with GL_FRAMEBUFFER_SRGB off: shaders light in linear RGB and encode to sRGB
   once per fragment (shaders/output.glsl, IEC 61966-2-1), and GL stores the bytes as they come.
   (With GL_FRAMEBUFFER_SRGB on during the draw, GL would encode instead, per sample of every
   write: about a tenth of the draw on llvmpipe.) Order: opaque yarn triangles, bodies, the ground
   plane, then the translucent (fading) yarn triangles sorted back to front, depth writes off.
2. Resolve the samples with a framebuffer blit into a single-sample sRGB texture with
   GL_FRAMEBUFFER_SRGB on: the samples are decoded, averaged in linear light and the mean encoded,
   so anti-aliased edges are exact (tests/test_render_gl.py).
3. Read back and flip vertically (GL's first row is the bottom one).
The fading ends are drawn with GL_FRAMEBUFFER_SRGB on and the shader's encoding off (u_encode = 0):
GL decodes the target, blends in linear light and encodes, on the few pixels they cover.

The "float" target (16-bit PNGs, EXR, ProRes: `fraytool render --depth 16 / --exr / --codec prores`)
draws the same way into RGBA32F colour instead, without the encoding: the buffer holds linear colour
premultiplied by alpha, unclamped, blended and averaged by the resolve in linear light, and the CPU
encodes it (fraytool.render.color.encode_premultiplied_linear). With `depth`, the resolve also
copies the depth buffer into a depth texture, read as the distance along the view axis
(`read_depth_m`; the resolve of depth keeps one of each pixel's samples, which one is up to the GL
implementation).

Transparency: broken yarn ends fade out over a few yarn spacings, so the translucent surface is a
small share of the mesh (only triangles touching a fading stretch). Those triangles are depth-sorted
back to front by centroid each frame (NumPy argsort, well under a millisecond) and alpha-blended
over the finished opaque image with depth testing on and depth writes off. We chose sorting over
weighted blended OIT (McGuire & Bavoil 2013) because the fade runs from alpha 1 down to 0, and
WBOIT's depth-weighted average is visibly wrong for nearly opaque overlapping layers (exactly the
tangle of frayed ends), because it needs float MRT accumulation plus a composite pass on every
pixel (costly on llvmpipe) and because sorted blending is exact wherever triangles do not
intersect. Opaque triangles never pass through the blend path, so they are unaffected.

Wireframe (Fig. 8): spring lines, purple at base-model crossings and blue at yarn level, drawn with
the bodies; alone ("only") or as a right-hand panel beside the shaded view ("beside": both panels
share the output size, left W//2 columns shaded, right W - W//2 wireframe).
"""
from __future__ import annotations

import math
import time
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Mapping, Optional

import moderngl
import numpy as np

from fraytool.meshes import MeshTable
from fraytool.geometry.rotations import rotation_from_y
from fraytool.render.bodies import BodySet, mesh_draw_vertices, unit_cube, unit_quad, unit_sphere
from fraytool.render.camera import Camera, gl_matrix_bytes, is_animated, key_times_s
from fraytool.render.color import (
    WIREFRAME_BASE_SRGB,
    WIREFRAME_YARN_SRGB,
    encode_premultiplied_linear,
    linear_to_srgb,
    srgb_to_linear,
    straight_alpha_srgb,
    yarn_palette,
)
from fraytool.errors import InputError, RunError
from fraytool.render.context import check_gl_error
from fraytool.render.farfield import SURFACE_FLOATS
from fraytool.render.geometry import FrameGeometry, GeometryBuilder, YarnStyle
from fraytool.render.ribbon import STEP_FLOATS
from fraytool.render.shadow import LightFrame, shadow_footprint
from fraytool.render.shadow_pass import ShadowPass
from fraytool.render.weave_texture import coverage_tile, texels_per_crossing, weave_tiles
from fraytool.render.weave_visibility import NORMAL_BINS, view_tables
from fraytool.resources import shader_source
from fraytool.scene.spec import CameraSpec, RenderSpec

KAJIYA_WEIGHT = 0.35
"""Share of Kajiya-Kay's sin(T, L) in the yarn diffuse term (the rest is Lambert on the tube)."""

WIREFRAME_MODES = ("off", "only", "beside")
TARGETS = ("srgb8", "float")
"""Colour targets: 8-bit sRGB-encoded (the default) or 32-bit float linear (see the module docstring)."""

WEAVE_UNIT = 1
"""Texture unit of the far field's weave texture (the shadow map is unit 0)."""
VISIBILITY_UNIT = 2
"""Texture unit of the far field's view table (fraytool.render.weave_visibility)."""
DOWNSAMPLE_UNIT = 3
"""Texture unit of the resolved image in the supersample pass (shaders/downsample.frag)."""
VISIBILITY_LAYERS = 1 + 2 * 2 * 2 * NORMAL_BINS // 4
"""Layers of the view table per panel: the shares, then the seen normals of the front's weft, its warp,
the back's weft and warp, each their shares per bin and their mean part along the yarn, NORMAL_BINS / 4
RGBA layers each (fraytool.render.weave_visibility; shaders/farfield.vert holds the same layout)."""
MAX_WEAVE_LAYERS = 16
"""Panels with a weave of their own in the far field (the rest share the last one's; shaders/farfield.*)."""

GL_SRGB8_ALPHA8 = 0x8C43
GL_FRAMEBUFFER_SRGB = 0x8DB9

GROUND_OFFSET = (1.0, 4.0)
"""glPolygonOffset of the ground drawn around the shadow footprint: behind the footprint's own depth,
so it fails the depth test there (the two draws' depths of one plane differ by rounding only)."""


@dataclass(frozen=True)
class Panel:
    view: str
    """"shaded" or "wireframe"."""
    x: int
    width: int


def panels(width: int, wireframe: str) -> list[Panel]:
    """How the output image is split for a wireframe mode."""
    if wireframe == "off":
        return [Panel("shaded", 0, width)]
    if wireframe == "only":
        return [Panel("wireframe", 0, width)]
    half = width // 2
    return [Panel("shaded", 0, half), Panel("wireframe", half, width - half)]


def _preprocess(source: str, defines: tuple[str, ...]) -> str:
    """`#define NAME 1` for each of `defines` after the #version line, and each `#include "file"`
    line replaced by that file of shaders/ (GLSL 330 has no include). Without defines and includes
    the source is returned unchanged."""
    lines = source.splitlines(keepends=True)
    out = []
    for line in lines:
        stripped = line.strip()
        if stripped.startswith("#include"):
            out.append(shader_source(stripped.split('"')[1]) + "\n")
        else:
            out.append(line)
            if stripped.startswith("#version"):
                if "FAR_BAND" in defines:  # gl_SampleMask (band.glsl): core only from GLSL 4.00
                    out.append("#extension GL_ARB_sample_shading : require\n")
                if "RIBBON" in defines:  # interpolateAtCentroid (yarn.frag): core only from GLSL 4.00
                    out.append("#extension GL_ARB_gpu_shader5 : require\n")
                out += [f"#define {d} 1\n" for d in defines]
    return "".join(out)


def load_program(ctx: moderngl.Context, vertex: str, fragment: str, defines: tuple[str, ...] = ()) -> moderngl.Program:
    """Compile a program from shader files in shaders/ (see fraytool.resources), with the optional
    features named in `defines` (SHADOWS, FILL, SHADOW_ONE_TAP, RIBBON, ENCODE_SRGB, SURFACE) switched on; a missing file or a compile error is a
    RunError naming the files (a broken installation, not a user mistake)."""
    try:
        sources = _preprocess(shader_source(vertex), defines), _preprocess(shader_source(fragment), defines)
    except OSError as exc:
        raise RunError(f"cannot read shader {exc.filename}: {exc.strerror} (is fraytool installed completely?)") from None
    try:
        return ctx.program(vertex_shader=sources[0], fragment_shader=sources[1])
    except moderngl.Error as exc:
        raise RunError(f"shaders {vertex} + {fragment} do not compile on this GL: {exc}") from None


class _Stream:
    """A GL buffer that grows as needed (re-created, with its vertex arrays, when too small)."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self.buffer: Optional[moderngl.Buffer] = None
        self.capacity = 0
        self.generation = 0

    def write(self, data: np.ndarray) -> None:
        raw = np.ascontiguousarray(data)
        n = raw.nbytes
        if self.buffer is None or n > self.capacity:
            if self.buffer is not None:
                self.buffer.release()
            self.capacity = max(n, int(self.capacity * 1.5), 1024)
            self.buffer = self.ctx.buffer(reserve=self.capacity, dynamic=True)
            self.generation += 1
        if n:
            self.buffer.write(raw)

    def release(self) -> None:
        if self.buffer is not None:
            self.buffer.release()
            self.buffer = None


class Renderer:
    """Draws frames of one run at one size. Holds GL objects; call `release()` when done."""

    def __init__(self, ctx: moderngl.Context, size: tuple[int, int], samples: int, render: RenderSpec,
                 camera: CameraSpec, topology: Mapping[str, np.ndarray], wireframe: str = "off",
                 alpha: bool = False, target: str = "srgb8", depth: bool = False, panels_spec=()):
        """`alpha`: a transparent background; `read()` then gives (H, W, 4) straight alpha (docs/rendering.md).
        `target`: "srgb8" or "float" (`read_linear()`); `depth`: keep the depth for `read_depth_m()`.
        `panels_spec`: the scene's cloth panels (SceneSpec.all_panels), for their own yarn colours."""
        self.palette = yarn_palette(render, panels_spec)
        """sRGB yarn colours by colour index (fraytool.render.color.yarn_palette)."""
        if wireframe not in WIREFRAME_MODES:
            raise ValueError(f"wireframe must be one of {WIREFRAME_MODES}, got {wireframe!r}")
        if target not in TARGETS:
            raise ValueError(f"target must be one of {TARGETS}, got {target!r}")
        self.ctx = ctx
        self.alpha = bool(alpha)
        self.target = target
        self.size = (int(size[0]), int(size[1]))
        """The output image's width and height [px]."""
        self.supersample = int(getattr(render, "supersample", 1))
        """Drawn pixels per output pixel along each axis ([render] supersample)."""
        k = self.supersample
        self.draw_size = (self.size[0] * k, self.size[1] * k)
        """The drawn image's width and height [px]: what the level of detail measures yarns in."""
        self.samples = clamp_samples(ctx, samples)
        self.render_spec = render
        self.camera = Camera(camera)
        self._ground_distance: Optional[float] = None
        """A moving camera's ground checker size comes from this (_ground_distance_m), made when first needed."""
        """The camera of the frame being drawn: a moving camera's ([camera] keys) pose at the frame's time
        (`draw` moves it), else the one camera."""
        self.wireframe = wireframe
        self.panels = [Panel(p.view, p.x * k, p.width * k) for p in panels(self.size[0], wireframe)]
        """The views side by side, in drawn pixels."""
        self.part_s: Optional[dict[str, float]] = None
        """Seconds per part of the last draws when a dict (``_part``; fraytool bench --render)."""

        W, H = self.draw_size
        self._drawn = "float" if target == "float" or k > 1 else "srgb8"
        """The drawn image's format: supersampled, float, so the mean of the drawn pixels keeps a highlight's
        excess over 1 as a camera's pixel does (the 8-bit target clips each drawn pixel; frame 53 of
        tablecloth_tear: 2.09 levels from the 4x reference that way, 1.87 through float)."""
        check_drawn_size(ctx, self.size, k, wireframe)
        try:
            self._make_framebuffers(ctx, depth)
        except moderngl.Error as exc:
            self._release_framebuffers()
            ctx.error  # noqa: B018  (reading it clears the failed allocation's GL error)
            raise RunError(f"{_drawn_size_text(self.size, k, wireframe)}: the GL context cannot make that framebuffer "
                           f"with {self.samples} MSAA samples ({exc}); lower "
                           + ("supersample, " if k > 1 else "") + "resolution or samples") from None

        encode = ("ENCODE_SRGB",) if self._drawn == "srgb8" else ()
        features = (("SHADOWS",) if render.shadows else ()) + (("FILL",) if render.fill_intensity > 0 else ()) + encode
        self.ribbons = render.yarn_shape == "ribbon"
        yarn_features = features + (("SHADOW_ONE_TAP",) if render.shadows else ()) + (("RIBBON",) if self.ribbons else ())
        self._yarn_prog = load_program(ctx, "yarn.vert", "yarn.frag", yarn_features)
        self._body_prog = load_program(ctx, "body.vert", "body.frag", features)
        self._ground_prog = load_program(ctx, "body.vert", "ground.frag", features)
        # With shadows, the ground outside the shadow map's footprint cannot be in shadow: it is
        # drawn by this program without the shadow lookups (_draw_ground).
        split_ground = render.shadows and render.ground_plane
        self._ground_lit_prog = (load_program(ctx, "body.vert", "ground.frag", tuple(f for f in features if f != "SHADOWS"))
                                 if split_ground else None)
        self._ground_progs = (self._ground_prog,) + ((self._ground_lit_prog,) if split_ground else ())
        self._line_prog = load_program(ctx, "line.vert", "line.frag", encode)
        self._thickness_m = float(np.asarray(topology.get("thickness_m", 0.0)).item())
        self._topology_spacing = float(np.asarray(topology.get("spacing_m", 0.0)).item())
        # The far field (fraytool.render.farfield): the surface, and the yarns of the blend band
        # made on the first frame that has a far field (_ensure_far_field): a render that never needs
        # one pays nothing for it
        self.far_field = bool(render.far_field)
        self._far_features = (yarn_features, features)
        self._far_topology = topology
        self._yarn_band_prog = self._far_prog = self._weave = self._visibility = None
        self._yarn_progs = (self._yarn_prog,)
        self.shadow = (ShadowPass(ctx, render.shadow_map_size, topology, load_program(ctx, "depth.vert", "depth.frag"))
                       if render.shadows else None)

        self._body_vaos = {}
        self._ground_lit_vao: Optional[moderngl.VertexArray] = None
        self._light: Optional[LightFrame] = None
        """The key light's box of the frame being drawn (None: no shadows, or nothing casts)."""
        self._static = []
        for name, mesh in (("sphere", unit_sphere()), ("cube", unit_cube()), ("quad", unit_quad())):
            vbo = ctx.buffer(mesh.vertices.tobytes())
            ibo = ctx.buffer(mesh.indices.tobytes())
            self._static += [vbo, ibo]
            self._body_vaos[name] = (
                ctx.vertex_array(self._body_prog, [(vbo, "3f 3f", "in_position", "in_normal")], ibo, 4),
                ctx.vertex_array(self._ground_prog, [(vbo, "3f 3f", "in_position", "in_normal")], ibo, 4),
            )
            if self.shadow is not None:
                self.shadow.add_body_mesh(name, vbo, ibo)
            if name == "quad" and self._ground_lit_prog is not None:
                self._ground_lit_vao = ctx.vertex_array(self._ground_lit_prog, [(vbo, "3f 3f", "in_position", "in_normal")],
                                                        ibo, 4)

        self._meshes = MeshTable(topology)
        self._animated_meshes: list[tuple[int, moderngl.Buffer]] = []
        self._mesh_time_s: Optional[float] = None
        for m in range(self._meshes.count):
            vbo = ctx.buffer(mesh_draw_vertices(self._meshes.key_vertices(m, 0), self._meshes.local_triangles(m)).tobytes())
            ibo = ctx.buffer(np.arange(3 * self._meshes.local_triangles(m).shape[0], dtype=np.uint32).tobytes())
            self._static += [vbo, ibo]
            name = f"mesh{m}"
            self._body_vaos[name] = (
                ctx.vertex_array(self._body_prog, [(vbo, "3f 3f", "in_position", "in_normal")], ibo, 4),
                ctx.vertex_array(self._ground_prog, [(vbo, "3f 3f", "in_position", "in_normal")], ibo, 4),
            )
            if self.shadow is not None:
                self.shadow.add_body_mesh(name, vbo, ibo)
            if self._meshes.animated(m):
                self._animated_meshes.append((m, vbo))

        self._yarn_vbo = _Stream(ctx)
        self._far_vbo = _Stream(ctx)
        """Far weight of each yarn vertex in the blend band (YarnMesh.far)."""
        self._step_vbo = _Stream(ctx)
        """Ribbons: the straight-step data of each yarn vertex (YarnMesh.steps, fraytool.render.ribbon)."""
        self._surface_vbo = _Stream(ctx)
        self._surface_ibo = _Stream(ctx)
        self._surface_shadow_ibo = _Stream(ctx)
        self._surface_vao: Optional[tuple] = None
        self._shadow_vbo = _Stream(ctx)
        """Ribbons: the strips turned to the key light, for the shadow pass (fraytool.render.ribbon)."""
        self._opaque_ibo = _Stream(ctx)
        self._shadow_ibo = _Stream(ctx)
        self._translucent_ibo = _Stream(ctx)
        self._line_vbo = _Stream(ctx)
        self._yarn_vaos: dict[str, tuple[int, moderngl.VertexArray]] = {}
        self._line_vao: Optional[tuple[int, moderngl.VertexArray]] = None
        self._opaque_uploaded: Optional[np.ndarray] = None

        self._set_uniforms(render)
        self.bodies = BodySet(topology, plane_half_size_m=self._scene_scale(topology) * 20.0,
                              ground=self._ground())
        check_gl_error(ctx, "renderer set-up")

    def _make_framebuffers(self, ctx: moderngl.Context, depth: bool) -> None:
        """The multisampled framebuffer at the drawn size, its resolve target, and with supersampling the
        output-sized target of the downsample pass."""
        W, H = self.draw_size
        k = self.supersample
        self._color_ms = self._resolved = self._depth_ms = self._fbo_ms = self._depth_out = self._fbo_out = None
        self._down = self._fbo_down = self._down_prog = self._down_vao = None
        if self._drawn == "float":
            self._color_ms = ctx.texture((W, H), 4, samples=self.samples, dtype="f4")
            self._resolved = ctx.texture((W, H), 4, dtype="f4")
        else:
            self._color_ms = ctx.texture((W, H), 4, samples=self.samples, internal_format=GL_SRGB8_ALPHA8)
            self._resolved = ctx.texture((W, H), 4, internal_format=GL_SRGB8_ALPHA8)
        self._depth_ms = ctx.depth_renderbuffer((W, H), samples=self.samples)
        self._fbo_ms = ctx.framebuffer(color_attachments=[self._color_ms], depth_attachment=self._depth_ms)
        # with a depth attachment here, the resolve blit copies depth too
        self._depth_out = ctx.depth_texture((W, H)) if depth else None
        self._fbo_out = ctx.framebuffer(color_attachments=[self._resolved], depth_attachment=self._depth_out)
        if k > 1:  # supersampling: the resolved image's k x k blocks averaged into the output (_downsample)
            self._down = (ctx.texture(self.size, 4, dtype="f4") if self.target == "float" else
                          ctx.texture(self.size, 4, internal_format=GL_SRGB8_ALPHA8))
            self._fbo_down = ctx.framebuffer(color_attachments=[self._down])
            self._down_prog = load_program(ctx, "downsample.vert", "downsample.frag")
            self._down_prog["u_source"].value = DOWNSAMPLE_UNIT
            self._down_prog["u_factor"].value = k
            self._down_vao = ctx.vertex_array(self._down_prog, [])
        self._fbo_read = self._fbo_down if k > 1 else self._fbo_out
        """Where the output image is read from."""

    def _release_framebuffers(self) -> None:
        for name in ("_down_vao", "_down_prog", "_fbo_down", "_down", "_fbo_out", "_depth_out", "_fbo_ms", "_depth_ms",
                     "_resolved", "_color_ms"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.release()
            setattr(self, name, None)

    @property
    def shaded_width(self) -> int:
        """Width [drawn px] of the shaded view (the whole image, or its left panel beside the wireframe)."""
        return next((p.width for p in self.panels if p.view == "shaded"), self.draw_size[0])

    def geometry_builder(self, topology: Mapping[str, np.ndarray]) -> GeometryBuilder:
        """The frames' geometry for this renderer: its camera, its drawn height and shaded width (the level of
        detail's pixels) and the render table's yarn style."""
        return GeometryBuilder(topology, YarnStyle.from_spec(self.render_spec, topology), self.camera, self.draw_height,
                               image_width=self.shaded_width)

    @property
    def draw_height(self) -> int:
        """Height [drawn px] of the image: the output's times [render] supersample (GeometryBuilder's
        image height, which the level of detail measures yarns against)."""
        return self.draw_size[1]

    # -- set-up -------------------------------------------------------------------------------
    def _scene_scale(self, topology: Mapping[str, np.ndarray]) -> float:
        rest = np.asarray(topology.get("crossing_rest_position_m", np.zeros((1, 3))))
        extent = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))) if len(rest) else 0.0
        poses = [self.camera] + [self.camera.at(t) for t in key_times_s(self.camera.keyed)]  # a moving camera's keys
        return max(extent, *(float(np.linalg.norm(c.target - c.eye)) for c in poses), 1e-3)

    def _ground(self) -> Optional[tuple[np.ndarray, float]]:
        if not self.render_spec.ground_plane:
            return None
        up = np.asarray(self.camera.spec.up, dtype=np.float64)
        return up / np.linalg.norm(up), float(self.render_spec.ground_height_m)

    def _set_uniforms(self, r: RenderSpec) -> None:
        light = np.asarray(r.light_direction, dtype=np.float64)
        light = light / (np.linalg.norm(light) or 1.0)
        self._light_dir = light
        eye = self.camera.eye
        common = {"u_eye": eye, "u_light_dir": light, "u_light_intensity": r.light_intensity,
                  "u_ambient": r.ambient}
        if r.fill_intensity > 0:
            fill = np.asarray(r.fill_direction, dtype=np.float64)
            common.update(u_fill_intensity=r.fill_intensity, u_fill_dir=fill / np.linalg.norm(fill))
        far = (self._far_prog,) if self._far_prog is not None else ()
        for prog in (*self._yarn_progs, *far, self._body_prog, *self._ground_progs, self._line_prog):
            if "u_encode" in prog:
                prog["u_encode"].value = 1.0
        for prog in (*self._yarn_progs, *far, self._body_prog, *self._ground_progs):
            for k, v in common.items():
                if k in prog:
                    prog[k].value = tuple(np.atleast_1d(v).tolist()) if np.ndim(v) else float(v)
        radius = r.yarn_radius_m if r.yarn_radius_m > 0 else 0.5 * self._thickness_m
        for y in (*self._yarn_progs, *far):
            if "u_yarn_radius" in y:
                y["u_yarn_radius"].value = float(radius)
            y["u_specular"].value = r.specular
            y["u_shininess"].value = r.shininess
            y["u_kajiya_weight"].value = KAJIYA_WEIGHT
            y["u_yarn_colors"].write(srgb_to_linear(self.palette).astype("f4").tobytes())
        if far:
            f = self._far_prog
            f["u_weave"].value = WEAVE_UNIT
            f["u_visibility"].value = VISIBILITY_UNIT
            f["u_visibility_rows"].value = float(self._visibility.height)
            f["u_visibility_columns"].value = float(self._visibility.width)
            f["u_weave_period"].value = self._weave_period
            f["u_layers"].value = int(len(self._mean_cover))
            means = np.ones((MAX_WEAVE_LAYERS, 4), dtype="f4")
            means[:len(self._mean_cover)] = self._mean_cover
            f["u_mean_cover"].write(means.tobytes())
            f["u_yarn_diameter_m"].value = 2.0 * float(radius)
            if "u_yarn_top_m" in f:
                f["u_yarn_top_m"].value = float(radius) + 0.5 * self._thickness_m
            spacing = float(np.asarray(self._topology_spacing).item())
            f["u_undulation"].value = float(np.pi * self._thickness_m / (2.0 * spacing)) if spacing > 0 else 0.0
        self._body_prog["u_color"].value = tuple(srgb_to_linear(r.body_color))
        self._background = tuple(srgb_to_linear(r.background))
        stored = linear_to_srgb(self._background) if self._drawn == "srgb8" else np.asarray(self._background)
        self._clear = (0.0, 0.0, 0.0, 0.0) if self.alpha else (*stored.tolist(), 1.0)
        self._line_prog["u_base_color"].value = tuple(srgb_to_linear(WIREFRAME_BASE_SRGB))
        self._line_prog["u_yarn_color"].value = tuple(srgb_to_linear(WIREFRAME_YARN_SRGB))

    def _ensure_far_field(self) -> None:
        """The far field's programs (the surface, and the yarns of the blend band) and textures, once."""
        if self._far_prog is not None or not self.far_field:
            return
        ctx, render = self.ctx, self.render_spec
        yarn_features, features = self._far_features
        self._yarn_band_prog = load_program(ctx, "yarn.vert", "yarn.frag", yarn_features + ("FAR_BAND",))
        self._far_prog = load_program(ctx, "farfield.vert", "farfield.frag",
                                      features + ("FAR_BAND",) + (("SHADOW_ONE_TAP",) if render.shadows else ()))
        self._weave, self._mean_cover, self._weave_period, self._visibility = \
            self._weave_textures(ctx, render, self._far_topology)
        self._yarn_progs = (self._yarn_prog, self._yarn_band_prog)
        if self.shadow is not None:
            self.shadow.surface_program = load_program(ctx, "depth.vert", "depth.frag", ("SURFACE",))
        self._set_uniforms(render)

    def _weave_textures(self, ctx: moderngl.Context, r: RenderSpec, topology: Mapping[str, np.ndarray]):
        """The far field's textures, one layer per panel (fraytool.render.weave_texture.weave_tiles), each
        RGBA: weft and warp seen from the front, then from the back (where the other yarn is on top):
        the mipmapped weave coverage (fraytool.render.weave_texture), and the view table
        (fraytool.render.weave_visibility) scaled to agree with the coverage straight above, family by
        family. Returns (coverage array, mean coverage per layer (P, 4), repeat (i, j), view table array)."""
        radius = r.yarn_radius_m if r.yarn_radius_m > 0 else 0.5 * self._thickness_m
        spacing = float(np.asarray(topology.get("spacing_m", 1.0)).item())
        tiles = weave_tiles(topology)
        if tiles is None:  # YarnStyle builds no surface for such a cloth; a style made by hand may
            tiles = np.array([[[True, False], [False, True]]])   # (it is drawn with plain coverage)
        tiles = tiles[:MAX_WEAVE_LAYERS]
        cover = 2.0 * radius / spacing
        texels = texels_per_crossing(tiles.shape[1:])
        data = np.stack([np.concatenate([coverage_tile(t, cover, texels), coverage_tile(~t, cover, texels)], axis=-1)
                         for t in tiles])
        py, px = tiles.shape[1:]
        tex = ctx.texture_array((data.shape[2], data.shape[1], data.shape[0]), 4, np.ascontiguousarray(data).tobytes())
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        tex.anisotropy = 1.0  # trilinear: 16x anisotropic filtering tripled the surface's cost on llvmpipe
        tex.repeat_x = tex.repeat_y = True
        mean = np.maximum(data.reshape(len(tiles), -1, 4).mean(axis=1) / 255.0, 1e-6)      # (P, 4)
        layers = []
        for t, m in zip(tiles, mean):
            sides = [view_tables(side, radius, spacing, self._thickness_m) for side in (t, ~t)]
            table = np.concatenate([shares for shares, _ in sides], axis=-1)                  # (E, A, 4)
            layers.append(table * (m / np.maximum(table[-1].mean(axis=0), 1e-6)))
            for _, normals in sides:                          # (E, A, 2, 2, bins): share, along; weft, warp
                for family in range(2):
                    layers += [normals[:, :, part, family, q:q + 4] for part in range(2)
                               for q in range(0, NORMAL_BINS, 4)]
        table = np.ascontiguousarray(np.stack(layers), dtype="f4")      # (P x VISIBILITY_LAYERS, E, A, 4)
        vis = ctx.texture_array((table.shape[2], table.shape[1], table.shape[0]), 4, table.tobytes(), dtype="f4")
        vis.filter = (moderngl.LINEAR, moderngl.LINEAR)
        vis.repeat_x = True                              # azimuth: a view and its opposite are alike
        vis.repeat_y = False
        return tex, mean, (float(px), float(py)), vis

    # -- per frame ----------------------------------------------------------------------------
    def _upload_yarns(self, geom: FrameGeometry) -> None:
        mesh = geom.yarns
        self._yarn_vbo.write(mesh.vertices)
        if mesh.far is not None:
            self._far_vbo.write(mesh.far)
        if self.ribbons:  # no straight step: zeros (the shaders then blend the two ends alone)
            self._step_vbo.write(mesh.steps if mesh.steps is not None
                                 else np.zeros((len(mesh.vertices), STEP_FLOATS), np.float32))
        if mesh.opaque is not self._opaque_uploaded:
            self._opaque_ibo.write(mesh.opaque)
            self._opaque_uploaded = mesh.opaque

    def _yarn_vao(self, which: str, ibo: _Stream, band: bool = False) -> moderngl.VertexArray:
        """The yarn vertices with `ibo`; `band`: through the blend band's program, with the far weights."""
        key = (self._yarn_vbo.generation, ibo.generation, self._step_vbo.generation) + \
            ((self._far_vbo.generation,) if band else ())
        which = which + ("_band" if band else "")
        have = self._yarn_vaos.get(which)
        if have is None or have[0] != key:
            if have is not None:
                have[1].release()
            content = [(self._yarn_vbo.buffer, "3f 3f 3f 1f 1f", "in_position", "in_normal", "in_tangent",
                        "in_alpha", "in_warp")]
            if self.ribbons:
                content.append((self._step_vbo.buffer, "3f 3f 1f", "in_step_start", "in_step_middle", "in_step"))
            if band:
                content.append((self._far_vbo.buffer, "1f", "in_far"))
            vao = self.ctx.vertex_array(self._yarn_band_prog if band else self._yarn_prog, content, ibo.buffer, 4)
            self._yarn_vaos[which] = (key, vao)
        return self._yarn_vaos[which][1]

    def _draw_bodies(self, geom: FrameGeometry, view_proj: bytes) -> None:
        self._body_prog["u_view_proj"].write(view_proj)
        for d in self.bodies.draws(geom.body_position_m, geom.body_rotation):
            self._body_prog["u_model"].write(gl_matrix_bytes(d.model))
            self._body_prog["u_normal_matrix"].write(gl_matrix_bytes(d.normal_matrix))
            self._body_vaos[d.mesh][0].render(moderngl.TRIANGLES)

    def _ground_distance_m(self) -> float:
        """A moving camera's largest eye-to-target distance over its key poses (and time 0): one checker cell
        for the whole shot."""
        if self._ground_distance is None:
            poses = [self.camera.at(0.0)] + [self.camera.at(t) for t in key_times_s(self.camera.keyed)]
            self._ground_distance = max(float(np.linalg.norm(c.target - c.eye)) for c in poses)
        return self._ground_distance

    def _draw_ground(self, view_proj: bytes) -> None:
        """The ground plane, out to where it has faded into the background (beyond, the clear colour
        is the same picture). With shadows it is drawn in two parts: the footprint of the key
        light's box on the plane (every ground point that can be in shadow: fraytool.render.shadow)
        with the shadow lookups, then the whole plane without them, pushed back by a polygon offset
        so that it fails the depth test where the footprint was drawn. Outside the footprint a lookup
        reads cleared depth and gives full light, so both parts shade alike there; the lookups,
        about a third of the ground's cost on llvmpipe, are paid only where a shadow can fall. The
        offset also moves the depth the lit part stores, so a renderer that keeps the depth (EXR Z)
        draws the ground in one shadowed piece."""
        ground = self._ground()
        if ground is None:
            return
        up, height = ground
        Rg = rotation_from_y(up)
        dist = float(np.linalg.norm(self.camera.target - self.camera.eye))
        fade_radius_m = 4.0 * dist
        moving = is_animated(self.camera.keyed)
        centre, cell = ground_checker(self.camera, up, height, self._ground_distance_m() if moving else None)
        uniforms = {"u_view_proj": view_proj,
                    "u_color": tuple(srgb_to_linear(self.render_spec.body_color) * 0.8),
                    "u_background": self._background, "u_alpha_out": 1.0 if self.alpha else 0.0,
                    "u_centre": tuple(centre), "u_axis_u": tuple(Rg[:, 0]), "u_axis_v": tuple(Rg[:, 2]),
                    "u_cell": cell, "u_fade_radius": fade_radius_m}
        size = min(self.bodies.plane_half_size_m, fade_radius_m)
        plane = np.eye(4)
        plane[:3, :3] = Rg @ np.diag([size, 1.0, size])
        plane[:3, 3] = centre
        # Split only where the depth is not kept: the offset moves the depth the lit part stores, and
        # the EXR's Z must be the plane's (read_depth_m).
        split = self._ground_lit_vao is not None and self._depth_out is None
        footprint = shadow_footprint(self._light, up, height) if split else None
        if footprint is None:  # no shadows, nothing casts, the light grazes the plane, or depth kept: one draw
            if self._ground_lit_vao is not None and self._light is None:
                self._ground_quad(self._ground_lit_prog, self._ground_lit_vao, plane, uniforms)
            else:
                self._ground_quad(self._ground_prog, self._body_vaos["quad"][1], plane, uniforms)
            return
        self._ground_quad(self._ground_prog, self._body_vaos["quad"][1], footprint, uniforms)
        self.ctx.polygon_offset = GROUND_OFFSET
        self._ground_quad(self._ground_lit_prog, self._ground_lit_vao, plane, uniforms)
        self.ctx.polygon_offset = (0.0, 0.0)

    @staticmethod
    def _ground_quad(prog: moderngl.Program, vao: moderngl.VertexArray, model: np.ndarray, uniforms: dict) -> None:
        """Draw the unit quad placed by `model` (its normal matrix makes the quad's +y the plane's up)."""
        for name, value in uniforms.items():
            if isinstance(value, bytes):
                prog[name].write(value)
            else:
                prog[name].value = value
        prog["u_model"].write(gl_matrix_bytes(model))
        prog["u_normal_matrix"].write(gl_matrix_bytes(np.linalg.inv(model[:3, :3]).T))
        vao.render(moderngl.TRIANGLES)

    def _draw_shaded(self, geom: FrameGeometry, view_proj: bytes) -> None:
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST)
        # Opaque yarns first, then bodies, then the ground: the same pixels in any order (depth test,
        # no blending), but the ground and bodies behind the cloth then fail the depth test before
        # their shading (shadow lookups included) instead of being shaded and overdrawn.
        mesh = geom.yarns
        have_yarns = mesh is not None and len(mesh.vertices) > 0
        band = have_yarns and mesh.far is not None and self._yarn_band_prog is not None
        if have_yarns:
            for prog in self._yarn_progs:
                prog["u_view_proj"].write(view_proj)
        cull = not self.ribbons  # a strip has no back faces to cull, and its winding is not kept
        if have_yarns and len(mesh.opaque):
            if cull:
                ctx.enable(moderngl.CULL_FACE)
            with self._part("yarns"):
                self._yarn_vao("opaque", self._opaque_ibo, band=band).render(moderngl.TRIANGLES,
                                                                             vertices=mesh.opaque.size)
        ctx.disable(moderngl.CULL_FACE)
        with self._part("bodies"):
            self._draw_bodies(geom, view_proj)
        with self._part("ground"):
            self._draw_ground(view_proj)
        if geom.surface is not None and self._far_prog is not None:
            with self._part("far_field"):
                self._draw_surface(geom, view_proj)
        if not have_yarns:
            return
        if cull:
            ctx.enable(moderngl.CULL_FACE)
        if len(mesh.translucent):
            order = np.argsort(self.camera.view_depth(mesh.centroid), kind="stable")  # far first
            self._translucent_ibo.write(mesh.translucent[order])
            # colour: over (premultiplied result); alpha: coverage a + a_dst (1 - a); in linear light
            # (GL decodes the 8-bit target, blends and encodes: a few pixels)
            restore = self._blend_linear()
            self._fbo_ms.depth_mask = False
            try:
                with self._part("yarns"):
                    self._yarn_vao("translucent", self._translucent_ibo).render(
                        moderngl.TRIANGLES, vertices=mesh.translucent.size)
            finally:
                self._fbo_ms.depth_mask = True
                restore()
        ctx.disable(moderngl.CULL_FACE)

    def _blend_linear(self):
        """Alpha blending in linear light for the next draws: colour over, alpha a + a_dst (1 - a); the
        8-bit target is decoded, blended and encoded by GL (GL_FRAMEBUFFER_SRGB), the shaders' own
        encoding off. Returns the function that restores the state."""
        ctx = self.ctx
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = (moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA, moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA)
        encoded = self._drawn == "srgb8"
        progs = (self._yarn_prog,) + ((self._far_prog,) if self._far_prog is not None else ())
        if encoded:
            for prog in progs:
                prog["u_encode"].value = 0.0
            ctx.enable_direct(GL_FRAMEBUFFER_SRGB)

        def restore():
            if encoded:
                ctx.disable_direct(GL_FRAMEBUFFER_SRGB)
                for prog in progs:
                    prog["u_encode"].value = 1.0
            ctx.disable(moderngl.BLEND)
        return restore

    def _surface_vertex_array(self) -> moderngl.VertexArray:
        key = (self._surface_vbo.generation, self._surface_ibo.generation)
        if self._surface_vao is None or self._surface_vao[0] != key:
            if self._surface_vao is not None:
                self._surface_vao[1].release()
            vao = self.ctx.vertex_array(
                self._far_prog,
                [(self._surface_vbo.buffer, "3f 3f 3f 3f 2f 1f 1f", "in_position", "in_normal", "in_weft_edge",
                  "in_warp_edge", "in_grid", "in_far", "in_panel")],
                self._surface_ibo.buffer, 4)
            self._surface_vao = (key, vao)
        return self._surface_vao[1]

    def _draw_surface(self, geom: FrameGeometry, view_proj: bytes) -> None:
        """The far-field surface (fraytool.render.farfield), blended over what is behind it (its alpha
        is the weave's coverage), both sides, writing depth (EXR Z is the surface's)."""
        prog = self._far_prog
        prog["u_view_proj"].write(view_proj)
        self._weave.use(location=WEAVE_UNIT)
        self._visibility.use(location=VISIBILITY_UNIT)
        restore = self._blend_linear()
        try:
            self._surface_vertex_array().render(moderngl.TRIANGLES, vertices=geom.surface.shown.size)
        finally:
            restore()

    def _draw_wireframe(self, geom: FrameGeometry, view_proj: bytes) -> None:
        ctx = self.ctx
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        self._draw_bodies(geom, view_proj)
        lines = geom.lines
        if lines is None or lines.count == 0:
            return
        self._line_vbo.write(lines.vertices)
        if self._line_vao is None or self._line_vao[0] != self._line_vbo.generation:
            if self._line_vao is not None:
                self._line_vao[1].release()
            vao = ctx.vertex_array(self._line_prog, [(self._line_vbo.buffer, "3f 1f", "in_position",
                                                      "in_yarn_level")])
            self._line_vao = (self._line_vbo.generation, vao)
        self._line_prog["u_view_proj"].write(view_proj)
        # supersampled, lines k drawn pixels wide: one output pixel, as without (as wide as the GL draws them)
        widest = float(np.max(self.ctx.info.get("GL_ALIASED_LINE_WIDTH_RANGE", (1.0, 1.0))))
        ctx.line_width = min(float(self.supersample), widest)
        try:
            self._line_vao[1].render(moderngl.LINES, vertices=2 * lines.count)
        finally:
            ctx.line_width = 1.0

    def _draw_shadow_map(self, geom: FrameGeometry) -> None:
        """Render the key light's depth map of this frame and hand it to the shaded programs."""
        mesh = geom.yarns
        have_yarns = mesh is not None and len(mesh.opaque) > 0
        casters = self._yarn_vbo if have_yarns else None
        positions = mesh.vertices[:, :3] if have_yarns else None
        triangles, count, packed = self._opaque_ibo, mesh.opaque.size if have_yarns else 0, False
        if have_yarns and mesh.shadow_positions is not None:  # ribbons: the strips turned to the light
            self._shadow_vbo.write(mesh.shadow_positions)
            self._shadow_ibo.write(mesh.shadow_triangles)
            casters, positions, packed = self._shadow_vbo, mesh.shadow_positions, True
            triangles, count = self._shadow_ibo, mesh.shadow_triangles.size
        surface = None
        if geom.surface is not None and self._far_prog is not None:  # the far field casts as one sheet
            surface = (self._surface_vbo, self._surface_shadow_ibo, geom.surface.triangles.size, SURFACE_FLOATS)
            sheet = geom.surface.vertices[geom.surface.used, :3]
            positions = sheet if positions is None else (positions, sheet)  # bounded together, not joined
        light = self._light = self.shadow.draw(self._light_dir, positions, casters, triangles if have_yarns else None,
                                               count, self.bodies, geom, packed=packed, surface=surface)
        for prog in (*self._yarn_progs, self._body_prog, self._ground_prog) + (
                (self._far_prog,) if self._far_prog is not None else ()):
            self.shadow.bind(prog, light)

    @contextmanager
    def _part(self, name: str):
        """With ``part_s`` a dict (fraytool bench --render), time this part of the draw to completion
        into ``part_s[name]`` (the GL queue is finished before and after it); otherwise nothing."""
        if self.part_s is None:
            yield
            return
        self.ctx.finish()
        t0 = time.perf_counter()
        yield
        self.ctx.finish()
        self.part_s[name] = self.part_s.get(name, 0.0) + time.perf_counter() - t0

    def _pose_meshes(self, time_s: float) -> None:
        """Animated mesh bodies' vertices at the frame's time."""
        if not self._animated_meshes or self._mesh_time_s == time_s:
            return
        for m, vbo in self._animated_meshes:
            vbo.write(mesh_draw_vertices(self._meshes.vertices_at(m, time_s), self._meshes.local_triangles(m)).tobytes())
        self._mesh_time_s = time_s

    def _follow_camera(self, time_s: float) -> None:
        """A moving camera ([camera] keys) to its pose at the frame's time, and the shaders' eye with it; a
        static camera stays as it is (the same uniforms: the same pixels as before cameras moved)."""
        camera = self.camera.at(time_s)
        if camera is self.camera:
            return
        self.camera = camera
        far = (self._far_prog,) if self._far_prog is not None else ()
        for prog in (*self._yarn_progs, *far, self._body_prog, *self._ground_progs):
            if "u_eye" in prog:
                prog["u_eye"].value = tuple(float(v) for v in camera.eye)

    def draw(self, geom: FrameGeometry) -> None:
        """Draw one frame into the multisampled framebuffer and resolve it (no read-back), with the camera of
        the frame's time."""
        W, H = self.draw_size
        self._follow_camera(geom.time_s)
        if geom.surface is not None or (geom.yarns is not None and geom.yarns.far is not None):
            self._ensure_far_field()
        self._fbo_ms.use()
        self._pose_meshes(geom.time_s)
        if geom.yarns is not None:
            self._upload_yarns(geom)
        if geom.surface is not None and self._far_prog is not None:
            self._surface_vbo.write(geom.surface.vertices)
            self._surface_ibo.write(geom.surface.shown)
            if self.shadow is not None:
                self._surface_shadow_ibo.write(geom.surface.triangles)
        if self.shadow is not None:
            with self._part("shadow_map"):
                self._draw_shadow_map(geom)
            self._fbo_ms.use()
        if len(self.panels) == 1:
            self._fbo_ms.clear(*self._clear, depth=1.0)
        # Panels are cleared and drawn one at a time inside their scissor box, wireframe first:
        # llvmpipe lets multisampled lines leak one pixel past the scissor edge, and the shaded
        # panel's own clear then wipes that leak.
        for p in sorted(self.panels, key=lambda p: p.view != "wireframe"):
            box = (p.x, 0, p.width, H)
            if len(self.panels) > 1:
                self._fbo_ms.clear(*self._clear, depth=1.0, viewport=box)
            self._fbo_ms.viewport = box
            self._fbo_ms.scissor = box
            self._fbo_ms.use()                             # applies viewport and scissor
            vp = gl_matrix_bytes(self.camera.view_proj(p.width / H))
            if p.view == "shaded":
                self._draw_shaded(geom, vp)
            else:
                self._draw_wireframe(geom, vp)
        self._fbo_ms.viewport = (0, 0, W, H)
        self._fbo_ms.scissor = None
        with self._part("resolve"):
            self.ctx.enable_direct(GL_FRAMEBUFFER_SRGB)     # decode, average in linear light, encode
            self.ctx.copy_framebuffer(self._fbo_out, self._fbo_ms)
            self.ctx.disable_direct(GL_FRAMEBUFFER_SRGB)    # leave the context as we found it
        if self._fbo_down is not None:
            with self._part("downsample"):
                self._downsample()

    def _downsample(self) -> None:
        """The output image from the resolved one: each pixel the mean of its k x k drawn pixels in linear
        light (shaders/downsample.frag; GL encodes the 8-bit target's mean on the write)."""
        ctx = self.ctx
        ctx.disable(moderngl.DEPTH_TEST | moderngl.BLEND | moderngl.CULL_FACE)
        self._fbo_down.viewport = (0, 0, *self.size)
        self._fbo_down.use()
        self._resolved.use(location=DOWNSAMPLE_UNIT)
        if self.target == "srgb8":
            ctx.enable_direct(GL_FRAMEBUFFER_SRGB)
        self._down_vao.render(moderngl.TRIANGLES, vertices=3)
        if self.target == "srgb8":
            ctx.disable_direct(GL_FRAMEBUFFER_SRGB)

    def read(self) -> np.ndarray:
        """The presented image, top row first: (H, W, 3) uint8 sRGB, or with `alpha` (H, W, 4) uint8
        straight (unassociated) alpha with sRGB colour, as PNG stores it."""
        if self.target == "float":
            return encode_premultiplied_linear(self.read_linear(), 8, self.alpha)
        W, H = self.size
        n = 4 if self.alpha else 3
        raw = self._fbo_read.read(components=n, alignment=1)
        check_gl_error(self.ctx, "drawing a frame")
        image = np.frombuffer(raw, dtype=np.uint8).reshape(H, W, n)[::-1]
        return straight_alpha_srgb(image) if self.alpha else image

    def read_linear(self) -> np.ndarray:
        """The float target's image, top row first: (H, W, 4) float32 linear RGB premultiplied by
        alpha, and alpha (1 everywhere without `alpha`)."""
        if self.target != "float":
            raise ValueError("read_linear() needs a renderer made with target='float'")
        W, H = self.size
        raw = self._fbo_read.read(components=4, dtype="f4", alignment=1)
        check_gl_error(self.ctx, "drawing a frame")
        return np.frombuffer(raw, dtype=np.float32).reshape(H, W, 4)[::-1]

    def read_depth_m(self) -> np.ndarray:
        """Distance along the view axis [m] of what each pixel shows, top row first, (H, W) float32;
        +inf where nothing was drawn. Supersampled, the nearest of each pixel's k x k drawn depths (as MSAA's
        resolve keeps one sample's, a depth is never averaged across an edge)."""
        if self._depth_out is None:
            raise ValueError("read_depth_m() needs a renderer made with depth=True")
        W, H = self.draw_size
        raw = self._depth_out.read(alignment=1)
        check_gl_error(self.ctx, "reading the depth")
        depth = np.frombuffer(raw, dtype=np.float32).reshape(H, W)[::-1]
        k = self.supersample
        if k > 1:
            depth = depth.reshape(H // k, k, W // k, k).min(axis=(1, 3))
        return self.camera.view_distance(depth)

    def render(self, geom: FrameGeometry) -> np.ndarray:
        """Draw, resolve, present and read back one frame: (H, W, 3) uint8, top row first."""
        self.draw(geom)
        return self.read()

    def release(self) -> None:
        # Unbind our framebuffers first: moderngl re-binds "the current framebuffer" when it makes
        # new ones, and a released one there would be GL_INVALID_OPERATION for the next renderer.
        self.ctx.detect_framebuffer(0).use()
        for _, vao in self._yarn_vaos.values():
            vao.release()
        if self._line_vao is not None:
            self._line_vao[1].release()
        for vaos in self._body_vaos.values():
            for vao in vaos:
                vao.release()
        if self._ground_lit_vao is not None:
            self._ground_lit_vao.release()
            self._ground_lit_prog.release()
        for s in (self._yarn_vbo, self._shadow_vbo, self._shadow_ibo, self._opaque_ibo, self._translucent_ibo,
                  self._line_vbo, self._far_vbo, self._step_vbo, self._surface_vbo, self._surface_ibo,
                  self._surface_shadow_ibo):
            s.release()
        if self._surface_vao is not None:
            self._surface_vao[1].release()
        for obj in (self._yarn_band_prog, self._far_prog, self._weave, self._visibility):
            if obj is not None:
                obj.release()
        if self.shadow is not None:
            self.shadow.release()
        for obj in (*self._static, self._yarn_prog, self._body_prog, self._ground_prog, self._line_prog):
            obj.release()
        self._release_framebuffers()


def _drawn_size_text(size: tuple[int, int], supersample: int, wireframe: str) -> str:
    W, H = size
    views = 2 if wireframe == "beside" else 1
    text = f"[render] resolution = [{W // views}, {H}]" + (" with the wireframe beside" if views > 1 else "")
    if supersample > 1:
        text += f" and supersample = {supersample}"
    return text + f" draws {W * supersample}x{H * supersample} pixels"


def gl_size_limit(ctx: moderngl.Context) -> int:
    """The widest side [px] the context draws into (GL_MAX_TEXTURE_SIZE, GL_MAX_RENDERBUFFER_SIZE; 16384 on llvmpipe)."""
    return min(int(ctx.info.get("GL_MAX_TEXTURE_SIZE", 1 << 30)), int(ctx.info.get("GL_MAX_RENDERBUFFER_SIZE", 1 << 30)))


def check_drawn_size_early(size: tuple[int, int], supersample: int, wireframe: str = "off", where: str = "",
                           limit: Optional[int] = None) -> Optional[int]:
    """check_drawn_size for commands that check input before any drawing (`fraytool check`, `batch`): against
    `limit`, or a context made and released here when None. Returns the limit for the next call (None when no
    GL context can be made: nothing is checked, and the render itself then says why)."""
    if limit is None:
        from fraytool.render.context import create_context

        try:
            ctx = create_context()
        except Exception:  # noqa: BLE001  (no GL here: nothing to compare with; rendering reports it)
            return None
        try:
            limit = gl_size_limit(ctx)
        finally:
            ctx.release()
    problem = drawn_size_problem(size, supersample, wireframe, limit, where)
    if problem:
        raise InputError(problem)
    return limit


def drawn_size_problem(size: tuple[int, int], supersample: int, wireframe: str, most: int, where: str = "") -> Optional[str]:
    """The message when the drawn frame, `size` (the output's, both views beside) times `supersample` in each axis,
    is wider than `most` pixels; None when it fits."""
    if max(size) * supersample <= most:
        return None
    return (f"{where + ': ' if where else ''}{_drawn_size_text(size, supersample, wireframe)}; this GL context draws "
            f"at most {most} a side: lower " + ("supersample or " if supersample > 1 else "") + "the resolution")


def check_drawn_size(ctx: moderngl.Context, size: tuple[int, int], supersample: int, wireframe: str = "off",
                     where: str = "") -> None:
    """InputError (drawn_size_problem) when the drawn frame is larger than the context draws."""
    problem = drawn_size_problem(size, supersample, wireframe, gl_size_limit(ctx), where)
    if problem:
        raise InputError(problem)


def clamp_samples(ctx: moderngl.Context, samples: int) -> int:
    """MSAA samples the context can do: 0 (off) for 0 or 1, else at most ctx.max_samples."""
    s = int(samples)
    if s <= 1:
        return 0
    return min(s, int(ctx.max_samples))


def ground_checker(camera: Camera, up: np.ndarray, height: float,
                   shot_distance_m: Optional[float] = None) -> tuple[np.ndarray, float]:
    """(centre, cell size [m]) of the ground's checker: the target dropped onto the plane, and a round cell about
    a sixth of the eye's distance. A moving camera passes `shot_distance_m` (its largest distance over the shot):
    one cell size for the whole shot, and the centre snapped to a multiple of two cells along the plane's axes, so
    that the squares stay put on the ground as the camera moves (the checker is there to read motion and scale)."""
    centre = camera.target - (camera.target @ up - height) * up
    if shot_distance_m is None:
        return centre, _nice_cell(float(np.linalg.norm(camera.target - camera.eye)) / 6.0)
    cell = _nice_cell(shot_distance_m / 6.0)
    rg = rotation_from_y(up)
    for axis in (rg[:, 0], rg[:, 2]):
        centre = centre - axis * math.remainder(float(centre @ axis), 2.0 * cell)
    return centre, cell


def _nice_cell(x: float) -> float:
    """Round a length to 1, 2 or 5 x a power of ten (checker cells of a readable size)."""
    if x <= 0:
        return 1.0
    e = np.floor(np.log10(x))
    m = x / 10 ** e
    return float((1.0 if m < 1.5 else 2.0 if m < 3.5 else 5.0) * 10 ** e)
