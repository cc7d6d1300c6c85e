"""One rigid body as the builder adds it, and the Model's body and mesh arrays from all of them.

`lay_out_body` works out, when a body is added, what the Model and the attachments need of it: its
orientation keys (unit, sign-consistent: fraytool.sim.paths), its rotation and position at the first
frame, a plane's unit normal, and for a mesh its asset and bounding radius. `body_fields` concatenates the
bodies into the Model's arrays (fraytool.sim.model.Model, body_* and mesh_*)."""
from __future__ import annotations

import dataclasses
from typing import Any, Optional, Sequence

import numpy as np

from fraytool.geometry.rotations import euler_rotation, quat_to_matrix
from fraytool.kinds import MOTION_NAMES, SHAPE_NAMES
from fraytool.scene.spec import BodySpec
from fraytool.sim.paths import orientation_keys


@dataclasses.dataclass(frozen=True, eq=False)
class BodyLayout:
    spec: BodySpec
    orientation_keys: np.ndarray  # (K, 5) t, w, x, y, z; (0, 5) for a body that does not turn
    rotation: np.ndarray  # (3, 3) body to world at the first frame
    initial_position_m: np.ndarray  # (3,)
    unit_normal: np.ndarray  # (3,) a plane's free side
    mesh: Optional[Any] = None  # fraytool.scene.mesh_files.MeshAsset
    mesh_radius_m: float = 0.0  # the mesh's bounding radius about the body's centre over all its keys


def unit(v) -> np.ndarray:
    """v / |v|, scaled by its largest component first so that neither a huge vector (|v|^2 overflows
    to inf, v / |v| to 0) nor a tiny one (|v|^2 underflows to 0) loses its direction."""
    v = np.asarray(v, float)
    v = v / np.abs(v).max()
    return v / np.linalg.norm(v)


def lay_out_body(body: BodySpec, mesh=None) -> BodyLayout:
    if body.path_rotation_deg:
        keys = orientation_keys(body.path_rotation_deg, euler_deg=True)
    elif body.path_quaternion:
        keys = orientation_keys(body.path_quaternion, euler_deg=False)
    else:
        keys = np.zeros((0, 5))
    rotation = euler_rotation(body.rotation_deg) if not len(keys) else quat_to_matrix(keys[0, 1:])
    position = np.array(body.path[0][1:] if body.motion == "kinematic" and body.path else body.position_m, float)
    radius = 0.0
    if mesh is not None:
        scaled = mesh.key_vertices * np.asarray(body.scale, float)
        radius = max(float(np.linalg.norm(scaled[k], axis=1).max()) for k in range(scaled.shape[0]))
    return BodyLayout(body, keys, np.asarray(rotation, float), position, unit(body.normal), mesh, radius)


def body_fields(bodies: Sequence[BodyLayout]) -> dict[str, Any]:
    """The Model's body_* fields and mesh arrays (fraytool.meshes) of the bodies, in the order added."""
    mesh_arrays = _mesh_arrays(bodies)
    params, m = [], 0
    for b in bodies:
        s = b.spec
        if s.shape == "sphere":
            params.append((s.radius_m, 0.0, 0.0))
        elif s.shape == "box":
            params.append(tuple(s.half_extents_m))
        elif s.shape == "mesh":
            params.append((b.mesh_radius_m, float(mesh_arrays["mesh_closed"][m]), float(m)))
            m += 1
        else:
            params.append(tuple(b.unit_normal))
    specs = [b.spec for b in bodies]
    return dict(
        body_names=tuple(s.name for s in specs),
        body_shape=np.array([SHAPE_NAMES.index(s.shape) for s in specs], np.int8),
        body_motion=np.array([MOTION_NAMES.index(s.motion) for s in specs], np.int8),
        body_params=np.array(params, float).reshape(-1, 3),
        body_rotation=np.array([b.rotation for b in bodies]).reshape(-1, 3, 3),
        body_mass_kg=np.array([s.mass_kg for s in specs], float),
        body_gravity=np.array([s.gravity for s in specs], bool),
        body_friction=np.array([s.friction for s in specs], float),
        body_collide=np.array([s.collide for s in specs], bool),
        body_start_s=np.array([s.start_s for s in specs], float),
        body_initial_position_m=np.array([b.initial_position_m for b in bodies], float).reshape(-1, 3),
        body_initial_velocity_m_s=np.array([s.velocity_m_s for s in specs], float).reshape(-1, 3),
        body_path=tuple(np.asarray(s.path, float).reshape(-1, 4) for s in specs),
        body_orientation_path=tuple(b.orientation_keys for b in bodies),
        body_interpolation=tuple(s.interpolation for s in specs),
        **mesh_arrays,
    )


def _mesh_arrays(bodies: Sequence[BodyLayout]) -> dict[str, np.ndarray]:
    """The Model's mesh arrays (fraytool.meshes) from the mesh bodies' assets, scaled, key times from
    the body's start_s + sequence_start_s."""
    from fraytool.meshes import empty_fields

    out = empty_fields()
    meshes = [(k, b.spec, b.mesh) for k, b in enumerate(bodies) if b.spec.shape == "mesh"]
    if not meshes:
        return out
    v_off = t_off = k_off = e_off = 0
    starts = {"mesh_vertex_start": [0], "mesh_triangle_start": [0], "mesh_key_start": [0], "mesh_edge_start": [0]}
    tris, times, keys, edges = [], [], [], []
    for k, bd, a in meshes:
        scale = np.asarray(bd.scale, float)
        tris.append(a.triangles + v_off)
        edges.append(a.sharp_edges + v_off)
        times.append(a.key_time_s + (bd.start_s + bd.sequence_start_s))
        keys.append((a.key_vertices * scale).reshape(-1, 3))
        v_off += a.key_vertices.shape[1]
        t_off += a.triangles.shape[0]
        k_off += a.key_vertices.shape[0]
        e_off += a.sharp_edges.shape[0]
        for name, value in (("mesh_vertex_start", v_off), ("mesh_triangle_start", t_off),
                            ("mesh_key_start", k_off), ("mesh_edge_start", e_off)):
            starts[name].append(value)
    out.update({name: np.asarray(v, np.int64) for name, v in starts.items()})
    out["mesh_body"] = np.array([k for k, _, _ in meshes], np.int32)
    out["mesh_closed"] = np.array([a.closed for _, _, a in meshes], bool)
    out["mesh_triangles"] = np.concatenate(tris).astype(np.int32)
    out["mesh_sharp_edges"] = np.concatenate(edges).astype(np.int32).reshape(-1, 2)
    out["mesh_key_time_s"] = np.concatenate(times).astype(float)
    out["mesh_key_vertex_m"] = np.ascontiguousarray(np.concatenate(keys), dtype=float)
    return out
