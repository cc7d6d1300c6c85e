"""The GL side of key-light shadows: the depth map, its framebuffer and the depth-only draw of the
casters (opaque yarn triangles, spheres and boxes) into it. The light box is fitted per frame by
fraytool.render.shadow; the yarn, body and ground shaders sample the map (shaders/shadow.glsl).

Translucent (fading) yarn ends cast no shadow: a shadow cannot fade with them in a depth map.
"""
from __future__ import annotations

from typing import Mapping, Optional

import moderngl
import numpy as np

from fraytool.kinds import SHAPE_MESH, SHAPE_SPHERE
from fraytool.render.bodies import BodySet, body_bounding_radii
from fraytool.render.camera import gl_matrix_bytes
from fraytool.render.farfield import SURFACE_FAR_WEIGHT
from fraytool.render.shadow import NORMAL_OFFSET_TEXELS, LightFrame, caster_points, fit_light

SHADOW_UNIT = 0
"""Texture unit of the shadow map (the only texture the shaded programs use)."""
POLYGON_OFFSET = (2.0, 4.0)
"""glPolygonOffset(factor, units) of the depth pass: slope-scaled bias against acne."""


class ShadowPass:
    """One shadow map of `size` x `size` texels, redrawn every frame."""

    def __init__(self, ctx: moderngl.Context, size: int, topology: Mapping[str, np.ndarray],
                 program: moderngl.Program, surface_program: Optional[moderngl.Program] = None):
        """`program`: shaders/depth.vert + depth.frag; `surface_program`: the same with SURFACE, for the
        far-field surface (set by the renderer when it first draws one)."""
        self.ctx = ctx
        self.size = int(size)
        self.program = program
        self.surface_program = surface_program
        self.texture = ctx.depth_texture((self.size, self.size))
        self.texture.compare_func = "<="
        self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.texture.repeat_x = False
        self.texture.repeat_y = False
        self.fbo = ctx.framebuffer(depth_attachment=self.texture)
        shape = np.asarray(topology.get("body_shape", np.zeros(0, np.int8)))
        mesh = shape == SHAPE_MESH  # a mesh casts within its bounding sphere
        self.body_shape = np.where(mesh, SHAPE_SPHERE, shape).astype(np.int8)
        self.body_radius = np.where(mesh, body_bounding_radii(topology),
                                    np.asarray(topology.get("body_radius_m", np.zeros(len(shape)))))
        self.body_half = np.asarray(topology.get("body_half_extents_m", np.zeros((len(self.body_shape), 3))))
        self._body_vaos: dict[str, moderngl.VertexArray] = {}
        self._yarn_vao: Optional[tuple[tuple, moderngl.VertexArray]] = None
        self._surface_vao: Optional[tuple[tuple, moderngl.VertexArray]] = None

    def add_body_mesh(self, name: str, vbo: moderngl.Buffer, ibo: moderngl.Buffer) -> None:
        self._body_vaos[name] = self.ctx.vertex_array(self.program, [(vbo, "3f 12x", "in_position")], ibo, 4)

    def _yarns(self, vbo_stream, ibo_stream, packed: bool) -> moderngl.VertexArray:
        key = (id(vbo_stream), vbo_stream.generation, id(ibo_stream), ibo_stream.generation, packed)
        if self._yarn_vao is None or self._yarn_vao[0] != key:
            if self._yarn_vao is not None:
                self._yarn_vao[1].release()
            layout = "3f" if packed else "3f 32x"  # positions only, or the interleaved yarn vertices
            vao = self.ctx.vertex_array(self.program, [(vbo_stream.buffer, layout, "in_position")],
                                        ibo_stream.buffer, 4)
            self._yarn_vao = (key, vao)
        return self._yarn_vao[1]

    def draw(self, light_dir: np.ndarray, yarn_positions: Optional[np.ndarray | tuple], yarn_vbo, opaque_ibo,
             opaque_count: int, bodies: BodySet, geom, packed: bool = False, surface=None) -> Optional[LightFrame]:
        """Fit the light to this frame's casters and draw them; None when nothing casts. `packed`: the
        yarn buffer holds positions only (ribbons turned to the light), not the interleaved vertices.
        `surface`: (vertex stream, index stream, index count, floats per vertex) of the far-field
        surface (fraytool.render.farfield), which casts as an opaque sheet where its far weight is at
        least a half (shaders/depth.frag); its positions are then
        among `yarn_positions`, a tuple (the yarns', the sheet's) the light is fitted to
        (fraytool.render.shadow.caster_points)."""
        points, radii = caster_points(yarn_positions, self.body_shape, geom.body_position_m,
                                      self.body_radius, self.body_half)
        light = fit_light(light_dir, points, radii, self.size)
        ctx = self.ctx
        self.fbo.use()
        self.fbo.clear(depth=1.0)
        if light is None:
            return None
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        ctx.polygon_offset = POLYGON_OFFSET
        prog = self.program
        prog["u_light_view_proj"].write(gl_matrix_bytes(light.view_proj))
        for d in bodies.draws(geom.body_position_m, geom.body_rotation):
            if d.mesh == "quad":   # planes receive, never cast
                continue
            prog["u_model"].write(gl_matrix_bytes(d.model))
            self._body_vaos[d.mesh].render(moderngl.TRIANGLES)
        if yarn_vbo is not None and opaque_count:
            prog["u_model"].write(gl_matrix_bytes(np.eye(4)))
            self._yarns(yarn_vbo, opaque_ibo, packed).render(moderngl.TRIANGLES, vertices=opaque_count)
        if surface is not None and surface[2]:
            self.surface_program["u_light_view_proj"].write(gl_matrix_bytes(light.view_proj))
            self.surface_program["u_model"].write(gl_matrix_bytes(np.eye(4)))
            self._surface(*surface).render(moderngl.TRIANGLES, vertices=surface[2])
        ctx.polygon_offset = (0.0, 0.0)
        return light

    def _surface(self, vbo_stream, ibo_stream, count: int, floats: int) -> moderngl.VertexArray:
        key = (vbo_stream.generation, ibo_stream.generation)
        if self._surface_vao is None or self._surface_vao[0] != key:
            if self._surface_vao is not None:
                self._surface_vao[1].release()
            layout = f"3f {4 * (SURFACE_FAR_WEIGHT - 3)}x 1f {4 * (floats - SURFACE_FAR_WEIGHT - 1)}x"
            vao = self.ctx.vertex_array(self.surface_program, [(vbo_stream.buffer, layout, "in_position", "in_far")],
                                        ibo_stream.buffer, 4)
            self._surface_vao = (key, vao)
        return self._surface_vao[1]

    def bind(self, prog: moderngl.Program, light: Optional[LightFrame]) -> None:
        """Hand the map and the light's matrix to a shaded program (a frame with no casters gets a
        matrix that maps everything to the far plane: all lit)."""
        self.texture.use(location=SHADOW_UNIT)
        prog["u_shadow_map"].value = SHADOW_UNIT
        if light is None:
            m = np.zeros((4, 4))
            m[3, 3] = 1.0
            m[2, 3] = 1.0
            prog["u_light_view_proj"].write(gl_matrix_bytes(m))
            prog["u_shadow_offset_m"].value = 0.0
        else:
            prog["u_light_view_proj"].write(gl_matrix_bytes(light.view_proj))
            prog["u_shadow_offset_m"].value = NORMAL_OFFSET_TEXELS * light.texel_m
        if "u_shadow_texel" in prog:
            prog["u_shadow_texel"].value = 1.0 / self.size

    def release(self) -> None:
        for vao in self._body_vaos.values():
            vao.release()
        for have in (self._yarn_vao, self._surface_vao):
            if have is not None:
                have[1].release()
        for obj in (self.fbo, self.texture, self.program, self.surface_program):
            if obj is not None:
                obj.release()
