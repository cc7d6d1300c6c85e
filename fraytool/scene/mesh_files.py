"""Mesh bodies' files: OBJ, PLY, STL, glTF/GLB through trimesh, numbered sequences, USD (docs/meshes.md).

`file_problems` checks what can be checked without reading a mesh (the file is there, its kind is
known, a sequence has no gap) when the scene is loaded; `read_asset` reads the triangles and every
key, checks them (not empty, finite, one topology through a sequence), welds vertices that share a
position, and finds whether the mesh is closed (watertight, consistently oriented: then its normals
are turned outward) and which of its edges are sharp. Any problem is a `MeshFileError` with one line
that names the file.

trimesh (a dependency) reads the mesh formats: it is the library made for this, kept up to date with
the formats' variants (OBJ groups and quads, binary and ASCII PLY and STL, glTF scenes). USD is read
with Pixar's own package (`pxr`, the optional `usd` extra): points per time sample, the prim's
transform at that time, and the stage's metersPerUnit.
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from fraytool.files import scene_path

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".gltf", ".glb")
USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")
BYTES_PER_FILE_BYTE = 16
"""Memory estimate of a mesh body per byte of its files: trimesh's parse (float64 vertices, faces, its
caches), our welded float64 keys, the BVH and the renderer's copy. Measured about 9 on OBJ (text, the
densest case per byte is binary STL/PLY at about 12); with margin."""


class MeshFileError(Exception):
    """A mesh file that cannot be used; the message is one line naming the file."""


@dataclass(frozen=True)
class MeshAsset:
    """A mesh body's geometry as read: welded, oriented, in the file's units (USD: metres)."""

    triangles: np.ndarray
    """(T, 3) int32."""
    key_vertices: np.ndarray
    """(K, V, 3) float64: one key for a static mesh."""
    key_time_s: np.ndarray
    """(K,) float64, from 0 (the first file or time sample)."""
    closed: bool
    sharp_edges: np.ndarray
    """(E, 2) int32: border edges of an open mesh and edges whose faces turn by more than SHARP_DEG."""


resolve = scene_path
"""The file a mesh body names (fraytool.files.scene_path: the one rule for a scene's files)."""


def is_sequence(path: Path) -> bool:
    return "#" in path.name


def sequence_files(path: Path) -> list[Path]:
    """The files of a numbered sequence `walk.####.obj` in frame order; MeshFileError on none or a gap."""
    m = re.fullmatch(r"(.*?)(#+)(.*)", path.name)
    if m is None or "#" in m.group(3):
        raise MeshFileError(f"{path}: a sequence has one run of # (walk.####.obj)")
    prefix, width, suffix = m.group(1), len(m.group(2)), m.group(3)
    pattern = re.compile(re.escape(prefix) + r"(\d{%d,})" % width + re.escape(suffix) + "$")
    found = {}
    if path.parent.is_dir():
        for f in path.parent.iterdir():
            hit = pattern.fullmatch(f.name)
            if hit:
                found[int(hit.group(1))] = f
    if not found:
        raise MeshFileError(f"{path}: no file of this sequence found ({prefix}{'0' * width}{suffix}, ...)")
    numbers = sorted(found)
    for a, b in zip(numbers, numbers[1:]):
        if b != a + 1:
            missing = f"{prefix}{str(a + 1).zfill(width)}{suffix}"
            raise MeshFileError(f"{path}: frame {a + 1} is missing ({missing}) between {numbers[0]} and "
                                f"{numbers[-1]}")
    return [found[k] for k in numbers]


def _suffix_problem(path: Path, prim: str) -> Optional[str]:
    suffix = path.suffix.lower()
    if suffix in USD_SUFFIXES:
        if not prim:
            return "a USD file needs `prim`, the path of its Mesh prim (e.g. /Root/Body)"
        if is_sequence(path):
            return "a USD file holds its own animation (time samples): name one file, not a sequence"
        return None
    if suffix not in MESH_SUFFIXES:
        return f"unknown mesh file kind {suffix or '(none)'}; allowed: {', '.join(MESH_SUFFIXES + USD_SUFFIXES)}"
    if prim:
        return "`prim` is for USD files"
    return None


def file_problems(file: str, prim: str, scene_file: str) -> list[tuple[str, str, str]]:
    """(key, value, message) problems of a mesh body's file found without reading the mesh."""
    path = resolve(file, scene_file)
    problem = _suffix_problem(path, prim)
    if problem:
        return [("file", file, problem)]
    try:
        files = sequence_files(path) if is_sequence(path) else [path]
    except OSError as exc:  # a name over 255 bytes, a folder that cannot be listed
        return [("file", file[:80] + ("..." if len(file) > 80 else ""), f"cannot be read: {exc.strerror}")]
    except MeshFileError as exc:
        return [("file", file, str(exc).split(": ", 1)[1])]
    from fraytool.files import not_a_regular_file

    for f in files:
        why = not_a_regular_file(f)
        if why == "no such file":
            return [("file", file, f"not found ({f})")]
        if why is not None:
            return [("file", file, f"cannot read {f.name[:60]}{'...' if len(f.name) > 60 else ''}: {why}")]
        try:
            with open(f, "rb") as handle:
                handle.read(1)
        except OSError as exc:
            return [("file", file, f"cannot read {f}: {exc.strerror}")]
    return []


def file_bytes(file: str, scene_file: str) -> int:
    """Bytes on disk of a mesh body's files (0 where they cannot be found: file_problems says so)."""
    path = resolve(file, scene_file)
    try:
        files = sequence_files(path) if is_sequence(path) else [path]
        return sum(f.stat().st_size for f in files)
    except (MeshFileError, OSError):
        return 0


def read_asset(path: Path, prim: str = "", frame_time_s: float = 1.0) -> MeshAsset:
    """Read a mesh body's files (cached on the files' paths, sizes and modification times)."""
    files = sequence_files(path) if is_sequence(path) else [path]
    stamps = []
    for f in files:
        try:
            st = f.stat()
        except OSError as exc:
            raise MeshFileError(f"{f}: cannot read: {exc.strerror}") from None
        stamps.append((str(f), st.st_size, st.st_mtime_ns))
    return _read_cached(tuple(stamps), prim, float(frame_time_s))


@functools.lru_cache(maxsize=16)
def _read_cached(stamps: tuple, prim: str, frame_time_s: float) -> MeshAsset:
    files = [Path(s[0]) for s in stamps]
    if files[0].suffix.lower() in USD_SUFFIXES:
        triangles, keys, times = _read_usd(files[0], prim)
    else:
        triangles, first = _read_trimesh(files[0])
        keys = [first]
        for f in files[1:]:
            tri, v = _read_trimesh(f)
            if tri.shape != triangles.shape or v.shape != first.shape or not np.array_equal(tri, triangles):
                raise MeshFileError(f"{f}: its topology differs from {files[0].name} ({v.shape[0]} vertices, "
                                    f"{tri.shape[0]} triangles against {first.shape[0]} and {triangles.shape[0]}); "
                                    "a sequence keeps one topology")
            keys.append(v)
        times = np.arange(len(keys), dtype=float) * frame_time_s
    asset = _prepare(np.stack(keys), triangles, files[0])
    out = MeshAsset(asset[0], asset[1], np.asarray(times, float), asset[2], asset[3])
    for a in (out.triangles, out.key_vertices, out.key_time_s, out.sharp_edges):
        a.setflags(write=False)
    return out


def _read_trimesh(path: Path) -> tuple[np.ndarray, np.ndarray]:
    try:
        import trimesh
    except ImportError as exc:  # a dependency: only a broken install lacks it
        raise MeshFileError(f"{path}: reading meshes needs trimesh (pip install trimesh): {exc}") from None
    try:
        mesh = trimesh.load(str(path), force="mesh", process=False)
    except Exception as exc:  # trimesh raises many kinds for a malformed file: one line, the file named
        text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise MeshFileError(f"{path}: cannot read as a mesh: {text[:160]}") from None
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))), np.int64).reshape(-1, 3)
    vertices = np.asarray(getattr(mesh, "vertices", np.zeros((0, 3))), np.float64).reshape(-1, 3)
    if faces.shape[0] == 0:
        raise MeshFileError(f"{path}: holds no triangles (an empty mesh)")
    if not np.isfinite(vertices).all():
        _raise_non_finite(path, vertices)
    return faces.astype(np.int32), vertices


def _raise_non_finite(path: Path, vertices: np.ndarray) -> None:
    """A non-finite vertex named as the file numbers it: trimesh reorders an OBJ's vertices (it splits them
    where texture coordinates differ), so an OBJ's `v` lines are read again to find the first bad one."""
    if path.suffix.lower() == ".obj":
        number = 0
        with open(path, "rb") as handle:
            for line_no, raw in enumerate(handle, 1):
                parts = raw.split()
                if not parts or parts[0] != b"v":
                    continue
                number += 1
                try:
                    xyz = [float(p) for p in parts[1:4]]
                except ValueError:
                    continue  # trimesh has said what it made of it
                if not all(math.isfinite(x) for x in xyz):
                    raise MeshFileError(f"{path}: vertex {number} (line {line_no}, OBJ counts from 1) is not "
                                        f"finite ({', '.join(p.decode(errors='replace') for p in parts[1:4])})")
    v = int(np.argwhere(~np.isfinite(vertices))[0][0])
    raise MeshFileError(f"{path}: vertex {v} (counting from 0 in the file's order) is not finite "
                        f"({vertices[v].tolist()})")


def _read_usd(path: Path, prim_path: str) -> tuple[np.ndarray, list[np.ndarray], np.ndarray]:
    try:
        from pxr import Usd, UsdGeom
    except ImportError:
        raise MeshFileError(f"{path}: reading USD needs the usd extra (pip install 'fraytool[usd]')") from None
    try:
        stage = Usd.Stage.Open(str(path))
    except Exception as exc:
        raise MeshFileError(f"{path}: cannot open as USD: {str(exc).strip().splitlines()[-1][:160]}") from None
    if stage is None:
        raise MeshFileError(f"{path}: cannot open as USD")
    prim = stage.GetPrimAtPath(prim_path) if prim_path.startswith("/") else None
    if prim is None or not prim.IsValid() or not prim.IsA(UsdGeom.Mesh):
        meshes = [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)][:5]
        raise MeshFileError(f"{path}: prim = {prim_path!r} is not a Mesh prim of the file (its meshes: "
                            f"{', '.join(meshes) if meshes else 'none'})")
    mesh = UsdGeom.Mesh(prim)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get() or [], np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get() or [], np.int64)
    if counts.size == 0 or counts.sum() != indices.size or (counts < 3).any():
        raise MeshFileError(f"{path}: {prim_path} holds no triangles (or its face counts do not match its indices)")
    tris = []
    start = 0
    for c in counts:  # fan triangulation of each polygon
        for q in range(1, int(c) - 1):
            tris.append((indices[start], indices[start + q], indices[start + q + 1]))
        start += int(c)
    triangles = np.asarray(tris, np.int32)
    points = mesh.GetPointsAttr()
    samples = list(points.GetTimeSamples())
    metres = float(UsdGeom.GetStageMetersPerUnit(stage))
    per_second = float(stage.GetTimeCodesPerSecond()) or 24.0
    xformable = UsdGeom.Xformable(prim)
    times = samples if samples else [Usd.TimeCode.Default()]
    keys = []
    for t in times:
        value = points.Get(t)
        if value is None or len(value) == 0:
            raise MeshFileError(f"{path}: {prim_path} has no points" + (f" at time sample {t}" if samples else ""))
        p = np.asarray(value, np.float64).reshape(-1, 3)
        m = np.asarray(xformable.ComputeLocalToWorldTransform(t), np.float64)  # row vectors: p' = [p 1] M
        keys.append(metres * (p @ m[:3, :3] + m[3, :3]))
    if any(k.shape != keys[0].shape for k in keys):
        raise MeshFileError(f"{path}: {prim_path} changes its number of points between time samples; "
                            "an animated mesh keeps one topology")
    key_time = (np.asarray(samples, float) - samples[0]) / per_second if samples else np.zeros(1)
    return triangles, keys, key_time


def _prepare(keys: np.ndarray, triangles: np.ndarray, path: Path):
    """Check, weld, orient; find the sharp edges. Returns (triangles, keys, closed, sharp_edges)."""
    bad = ~np.isfinite(keys)
    if bad.any():
        k, v, _ = np.argwhere(bad)[0]
        where = f" (key {k})" if keys.shape[0] > 1 else ""
        raise MeshFileError(f"{path}: vertex {v} is not finite ({keys[k, v].tolist()}){where}")
    vertex_count = keys.shape[1]
    if triangles.size and (triangles.min() < 0 or triangles.max() >= vertex_count):
        raise MeshFileError(f"{path}: a triangle refers to a vertex that does not exist")
    # weld the vertices that share a position in the first key (split for UV seams and normals)
    _, first, inverse = np.unique(keys[0], axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # keep the file's vertex order among the kept ones
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    tri = rank[inverse.reshape(-1)][triangles].astype(np.int32)
    keys = keys[:, first[order]]
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    area = np.linalg.norm(np.cross(keys[0, tri[:, 1]] - keys[0, tri[:, 0]], keys[0, tri[:, 2]] - keys[0, tri[:, 0]]),
                          axis=1)
    tri = tri[area > 0.0]
    if tri.shape[0] == 0:
        raise MeshFileError(f"{path}: holds no triangles with an area (an empty mesh)")
    used = np.unique(tri)
    remap = np.full(keys.shape[1], -1, np.int64)
    remap[used] = np.arange(used.size)
    tri = remap[tri].astype(np.int32)
    keys = np.ascontiguousarray(keys[:, used])
    closed = _closed(tri)
    if closed and _signed_volume(keys[0], tri) < 0.0:
        tri = tri[:, [0, 2, 1]].copy()  # inward normals: turn them out
    return tri, keys, closed, sharp_edges(keys[0], tri)


def _closed(tri: np.ndarray) -> bool:
    """Every edge has exactly two triangles that run it in opposite directions."""
    directed = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    if np.unique(directed, axis=0).shape[0] != directed.shape[0]:
        return False  # an edge run twice the same way: not consistently oriented (or not a manifold)
    undirected = np.sort(directed, axis=1)
    _, counts = np.unique(undirected, axis=0, return_counts=True)
    return bool((counts == 2).all())


def _signed_volume(v: np.ndarray, tri: np.ndarray) -> float:
    a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    return float(np.einsum("ij,ij->", a, np.cross(b, c))) / 6.0


def sharp_edges(v: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Edges with one triangle, more than two, or two whose normals differ by more than SHARP_DEG."""
    from fraytool.meshes import SHARP_DEG

    edges = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), axis=1)
    face = np.tile(np.arange(tri.shape[0]), 3)
    normal = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    edges, face = edges[order], face[order]
    new = np.ones(edges.shape[0], bool)
    new[1:] = (edges[1:] != edges[:-1]).any(axis=1)
    starts = np.flatnonzero(new)
    counts = np.diff(np.append(starts, edges.shape[0]))
    sharp = counts != 2
    two = np.flatnonzero(counts == 2)
    cos = np.einsum("ij,ij->i", normal[face[starts[two]]], normal[face[starts[two] + 1]])
    sharp[two] = cos < math.cos(math.radians(SHARP_DEG))
    return edges[starts[sharp]].astype(np.int32).reshape(-1, 2)


def asset_problems(spec) -> list[str]:
    """One error line per mesh body whose files cannot be used (read now, after the memory check: the
    reading is cached for the build)."""
    lines = []
    for i, b in enumerate(spec.bodies):
        if b.shape != "mesh":
            continue
        try:
            read_asset(resolve(b.file, spec.source_file), b.prim, b.frame_time_s or frame_time_default(spec))
        except MeshFileError as exc:
            lines.append(f"{spec.source}: [bodies.{i}] file = {b.file!r}: {exc}")
    return lines


def frame_time_default(spec) -> float:
    """Seconds between two files of a sequence when frame_time_s is 0: the scene's frame time."""
    return spec.time.step_s * spec.time.steps_per_frame


def asset_from_arrays(vertices_m, triangles, key_times_s=None) -> MeshAsset:
    """A mesh asset from arrays (ModelBuilder.add_mesh): vertices (V, 3) or keys (K, V, 3) at key_times_s."""
    where = Path("<arrays>")
    try:
        v = np.asarray(vertices_m, np.float64)
        t = np.asarray(triangles, np.int64)
    except (TypeError, ValueError) as exc:
        raise MeshFileError(f"{where}: vertices_m and triangles must be arrays of numbers ({exc})") from None
    if v.ndim == 2:
        v = v[None]
    if v.ndim != 3 or v.shape[2] != 3 or t.ndim != 2 or t.shape[1] != 3:
        raise MeshFileError(f"{where}: vertices_m must be (V, 3) or (K, V, 3) and triangles (T, 3); got "
                            f"{v.shape} and {t.shape}")
    if t.shape[0] == 0:
        raise MeshFileError(f"{where}: holds no triangles (an empty mesh)")
    times = np.zeros(1) if key_times_s is None else np.asarray(key_times_s, float).reshape(-1)
    if times.shape[0] != v.shape[0] or (np.diff(times) <= 0).any() or not np.isfinite(times).all():
        raise MeshFileError(f"{where}: key_times_s must give one increasing finite time per key "
                            f"({v.shape[0]} keys, {times.shape[0]} times)")
    tri, keys, closed, sharp = _prepare(v, t.astype(np.int32), where)
    return MeshAsset(tri, keys, times, closed, sharp)
