"""Warnings about a scene's units that no range check can catch (docs/meshes.md, "Units").

A mesh file carries no unit: OBJ, PLY and STL are plain numbers, and garment and character tools often
write centimetres or millimetres. Read as metres, a 1.7 m figure in centimetres spans 170 m, and the cloth
meets a wall or nothing at all, with no error anywhere. A mesh far larger than anything else in the scene
is named, with the `scale` that would make it centimetres or millimetres."""
from __future__ import annotations


LARGE_MESH_M = 20.0
"""A mesh body wider than this [m] and than LARGE_MESH_RATIO times the cloth is worth a warning."""
LARGE_MESH_RATIO = 50.0


def mesh_scale_warning(where: str, scale, extent_m: float, cloth_m: float) -> str:
    """The line for a mesh body (`where` names it and its file) whose extent (its widest side at its first key,
    after `scale`) is over LARGE_MESH_M metres and LARGE_MESH_RATIO times the cloth's; "" when it is not
    (ModelBuilder.finalize, once both the mesh and the cloth are added)."""
    if extent_m <= LARGE_MESH_M or extent_m <= LARGE_MESH_RATIO * cloth_m:
        return ""
    cm, mm = (tuple(round(0.01 * s, 12) for s in scale), tuple(round(0.001 * s, 12) for s in scale))
    fix = (f"if its file is in millimetres set scale = {_vec(mm)}" if extent_m * 0.01 > LARGE_MESH_M else
           f"if its file is in centimetres set scale = {_vec(cm)}, in millimetres {_vec(mm)}")
    return (f"{where}: the mesh spans {extent_m:.4g} m, {extent_m / max(cloth_m, 1e-12):.0f} times the cloth "
            f"({cloth_m:.3g} m); {fix} (mesh files carry no unit; fraytool reads metres times scale)")


def _vec(v) -> str:
    return "[" + ", ".join(f"{x:g}" for x in v) + "]"
