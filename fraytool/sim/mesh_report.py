"""What `fraytool check` says of each mesh body, and the warning an open mesh deserves (docs/meshes.md).

A studio's mesh can be other than it looks: an OBJ cut off in its face list loads as an open mesh with
part of its faces gone, a sequence can start at any number. So `check` describes each mesh body as the
simulation sees it, from the Model (after welding and `scale`) and its scene entry (the files):
triangles, vertices, closed or open with its border edges, sharp edges, bounds in metres at time 0, and
for an animated mesh its keys, first and last file, duration and which file is at scene time 0.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from fraytool.meshes import MeshTable


def border_edge_count(triangles: np.ndarray) -> int:
    """Edges run by exactly one triangle (an open mesh's border)."""
    if triangles.shape[0] == 0:
        return 0
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    return int((counts == 1).sum())


def describe_mesh_bodies(spec, model) -> list[dict]:
    """One record per mesh body of `model` (its scene entry in `spec` names the files)."""
    meshes = MeshTable(model)
    out = []
    for m in range(meshes.count):
        b = int(meshes.body[m])
        body = spec.bodies[b] if b < len(spec.bodies) else None
        tri = meshes.local_triangles(m)
        rot = np.asarray(model.body_rotation[b], float)
        world = meshes.vertices_at(m, 0.0) @ rot.T + np.asarray(model.body_initial_position_m[b], float)
        edges = meshes.sharp_edges[meshes.edge_start[m]:meshes.edge_start[m + 1]]
        record = {
            "body": b, "name": str(model.body_names[b]), "file": body.file if body is not None else "<arrays>",
            "triangles": int(tri.shape[0]), "vertices": meshes.vertex_count(m),
            "closed": bool(meshes.closed[m]), "border_edges": border_edge_count(tri),
            "sharp_edges": int(edges.shape[0]),
            "bounds_m": [world.min(axis=0).tolist(), world.max(axis=0).tolist()],
            "keys": meshes.key_count(m),
        }
        times = meshes.key_times(m)
        if meshes.animated(m):
            record.update({"first_key_s": float(times[0]), "last_key_s": float(times[-1]),
                           "duration_s": float(times[-1] - times[0])})
            files = _sequence_files(spec, body)
            if files:
                record.update({"first_file": files[0].name, "last_file": files[-1].name,
                               "file_at_time_0": _file_at(files, times, 0.0)})
        out.append(record)
    return out


def _sequence_files(spec, body) -> list[Path]:
    from fraytool.scene.mesh_files import MeshFileError, is_sequence, resolve, sequence_files

    if body is None or not body.file:
        return []
    path = resolve(body.file, spec.source_file)
    if not is_sequence(path):
        return []
    try:
        return sequence_files(path)
    except MeshFileError:
        return []


def _file_at(files: list[Path], times: np.ndarray, time_s: float) -> str:
    """The file shown at `time_s`: held before the first key and after the last, else the nearest two."""
    if time_s <= times[0]:
        return files[0].name + ("" if time_s == times[0] else f" (held until {times[0]:g} s)")
    if time_s >= times[-1]:
        return files[-1].name + ("" if time_s == times[-1] else " (held since its key)")
    j = int(np.searchsorted(times, time_s, side="right"))
    if times[j - 1] == time_s:
        return files[j - 1].name
    return f"between {files[j - 1].name} and {files[j].name}"


def describe_lines(records: list[dict]) -> list[str]:
    """The records as `check` prints them, a line or two per mesh body."""
    lines = []
    for r in records:
        lo, hi = r["bounds_m"]
        shape = "closed" if r["closed"] else _open_words(r)
        lines.append(f"mesh body {r['body']} {r['name']} ({r['file']}): {r['triangles']} triangles, {r['vertices']} "
                     f"vertices after welding, {shape}, {r['sharp_edges']} sharp edges, bounds at 0 s "
                     f"[{_v(lo)}] .. [{_v(hi)}] m")
        if r["keys"] > 1:
            files = (f", {r['first_file']} .. {r['last_file']}, {r['file_at_time_0']} at 0 s"
                     if "first_file" in r else "")
            lines.append(f"  animated: {r['keys']} keys from {r['first_key_s']:g} s to {r['last_key_s']:g} s "
                         f"({r['duration_s']:g} s){files}")
    return lines


def _open_words(r: dict) -> str:
    if r["border_edges"]:
        return f"open ({r['border_edges']} border edges)"
    return "open (no border edge, but not consistently oriented or not a manifold)"


def _v(v) -> str:
    return ", ".join(f"{x:.4g}" for x in v)


def open_mesh_warning(where: str, border_edges: int, triangles: int) -> str:
    """The line for an open mesh body (ModelBuilder.add_mesh records it): what an open mesh costs, so a file cut
    short or a mesh with holes does not pass silently. `where` names the body and its file."""
    return (f"{where}: the mesh is {_open_words({'border_edges': border_edges})}, of {triangles} triangles: its "
            "contact is two-sided, with no push-out of cloth that gets inside, and its borders are sharp edges the "
            "yarns catch on; a closed body with holes, or a file cut short, reads like this (docs/meshes.md)")
