"""USD export (`fraytool export SCENE --usd OUT.usd`): the yarns, bodies and camera of a shot, a time
sample per frame.

Stage layout (the default prim is named after the scene, made a valid USD identifier):

    /<scene>                 Xform
    /<scene>/Camera          Camera: the renderer's view (fraytool.export.usd_camera), time-sampled when it moves
    /<scene>/Yarns/Weft      BasisCurves: every weft piece of the frame
    /<scene>/Yarns/Warp      BasisCurves: every warp piece
    /<scene>/Yarns/<panel>/Weft, .../Warp   instead, with several [[cloth]] panels (a garment): one Scope per
                             panel, named by the panel, its curves in the panel's own colours
    /<scene>/Yarns/Stitches  BasisCurves, linear: every live stitch of the seams, two points each
    /<scene>/Bodies/<name>   Sphere (radius), Cube (size 2, scaled by the half extents), Plane or Mesh

Yarns: `type` cubic, `basis` catmullRom, `wrap` pinned (the curve runs through its first and last
point too). The points are the centre-line points the renderer's splines pass through
(fraytool.render.yarns: a crossing's weft and warp points, the masses of a yarn-level couple), one curve
per unbroken piece, so `curveVertexCounts` changes as the cloth tears and is time-sampled with the
points. USD's catmullRom is the uniform spline and the renderer's the centripetal one: both pass
through the same points. Per vertex: `widths`, the drawn yarn diameter (2 x [render] yarn_radius_m,
by default the cloth thickness), `velocities` (fraytool.export.velocities) and
`primvars:displayOpacity`, the renderer's fade towards broken ends (1 elsewhere). Constant
`primvars:displayColor`: [render] weft_color / warp_color, decoded from sRGB to linear (as USD
renderers expect). Per curve (uniform) `primvars:fraytool:yarn`: the yarn index (j of a weft, i of a
warp).

Bodies: xformOps translate (double3) and orient (quatf) sampled per frame from the frame record, plus
a constant scale for boxes; planes are squares of 20 x the cloth's size, their normal along the
plane's own axis. displayColor: [render] body_color, linear. Constant primvars `fraytool:velocity`
(of the body's origin) and `fraytool:angularVelocity` (world axes, rad/s); a mesh's `velocities` are
its points' own, in the body's frame (fraytool.export.velocities).

Velocities are per second of the stage's timeline (time code / timeCodesPerSecond): the simulated
velocity times frame_time x fps (a factor of 1 unless the shot plays in slow or fast motion).

Stage: metersPerUnit 1, upAxis Y or Z (whichever of the two the scene camera's up leans to; the
shipped scenes have Y), timeCodesPerSecond = framesPerSecond = [time] fps, a time code per scene
frame (frame k at time code k), start and end time codes the first and last exported frame;
customLayerData: the fraytool version, scene name and hash, and the frame time [s]. The file is
written to a hidden temp file beside OUT and renamed when complete.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Iterable, Mapping, Optional

import numpy as np

from fraytool import __version__
from fraytool.errors import InputError, RunError
from fraytool.geometry.rotations import quaternion_wxyz, rotation_from_y
from fraytool.export.usd_camera import define_camera, sample_camera
from fraytool.export.velocities import (FrameSource, Stencil, body_velocities, mesh_vertex_velocities,
                                        yarn_point_velocities)
from fraytool.io.frame_record import FrameRecord
from fraytool.kinds import SHAPE_BOX, SHAPE_MESH, SHAPE_PLANE, SHAPE_SPHERE
from fraytool.meshes import MeshTable
from fraytool.render.color import srgb_to_linear
from fraytool.render.encode import partial_path, remove_stale_partials
from fraytool.render.geometry import YarnStyle, yarn_curves
from fraytool.render.yarns import WARP, WEFT
from fraytool.scene import scene_hash
from fraytool.scene.spec import SceneSpec

USD_SUFFIXES = (".usd", ".usda", ".usdc")
"""File name endings USD picks its format by: .usd and .usdc binary (crate), .usda text."""
INSTALL_HINT = 'pip install "fraytool[usd]"'
CAMERA_NAME = "Camera"
"""The scene camera's prim, under the default prim."""
PLANE_SCALE = 20.0
"""A plane body is drawn as a square this many times the cloth's size."""


def require_usd() -> None:
    """InputError (exit 2) naming the install command when the USD library is missing."""
    try:
        from pxr import Usd  # noqa: F401
    except ImportError:
        raise InputError(f"--usd needs the USD Python library (pxr, from usd-core), which is not installed: "
                         f"{INSTALL_HINT}") from None


def check_usd_path(path: Path) -> Path:
    """The --usd file name, which must end in .usd, .usda or .usdc, in a folder that exists (a typo in
    the folder must not quietly make a new tree of folders), and not be a folder itself."""
    text = str(path)
    path = Path(path)
    if text.endswith(("/", "\\")) or path.is_dir():
        raise InputError(f"--usd {text!r} is a folder: give a file name ending in {', '.join(USD_SUFFIXES)}, "
                         f"e.g. {path / 'shot.usd'}")
    if path.suffix.lower() not in USD_SUFFIXES or not path.stem:
        raise InputError(f"--usd {text!r}: expected a file name ending in {', '.join(USD_SUFFIXES)} "
                         "(.usd and .usdc binary, .usda text), e.g. shot.usd")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"--usd {text!r}: the folder {str(parent)!r} does not exist; create it first or "
                         "choose another path")
    return path


def up_axis(camera_up) -> str:
    """"Y" or "Z" (the two axes USD allows), whichever the camera's up vector leans to more."""
    up = np.abs(np.asarray(camera_up, dtype=np.float64))
    return "Y" if up[1] >= up[2] else "Z"


class _YarnPrim:
    """One BasisCurves prim (a panel's weft or warp pieces, or the seams' stitches) and its time-sampled
    attributes."""

    def __init__(self, stage, path: str, color_srgb, width_m: float, linear: bool = False):
        from pxr import Gf, Sdf, UsdGeom

        self.width_m = width_m
        c = UsdGeom.BasisCurves.Define(stage, path)
        if linear:  # a stitch: a straight thread between its two masses
            c.CreateTypeAttr(UsdGeom.Tokens.linear)
        else:
            c.CreateTypeAttr(UsdGeom.Tokens.cubic)
            c.CreateBasisAttr(UsdGeom.Tokens.catmullRom)
            c.CreateWrapAttr(UsdGeom.Tokens.pinned)
        c.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(*map(float, srgb_to_linear(color_srgb)))])
        self.counts = c.CreateCurveVertexCountsAttr()
        self.points = c.CreatePointsAttr()
        self.widths = c.CreateWidthsAttr()
        c.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
        self.opacity = c.CreateDisplayOpacityPrimvar(UsdGeom.Tokens.vertex)
        self.yarn = UsdGeom.PrimvarsAPI(c).CreatePrimvar("fraytool:yarn", Sdf.ValueTypeNames.IntArray,
                                                         UsdGeom.Tokens.uniform)
        self.extent = c.CreateExtentAttr()
        self.velocities = c.CreateVelocitiesAttr()

    def set(self, time: float, points: np.ndarray, offsets: np.ndarray, opacity: np.ndarray, yarn: np.ndarray,
            velocities: Optional[np.ndarray]) -> None:
        """The pieces of one frame at time code `time`; `velocities` per point [m/s], None: unknown."""
        from pxr import Vt

        p = np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 3)
        self.counts.Set(Vt.IntArray.FromNumpy(np.diff(offsets).astype(np.int32)), time)
        self.points.Set(Vt.Vec3fArray.FromNumpy(p), time)
        self.widths.Set(Vt.FloatArray.FromNumpy(np.full(len(p), self.width_m, np.float32)), time)
        self.opacity.Set(Vt.FloatArray.FromNumpy(np.ascontiguousarray(opacity, dtype=np.float32)), time)
        self.yarn.Set(Vt.IntArray.FromNumpy(np.ascontiguousarray(yarn, dtype=np.int32)), time)
        if velocities is not None:
            self.velocities.Set(_vec3f_array(velocities), time)
        if len(p):
            half = 0.5 * self.width_m
            lo, hi = p.min(axis=0) - half, p.max(axis=0) + half
            self.extent.Set(Vt.Vec3fArray.FromNumpy(np.stack([lo, hi]).astype(np.float32)), time)


def _pieces_of(curves, chosen: np.ndarray, velocities: Optional[np.ndarray]) -> tuple:
    """(points, offsets, opacity, yarn, velocities or None) of the `chosen` pieces (a mask over them);
    `velocities` are per point of `curves` (None: unknown)."""
    sel = np.nonzero(chosen)[0]
    counts = np.diff(curves.offsets)[sel]
    starts = curves.offsets[:-1][sel]
    idx = np.repeat(starts - np.concatenate([[0], np.cumsum(counts)[:-1]]), counts) + np.arange(counts.sum())
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return (curves.points[idx], offsets, curves.opacity[idx], curves.yarn[sel],
            None if velocities is None else velocities[idx])


class _BodyPrim:
    """One body's prim: its time-sampled xformOps, its velocity primvars and, for a mesh, its points'
    velocities (and points, when the mesh is animated)."""

    def __init__(self, prim, extra: np.ndarray, mesh: Optional[int], meshes: MeshTable):
        from pxr import Sdf, UsdGeom

        self.extra = extra
        self.mesh = mesh
        self.meshes = meshes
        self.translate = prim.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble)
        self.orient = prim.AddOrientOp(UsdGeom.XformOp.PrecisionFloat)
        primvars = UsdGeom.PrimvarsAPI(prim)
        self.velocity = primvars.CreatePrimvar("fraytool:velocity", Sdf.ValueTypeNames.Vector3f,
                                               UsdGeom.Tokens.constant)
        self.angular_velocity = primvars.CreatePrimvar("fraytool:angularVelocity", Sdf.ValueTypeNames.Vector3f,
                                                       UsdGeom.Tokens.constant)
        is_mesh = mesh is not None
        self.points = prim.GetPointsAttr() if is_mesh and meshes.animated(mesh) else None
        self.point_velocities = prim.CreateVelocitiesAttr() if is_mesh else None
        if is_mesh and self.points is None:  # a rigid mesh: its points never move in its own frame
            self.point_velocities.Set(_vec3f_array(np.zeros((meshes.vertex_count(mesh), 3))))

    def set(self, time: float, record: FrameRecord, b: int, stencil: Stencil,
            motion: Optional[tuple[np.ndarray, np.ndarray]]) -> None:
        """Body b of `record` at time code `time`; `motion`: every body's (linear, angular) velocity
        (fraytool.export.velocities.body_velocities over `stencil`), None when unknown."""
        from pxr import Gf

        self.translate.Set(Gf.Vec3d(*map(float, record.body_position_m[b])), time)
        w, x, y, z = quaternion_wxyz(np.asarray(record.body_rotation[b], np.float64) @ self.extra)
        self.orient.Set(Gf.Quatf(float(w), float(x), float(y), float(z)), time)
        if self.points is not None:  # an animated mesh's points, time-sampled at each frame
            self.points.Set(_vec3f_array(self.meshes.vertices_at(self.mesh, float(record.time_s))), time)
        if motion is None:
            return
        linear, angular = motion
        self.velocity.Set(Gf.Vec3f(*map(float, linear[b])), time)
        self.angular_velocity.Set(Gf.Vec3f(*map(float, angular[b])), time)
        if self.points is not None:
            self.point_velocities.Set(_vec3f_array(mesh_vertex_velocities(self.meshes, self.mesh, stencil)), time)


def _define_bodies(stage, root: str, spec: SceneSpec, topology: Mapping[str, np.ndarray]) -> list:
    """One prim per body; returns a _BodyPrim per body (None for a body that cannot be drawn). A mesh
    body is a UsdGeom.Mesh of its triangles in the body's frame."""
    from pxr import Gf, Tf, UsdGeom

    shapes = np.asarray(topology.get("body_shape", np.zeros(0, np.int8)))
    radius = np.asarray(topology.get("body_radius_m", np.zeros(len(shapes))))
    half = np.asarray(topology.get("body_half_extents_m", np.zeros((len(shapes), 3))))
    normal = np.asarray(topology.get("body_normal", np.tile([0.0, 1.0, 0.0], (len(shapes), 1))))
    rest = np.asarray(topology.get("crossing_rest_position_m", np.zeros((1, 3))))
    cloth_size = float(np.linalg.norm(rest.max(axis=0) - rest.min(axis=0))) if len(rest) else 0.0
    names = [b.name for b in spec.bodies] if len(spec.bodies) == len(shapes) else [f"body_{i}" for i in range(len(shapes))]
    colour = [Gf.Vec3f(*map(float, srgb_to_linear(spec.render.body_color)))]
    UsdGeom.Xform.Define(stage, f"{root}/Bodies")
    used: set[str] = set()
    bodies = []
    meshes = MeshTable(topology)
    mesh_of_body = {int(body): m for m, body in enumerate(meshes.body)}
    for b, shape in enumerate(shapes):
        name = Tf.MakeValidIdentifier(names[b])
        while name in used:
            name += "_"
        used.add(name)
        path = f"{root}/Bodies/{name}"
        extra, mesh = np.eye(3), None
        if shape == SHAPE_SPHERE:
            prim = UsdGeom.Sphere.Define(stage, path)
            prim.CreateRadiusAttr(float(radius[b]))
        elif shape == SHAPE_BOX:
            prim = UsdGeom.Cube.Define(stage, path)
            prim.CreateSizeAttr(2.0)
        elif shape == SHAPE_PLANE:
            prim = UsdGeom.Plane.Define(stage, path)
            prim.CreateAxisAttr(UsdGeom.Tokens.y)
            prim.CreateWidthAttr(PLANE_SCALE * max(cloth_size, 1e-3))
            prim.CreateLengthAttr(PLANE_SCALE * max(cloth_size, 1e-3))
            prim.CreateDoubleSidedAttr(True)
            extra = rotation_from_y(normal[b])  # the plane's +y axis onto its normal (in the body's frame)
        elif shape == SHAPE_MESH and b in mesh_of_body:
            mesh = mesh_of_body[b]
            prim = UsdGeom.Mesh.Define(stage, path)
            tri = meshes.local_triangles(mesh)
            prim.CreateFaceVertexCountsAttr(np.full(tri.shape[0], 3, np.int32).tolist())
            prim.CreateFaceVertexIndicesAttr(tri.ravel().tolist())
            prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
            prim.CreatePointsAttr(_vec3f_array(meshes.key_vertices(mesh, 0)))
        else:
            bodies.append(None)
            continue
        prim.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(colour)
        body = _BodyPrim(prim, extra, mesh, meshes)
        if shape == SHAPE_BOX:
            prim.AddScaleOp(UsdGeom.XformOp.PrecisionFloat).Set(Gf.Vec3f(*map(float, half[b])))
        bodies.append(body)
    return bodies


def _define_yarns(stage, path: str, spec: SceneSpec, topology: Mapping[str, np.ndarray], width_m: float) -> dict:
    """The yarn prims: (panel, kind) -> _YarnPrim. One panel: Weft and Warp (panel -1: every piece); several
    (a garment): a Scope per panel named by the panel with its Weft and Warp in its own colours (the
    renderer's, fraytool.render.color.yarn_palette); (None, None): the seams' live stitches, when there are any."""
    from pxr import Tf, UsdGeom

    from fraytool.kinds import STITCH
    from fraytool.render.color import THREAD_SRGB, yarn_palette

    UsdGeom.Scope.Define(stage, path)
    panels = spec.all_panels
    palette = yarn_palette(spec.render, panels)  # the renderer's colours
    prims = {}
    if len(panels) <= 1:
        prims[(-1, WEFT)] = _YarnPrim(stage, f"{path}/Weft", palette[0], width_m)
        prims[(-1, WARP)] = _YarnPrim(stage, f"{path}/Warp", palette[1], width_m)
    else:
        used: set[str] = {"Stitches"}
        for p, panel in enumerate(panels):
            name = Tf.MakeValidIdentifier(panel.name or f"panel_{p}")
            while name in used:
                name += "_"
            used.add(name)
            scope = UsdGeom.Scope.Define(stage, f"{path}/{name}")
            scope.GetPrim().SetCustomDataByKey("fraytool:panel", panel.name)
            row = min(p, len(palette) // 2 - 1)
            prims[(p, WEFT)] = _YarnPrim(stage, f"{path}/{name}/Weft", palette[2 * row], width_m)
            prims[(p, WARP)] = _YarnPrim(stage, f"{path}/{name}/Warp", palette[2 * row + 1], width_m)
    if (np.asarray(topology["spring_kind"]) == STITCH).any():
        prims[(None, None)] = _YarnPrim(stage, f"{path}/Stitches", THREAD_SRGB, width_m, linear=True)
    return prims


def _vec3f_array(points: np.ndarray):
    from pxr import Vt

    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 3))


def frame_time_s(spec: SceneSpec) -> float:
    """Simulated seconds between two frames (step_s x steps_per_frame)."""
    return float(spec.time.step_s) * int(spec.time.steps_per_frame)


def _new_stage(spec: SceneSpec):
    """An in-memory stage with the module docstring's metadata and the default prim; returns (stage, root
    path)."""
    from pxr import Tf, Usd, UsdGeom

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up_axis(spec.camera.up) == "Y" else UsdGeom.Tokens.z)
    fps = float(spec.time.fps)
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    root = f"/{Tf.MakeValidIdentifier(spec.name)}"
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, root).GetPrim())
    stage.GetRootLayer().customLayerData = {"fraytool:version": __version__, "fraytool:scene_hash": scene_hash(spec),
                                            "fraytool:scene": spec.name, "fraytool:frame_time_s": frame_time_s(spec)}
    return stage, root


def write_usd(path: Path, spec: SceneSpec, topology: Mapping[str, np.ndarray], records: Iterable[FrameRecord],
              on_frame: Optional[Callable[[int], None]] = None, frames: Optional[FrameSource] = None) -> Path:
    """Write the frame records (in time order) as a USD stage at `path` (see the module docstring);
    `on_frame(n)` is called after each of them (n = records done). `frames`: every frame record the
    velocities may difference with (fraytool.export.velocities; default: `records` themselves).
    Returns the path."""
    from pxr import UsdGeom

    path = check_usd_path(path)
    if frames is None:
        records = list(records)
        frames = FrameSource.of_records(records)
    stage, root = _new_stage(spec)
    camera = define_camera(stage, f"{root}/{CAMERA_NAME}", spec.camera, spec.render.resolution)
    style = YarnStyle.from_spec(spec.render, topology)
    prims = _define_yarns(stage, f"{root}/Yarns", spec, topology, 2.0 * style.radius_m)
    bodies = _define_bodies(stage, root, spec, topology)
    time_codes_per_second = stage.GetTimeCodesPerSecond()

    first = last = None
    for n, record in enumerate(records, start=1):
        t = float(record.frame)
        first = t if first is None else first
        last = t
        stencil = Stencil.around(record, frames, time_codes_per_second)
        sample_camera(camera, spec.camera, spec.render.resolution, t, float(record.time_s))
        curves = yarn_curves(topology, record, style)
        velocities = yarn_point_velocities(topology, stencil) if stencil.has_motion else None
        for (panel, kind), prim in prims.items():
            chosen = curves.panel < 0 if panel is None else (curves.panel >= 0) & (curves.kind == kind)
            if panel is not None and panel >= 0:
                chosen &= curves.panel == panel
            prim.set(t, *_pieces_of(curves, chosen, velocities))
        motion = body_velocities(stencil) if stencil.has_motion else None
        for b, body in enumerate(bodies):
            if body is not None:
                body.set(t, record, b, stencil, motion)
        if on_frame is not None:
            on_frame(n)
    if first is None:
        raise ValueError("no frames to export")
    stage.SetStartTimeCode(first)
    stage.SetEndTimeCode(last)
    _save(stage, path)
    return path


def _save(stage, path: Path) -> None:
    """Export the stage to a hidden temp file beside `path`, fsync it and rename it to `path`."""
    from pxr import Tf

    remove_stale_partials(path)
    tmp = partial_path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        try:
            written, why = stage.GetRootLayer().Export(str(tmp)), "no reason given"
        except Tf.ErrorException as exc:  # USD reports failed writes (a read-only folder, ...) this way
            written, why = False, " ".join(str(exc).split())
        if not written:
            raise RunError(f"{path}: USD could not write the file ({why}): check that the folder is writable "
                           "and has space, or choose another --usd path")
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
