"""Warnings about a scene's units that no range check can catch (docs/meshes.md, "Units").

A mesh file carries no unit: OBJ, PLY and STL are plain numbers, and garment and character tools often
write centimetres or millimetres. Read as metres, a 1.7 m figure in centimetres spans 170 m, and the cloth
meets a wall or nothing at all, with no error anywhere. A mesh far larger than anything else in the scene
is named, with the `scale` that would make it centimetres or millimetres."""
from __future__ import annotations

import numpy as np

from fraytool.meshes import MeshTable
from fraytool.scene.spec import SceneSpec

LARGE_MESH_M = 20.0
"""A mesh body wider than this [m] and than LARGE_MESH_RATIO times the cloth is worth a warning."""
LARGE_MESH_RATIO = 50.0


def mesh_scale_warnings(spec: SceneSpec, model) -> list[str]:
    """One line per mesh body whose extent (its widest side at its first key, after `scale`) is over
    LARGE_MESH_M metres and LARGE_MESH_RATIO times the cloth's."""
    meshes = MeshTable(model)
    if meshes.count == 0:
        return []
    rest = np.asarray(model.crossing_rest_position_m, dtype=np.float64)
    cloth_m = float(np.ptp(rest, axis=0).max()) if len(rest) else 0.0
    out = []
    for m in range(meshes.count):
        extent_m = float(np.ptp(meshes.key_vertices(m, 0), axis=0).max())
        if extent_m <= LARGE_MESH_M or extent_m <= LARGE_MESH_RATIO * cloth_m:
            continue
        b = int(meshes.body[m])
        body = spec.bodies[b] if b < len(spec.bodies) else None
        where = f"{spec.source}: [bodies.{b}]" + (f" file = {body.file!r}" if body is not None and body.file else "")
        given = tuple(body.scale) if body is not None else (1.0, 1.0, 1.0)
        cm, mm = (tuple(round(0.01 * s, 12) for s in given), tuple(round(0.001 * s, 12) for s in given))
        fix = (f"if its file is in millimetres set scale = {_vec(mm)}" if extent_m * 0.01 > LARGE_MESH_M else
               f"if its file is in centimetres set scale = {_vec(cm)}, in millimetres {_vec(mm)}")
        out.append(f"{where}: the mesh spans {extent_m:.4g} m, {extent_m / max(cloth_m, 1e-12):.0f} times the cloth "
                   f"({cloth_m:.3g} m); {fix} (mesh files carry no unit; fraytool reads metres times scale)")
    return out


def _vec(v) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v) + "]"
