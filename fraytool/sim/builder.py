"""ModelBuilder: a cloth, rigid bodies and attachments, added in code or from a scene file -> Model.

    builder = ModelBuilder(seed=1)
    builder.add_cloth(warp_yarns=30, weft_yarns=30, spacing_m=0.005, thickness_m=0.0008,
                      mass_per_crossing_kg=2.0e-5, structural_n_per_m=20.0)
    builder.add_sphere("ball", radius_m=0.05, position_m=(0.0, -0.05, 0.0))
    model = builder.finalize()

Every keyword argument is the scene key of the same name (docs/scene-format.md), in SI units, with
the same default and allowed range: both come from the key's one declaration in
`fraytool.scene.spec`, and the rules that tie keys together from `fraytool.scene.rules`. A bad
argument raises ModelBuilderError (a ValueError) naming the method, the argument, the value and what
is allowed. `build_model(spec)` is these same calls for a scene read from a file.

The model (docs/method.md §3.2 base model at yarn resolution) has one mass per crossing on a quad grid
and springs:
- structural between grid neighbours along weft (i, i+1) and warp (j, j+1);
- bend between masses two apart (skip one) along weft and warp;
- shear between diagonal neighbours, acting only in compression;
- one dead twin slot per shear spring, brought to life when a split duplicates it (§3.4).
Break strains are drawn in `finalize()`, once, from numpy.random.default_rng(seed) (§3.4 "random
break limits").
"""
from __future__ import annotations

import dataclasses
import inspect
import math
from typing import Any, Callable, Optional, Sequence

import numpy as np

from fraytool.errors import SceneError
from fraytool.kinds import (BEND_WARP, BEND_WEFT, MOTION_NAMES, SHAPE_NAMES, SHEAR, SHEAR_TWIN, STITCH, STRUCT_WARP,
                            STRUCT_WEFT)
from fraytool.scene import rules, schema
from fraytool.scene.keys import Key, show
from fraytool.scene.spec import (
    AttachmentSpec,
    BodySpec,
    ClothSpec,
    CutSpec,
    MultiresSpec,
    SceneSpec,
    SelfCollisionSpec,
    SpringSpec,
    StrainSpec,
    SeamSpec,
    TearingSpec,
    WeakLineSpec,
)
from fraytool.scene.panel_shape import (PanelShapeError, crossing_fraction_along, distance_to_polyline, panel_shape,
                                       sample_map, tear_map_image)
from fraytool.sim.model import Model
from fraytool.geometry.rotations import euler_rotation, quat_to_matrix
from fraytool.sim.paths import orientation_keys
from fraytool.sim.seam_layout import border_crossings, stitch_pairs

Vec3 = tuple[float, float, float]

_PLANE_AXES = {"xz": (0, 2), "xy": (0, 1), "yz": (1, 2)}
"""[cloth] plane -> (the weft's axis, the warp's axis): the first letter's and the second's
(docs/scene-format.md; scene_hash marks "yz", whose frames once ran the weft along z)."""

_SCENE, _WORLD, _CLOTH, _SPRINGS = (schema.TOP[t] for t in ("scene", "world", "cloth", "cloth.springs"))
_STRAIN, _TEARING, _SELF = (schema.TOP[t] for t in ("cloth.strain", "cloth.tearing", "self_collision"))
_MULTIRES = schema.TOP["cloth.multires"]
_BODY, _ATTACH, _CUT = schema.TOP["bodies"], schema.TOP["attachments"], schema.TOP["cuts"]
_WEAK, _SEAM = schema.TOP["weak_lines"], schema.TOP["seams"]


@dataclasses.dataclass(frozen=True)
class _Panel:
    """A panel added to the builder: its keys, its shape (which crossings of its grid exist) and its tear map."""

    spec: ClothSpec
    shape: Any
    tear_map: Optional[np.ndarray]


class ModelBuilderError(SceneError, ValueError):
    """Bad arguments to a ModelBuilder method: one line per problem, "ModelBuilder.method: arg = value:
    what is allowed". A SceneError (exit code 2 from the CLI) and a ValueError (for Python callers)."""


def _unit(v) -> np.ndarray:
    """v / |v|, scaled by its largest component first so that neither a huge vector (|v|^2 overflows
    to inf, v / |v| to 0) nor a tiny one (|v|^2 underflows to 0) loses its direction."""
    v = np.asarray(v, float)
    v = v / np.abs(v).max()
    return v / np.linalg.norm(v)


def crossing_index(i: int | np.ndarray, j: int | np.ndarray, warp_yarns: int):
    """Crossing of warp yarn i and weft yarn j."""
    return j * warp_yarns + i


def select_crossings(att: AttachmentSpec, nx: int, ny: int, rest: np.ndarray,
                     crossing_grid: Optional[np.ndarray] = None) -> np.ndarray:
    """Crossings chosen by an attachment: an edge, a corner block, index ranges or a region.
    `crossing_grid` (ny, nx) maps a grid place to its crossing, -1 where a shaped panel has none (default:
    the full rectangle); an edge of a shaped panel is its border crossings on that side (the neighbour
    that way is missing)."""
    if crossing_grid is None:
        crossing_grid = np.arange(nx * ny, dtype=np.int64).reshape(ny, nx)
    present = crossing_grid >= 0
    jj, ii = np.nonzero(present)  # crossing order: row-major over the present places
    if att.edge is not None:
        pad = np.pad(present, 1)
        missing = {"left": ~pad[1:-1, :-2], "right": ~pad[1:-1, 2:], "bottom": ~pad[:-2, 1:-1],
                   "top": ~pad[2:, 1:-1]}[att.edge]
        mask = missing[jj, ii]
    elif att.corner is not None:
        k = att.corner_size
        left = ii < k
        right = ii >= nx - k
        bottom = jj < k
        top = jj >= ny - k
        mask = {"bottom_left": left & bottom, "bottom_right": right & bottom,
                "top_left": left & top, "top_right": right & top}[att.corner]
    elif att.warp_range is not None:
        (i0, i1), (j0, j1) = att.warp_range, att.weft_range
        mask = (ii >= i0) & (ii <= i1) & (jj >= j0) & (jj <= j1)
    else:
        d = np.linalg.norm(rest - np.asarray(att.region_center_m), axis=1)
        mask = d <= att.region_radius_m
    return np.nonzero(mask)[0].astype(np.int32)


def springs_across(start: Sequence[float], end: Sequence[float], spring_crossing_a: np.ndarray,
                   spring_crossing_b: np.ndarray, crossing_i: np.ndarray, crossing_j: np.ndarray) -> np.ndarray:
    """Springs whose rest segment meets the line from `start` to `end` ([i, j] in yarn indices, the
    grid coordinates of crossing (i, j) = (crossing_i[c], crossing_j[c])), ends included: a bool mask
    over the springs. Exact for the half-integer lines that run between yarns."""
    p = np.asarray(start, float)
    d = np.asarray(end, float) - p
    a = np.stack([crossing_i[spring_crossing_a], crossing_j[spring_crossing_a]], axis=1).astype(float)
    e = np.stack([crossing_i[spring_crossing_b], crossing_j[spring_crossing_b]], axis=1).astype(float) - a
    den = d[0] * e[:, 1] - d[1] * e[:, 0]
    w = a - p
    ok = den != 0.0  # parallel segments do not cut each other (a line along a yarn cuts no spring)
    safe = np.where(ok, den, 1.0)
    t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / safe  # along the cut
    u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / safe        # along the spring
    return ok & (t >= 0.0) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)


def _given(local_vars: dict[str, Any]) -> dict[str, Any]:
    """A method's arguments (its locals() on entry) without `self`."""
    return {k: v for k, v in local_vars.items() if k != "self"}


def _parameters(method: Callable) -> list[str]:
    return [p for p in inspect.signature(method).parameters if p != "self"]


def _keys_doc(*tables: str) -> Callable:
    """Append to a method's docstring one line per argument, generated from the keys' declarations
    (so that help() shows each argument's range, default and meaning without a second copy)."""
    def decorate(method: Callable) -> Callable:
        keys = {name: k for t in tables for name, k in schema.TOP[t].items()}
        lines = []
        for name, p in inspect.signature(method).parameters.items():
            if name in keys:
                k = keys[name]
                given = ("" if p.default is inspect.Parameter.empty else
                         ", optional" if p.default is None else f", default {show(p.default)}")
                lines.append(f"            {name}: {k.allowed()}{given}. {k.doc}")
        tables_named = ", ".join(f"[{t}]" for t in tables)
        method.__doc__ = ((method.__doc__ or "").rstrip() + f"\n\n        Arguments (keys of {tables_named}):\n"
                          + "\n".join(lines) + "\n")
        return method
    return decorate


class ModelBuilder:
    """Collects one cloth, its solver settings, rigid bodies and attachments; `finalize()` makes the Model.

    Settings of the cloth that the solver reads (strain limiting, tearing, self-collision) have their
    own `set_*` method, one per scene table; without the call, the scene file's defaults hold
    (strain limit 0.10, no tearing, no self-collision). Seed and gravity are given to the constructor.
    """

    @_keys_doc("scene", "world")
    def __init__(self, *, seed: int = _SCENE["seed"].default,
                 gravity_m_s2: Sequence[float] = _WORLD["gravity_m_s2"].default):
        """A builder with nothing added yet. `seed` seeds every random draw (break strains)."""
        v = self._check("ModelBuilder", {**_SCENE, **_WORLD}, dict(seed=seed, gravity_m_s2=gravity_m_s2))
        self.seed: int = v["seed"]
        self.gravity_m_s2: Vec3 = v["gravity_m_s2"]
        self.cloth: Optional[ClothSpec] = None
        self.strain = StrainSpec()
        self.tearing = TearingSpec()
        self.self_collision = SelfCollisionSpec()
        self.multires = MultiresSpec()
        self.bodies: list[BodySpec] = []
        self.attachments: list[AttachmentSpec] = []
        self.cuts: list[CutSpec] = []
        self.weak_lines: list[WeakLineSpec] = []
        self.seams: list[SeamSpec] = []
        self._panels: list[_Panel] = []
        self._mesh_assets: dict[str, Any] = {}  # mesh body name -> fraytool.scene.mesh_files.MeshAsset

    # --- checking arguments ---------------------------------------------------------------------------

    @staticmethod
    def _raise(method: str, problems: list[rules.Problem]) -> None:
        if problems:
            where = method if method == "ModelBuilder" else f"ModelBuilder.{method}"
            raise ModelBuilderError([f"{where}: {allowed}" if key is None
                                     else f"{where}: {key} = {show(value)}: {allowed}"
                                     for key, value, allowed in problems])

    def _check(self, method: str, keys: dict[str, Key], args: dict[str, Any]) -> dict[str, Any]:
        """Convert every argument against its key; raise one error listing every bad one."""
        out, problems = {}, []
        for name, value in args.items():
            k = keys[name]
            if value is None and k.default is None:  # an optional key left out
                out[name] = None
                continue
            ok, converted = k.convert(value)
            if ok:
                out[name] = converted
            else:
                problems.append((name, value, k.explain()))
        self._raise(method, problems)
        return out

    # --- the cloth and its solver settings ----------------------------------------------------------

    @_keys_doc("cloth", "cloth.springs")
    def add_cloth(self, *, spacing_m: float, thickness_m: float,
                  mass_per_crossing_kg: float, structural_n_per_m: float,
                  warp_yarns: int = _CLOTH["warp_yarns"].default, weft_yarns: int = _CLOTH["weft_yarns"].default,
                  outline_m: Sequence[Sequence[float]] = _CLOTH["outline_m"].default,
                  mask: str = _CLOTH["mask"].default,
                  mask_size_m: Sequence[float] = _CLOTH["mask_size_m"].default,
                  grain_deg: float = _CLOTH["grain_deg"].default,
                  edge: str = _CLOTH["edge"].default,
                  tear_map: str = _CLOTH["tear_map"].default,
                  tear_map_strain: Sequence[float] = _CLOTH["tear_map_strain"].default,
                  origin_m: Sequence[float] = _CLOTH["origin_m"].default,
                  plane: str = _CLOTH["plane"].default,
                  weave: str = _CLOTH["weave"].default,
                  twill: str = _CLOTH["twill"].default,
                  satin_shafts: int = _CLOTH["satin_shafts"].default,
                  table: Optional[Sequence[Sequence[int]]] = _CLOTH["table"].default,
                  bend_n_per_m: float = _SPRINGS["bend_n_per_m"].default,
                  shear_n_per_m: float = _SPRINGS["shear_n_per_m"].default,
                  damping: float = _SPRINGS["damping"].default,
                  name: str = "", rotation_deg: Sequence[float] = _CLOTH["rotation_deg"].default,
                  wrap_radius_m: float = _CLOTH["wrap_radius_m"].default,
                  warp_color: Optional[Sequence[float]] = None, weft_color: Optional[Sequence[float]] = None) -> None:
        """The woven cloth: a grid of warp_yarns x weft_yarns crossings, spacing_m apart, in `plane`
        from `origin_m`, with its weave and springs ([cloth] and [cloth.springs]); or a panel cut from
        that grid by `outline_m` (a polygon in the plane [m]) or `mask` (a greyscale image file), its
        weave turned by `grain_deg` (docs/panels.md). The first panel; add_panel adds more."""
        if self._panels:
            self._raise("add_cloth", [(None, None, "add_cloth makes the first panel and was already called; "
                                                   "add_panel adds more")])
        self._add_panel("add_cloth", _given(locals()))

    @_keys_doc("cloth", "cloth.springs")
    def add_panel(self, name: str, *, spacing_m: float, thickness_m: float,
                  mass_per_crossing_kg: float, structural_n_per_m: float,
                  warp_yarns: int = _CLOTH["warp_yarns"].default, weft_yarns: int = _CLOTH["weft_yarns"].default,
                  outline_m: Sequence[Sequence[float]] = _CLOTH["outline_m"].default,
                  mask: str = _CLOTH["mask"].default,
                  mask_size_m: Sequence[float] = _CLOTH["mask_size_m"].default,
                  grain_deg: float = _CLOTH["grain_deg"].default,
                  edge: str = _CLOTH["edge"].default,
                  tear_map: str = _CLOTH["tear_map"].default,
                  tear_map_strain: Sequence[float] = _CLOTH["tear_map_strain"].default,
                  origin_m: Sequence[float] = _CLOTH["origin_m"].default,
                  plane: str = _CLOTH["plane"].default,
                  weave: str = _CLOTH["weave"].default,
                  twill: str = _CLOTH["twill"].default,
                  satin_shafts: int = _CLOTH["satin_shafts"].default,
                  table: Optional[Sequence[Sequence[int]]] = _CLOTH["table"].default,
                  bend_n_per_m: float = _SPRINGS["bend_n_per_m"].default,
                  shear_n_per_m: float = _SPRINGS["shear_n_per_m"].default,
                  damping: float = _SPRINGS["damping"].default,
                  rotation_deg: Sequence[float] = _CLOTH["rotation_deg"].default,
                  wrap_radius_m: float = _CLOTH["wrap_radius_m"].default,
                  warp_color: Optional[Sequence[float]] = None, weft_color: Optional[Sequence[float]] = None) -> None:
        """One more cloth panel ([[cloth]] written again; docs/panels.md), with its own shape, weave, springs,
        mass, place and colours. Every panel shares the first's spacing_m, thickness_m, damping and solver
        settings; panels collide with each other through self-collision and are joined by add_seam."""
        if not self._panels:
            self._raise("add_panel", [(None, None, "call add_cloth first (the first panel)")])
        self._add_panel("add_panel", _given(locals()))

    def _add_panel(self, method: str, args: dict) -> None:
        v = self._check(method, {**_CLOTH, **_SPRINGS}, args)
        table, problems = rules.weave_table(v["weave"], v["twill"], v["satin_shafts"], v["table"])
        self._raise(method, problems + rules.cloth_problems(v["spacing_m"], v["thickness_m"])
                    + rules.wrap_problems(v["spacing_m"], v["wrap_radius_m"])
                    + rules.cloth_shape_problems(v["warp_yarns"], v["weft_yarns"], v["outline_m"], v["mask"],
                                                 v["mask_size_m"], v["grain_deg"])
                    + rules.tear_map_problems(v["tear_map"], v["tear_map_strain"]))
        springs = SpringSpec(**{k: v.pop(k) for k in _SPRINGS})
        del v["table"]
        v["name"] = v["name"] or ("cloth" if not self._panels else f"cloth{len(self._panels)}")
        # strain and tearing are set apart (set_strain_limit, set_tearing); finalize() reads those.
        cloth = ClothSpec(**v, weave_table=table, springs=springs)
        try:
            shape = panel_shape(cloth)
            tear_map = tear_map_image(cloth) if cloth.tear_map else None
        except PanelShapeError as exc:
            self._raise(method, exc.problems)
        first = self._panels[0].spec if self._panels else None
        if first is not None:
            shared = [(k, getattr(cloth, k), f"every panel shares the first panel's {k} = {getattr(first, k):g}")
                      for k in ("spacing_m", "thickness_m") if getattr(cloth, k) != getattr(first, k)]
            if springs.damping != first.springs.damping:
                shared.append(("damping", springs.damping, f"every panel shares the first panel's damping = "
                                                            f"{first.springs.damping:g}"))
            if cloth.name in self.panel_names:
                shared.append(("name", cloth.name, "must be unique among the panels"))
            self._raise(method, shared)
        if cloth.outline_m or cloth.mask:  # the shape sets the grid
            cloth = dataclasses.replace(cloth, warp_yarns=shape.warp_yarns, weft_yarns=shape.weft_yarns)
        self._panels.append(_Panel(cloth, shape, tear_map))
        if first is None:
            self.cloth = cloth

    @property
    def panel_names(self) -> list[str]:
        return [p.spec.name for p in self._panels]

    def _panel_index(self, method: str, name: str) -> int:
        """Index of the panel called `name` ("": the first)."""
        if not name:
            return 0
        if name not in self.panel_names:
            self._raise(method, [("panel", name, "must name one of the panels: " + ", ".join(self.panel_names))])
        return self.panel_names.index(name)

    @_keys_doc("cloth.strain")
    def set_strain_limit(self, *, limit: float = _STRAIN["limit"].default,
                         max_iterations: int = _STRAIN["max_iterations"].default,
                         tolerance: float = _STRAIN["tolerance"].default,
                         stiffness_n_per_m: float = _STRAIN["stiffness_n_per_m"].default,
                         damping_ratio: float = _STRAIN["damping_ratio"].default) -> None:
        """Strain limiting of structural springs (docs/method.md §4.1), as [cloth.strain]."""
        strain = StrainSpec(**self._check("set_strain_limit", _STRAIN, _given(locals())))
        self._raise("set_strain_limit", rules.strain_problems(strain))
        self.strain = strain

    @_keys_doc("cloth.tearing")
    def set_tearing(self, *, enabled: bool = True, yarn_level: bool = _TEARING["yarn_level"].default,
                    transition_strain: float = _TEARING["transition_strain"].default,
                    propagation: str = _TEARING["propagation"].default,
                    ineffective_length: int = _TEARING["ineffective_length"].default,
                    break_strain: float = _TEARING["break_strain"].default,
                    break_strain_spread: float = _TEARING["break_strain_spread"].default,
                    disconnect_factor: float = _TEARING["disconnect_factor"].default) -> None:
        """Tearing, as [cloth.tearing]. Calling it turns tearing on (enabled=False turns it off again);
        without the call the cloth does not tear."""
        t = TearingSpec(**self._check("set_tearing", _TEARING, _given(locals())))
        self._raise("set_tearing", rules.tearing_problems(t))
        self.tearing = t

    @_keys_doc("cloth.multires")
    def set_multires(self, *, factor: int = _MULTIRES["factor"].default,
                     refine_fraction: float = _MULTIRES["refine_fraction"].default,
                     band_cells: int = _MULTIRES["band_cells"].default,
                     refine_near_bodies: bool = _MULTIRES["refine_near_bodies"].default) -> None:
        """A coarse base model where the cloth is whole, refined ahead of tearing, as [cloth.multires]
        (docs/multires.md); without the call (or with factor = 1) the cloth is at yarn resolution everywhere."""
        m = MultiresSpec(**self._check("set_multires", _MULTIRES, _given(locals())))
        self._raise("set_multires", rules.multires_problems(m))
        self.multires = m

    @_keys_doc("self_collision")
    def set_self_collision(self, *, enabled: bool = True, iterations: int = _SELF["iterations"].default,
                           friction: float = _SELF["friction"].default) -> None:
        """Edge-edge self-collision between yarn segments (docs/method.md §4.2), as [self_collision]. Calling
        it turns self-collision on (enabled=False turns it off again); without the call it is off."""
        self.self_collision = SelfCollisionSpec(**self._check("set_self_collision", _SELF, _given(locals())))

    # --- rigid bodies -------------------------------------------------------------------------------

    def _add_body(self, method: str, shape: str, args: dict[str, Any]) -> int:
        v = self._check(method, _BODY, args)
        body = BodySpec(shape=shape, **v)
        self._raise(method, rules.body_name_problems(body.name, (b.name for b in self.bodies))
                    + rules.body_problems(body))
        self.bodies.append(body)
        return len(self.bodies) - 1

    @_keys_doc("bodies")
    def add_sphere(self, name: str, *, radius_m: float,
                   position_m: Sequence[float] = _BODY["position_m"].default,
                   rotation_deg: Sequence[float] = _BODY["rotation_deg"].default,
                   motion: str = _BODY["motion"].default,
                   velocity_m_s: Sequence[float] = _BODY["velocity_m_s"].default,
                   path: Sequence[Sequence[float]] = _BODY["path"].default,
                   path_rotation_deg: Sequence[Sequence[float]] = _BODY["path_rotation_deg"].default,
                   path_quaternion: Sequence[Sequence[float]] = _BODY["path_quaternion"].default,
                   interpolation: str = _BODY["interpolation"].default,
                   mass_kg: float = _BODY["mass_kg"].default,
                   gravity: bool = _BODY["gravity"].default,
                   friction: float = _BODY["friction"].default,
                   collide: bool = _BODY["collide"].default,
                   start_s: float = _BODY["start_s"].default) -> int:
        """A rigid sphere of radius_m centred at position_m; returns its body index."""
        return self._add_body("add_sphere", "sphere", _given(locals()))

    @_keys_doc("bodies")
    def add_box(self, name: str, *, half_extents_m: Sequence[float],
                position_m: Sequence[float] = _BODY["position_m"].default,
                rotation_deg: Sequence[float] = _BODY["rotation_deg"].default,
                motion: str = _BODY["motion"].default,
                velocity_m_s: Sequence[float] = _BODY["velocity_m_s"].default,
                path: Sequence[Sequence[float]] = _BODY["path"].default,
                path_rotation_deg: Sequence[Sequence[float]] = _BODY["path_rotation_deg"].default,
                path_quaternion: Sequence[Sequence[float]] = _BODY["path_quaternion"].default,
                interpolation: str = _BODY["interpolation"].default,
                mass_kg: float = _BODY["mass_kg"].default,
                gravity: bool = _BODY["gravity"].default,
                friction: float = _BODY["friction"].default,
                collide: bool = _BODY["collide"].default,
                start_s: float = _BODY["start_s"].default) -> int:
        """A rigid box (a bar is a long thin box) centred at position_m; returns its body index."""
        return self._add_body("add_box", "box", _given(locals()))

    @_keys_doc("bodies")
    def add_plane(self, name: str, *, normal: Sequence[float] = _BODY["normal"].default,
                  position_m: Sequence[float] = _BODY["position_m"].default,
                  rotation_deg: Sequence[float] = _BODY["rotation_deg"].default,
                  motion: str = _BODY["motion"].default,
                  velocity_m_s: Sequence[float] = _BODY["velocity_m_s"].default,
                  path: Sequence[Sequence[float]] = _BODY["path"].default,
                  path_rotation_deg: Sequence[Sequence[float]] = _BODY["path_rotation_deg"].default,
                  path_quaternion: Sequence[Sequence[float]] = _BODY["path_quaternion"].default,
                  interpolation: str = _BODY["interpolation"].default,
                  friction: float = _BODY["friction"].default,
                  collide: bool = _BODY["collide"].default,
                  start_s: float = _BODY["start_s"].default) -> int:
        """An infinite plane through position_m, free side towards `normal` (static or kinematic);
        returns its body index."""
        return self._add_body("add_plane", "plane", _given(locals()))

    @_keys_doc("bodies")
    def add_mesh(self, name: str, *, file: Optional[str] = None, prim: str = _BODY["prim"].default,
                 vertices_m: Optional[np.ndarray] = None, triangles: Optional[np.ndarray] = None,
                 key_times_s: Optional[Sequence[float]] = None,
                 scale: Sequence[float] = _BODY["scale"].default,
                 frame_time_s: float = _BODY["frame_time_s"].default,
                 sequence_start_s: float = _BODY["sequence_start_s"].default,
                 position_m: Sequence[float] = _BODY["position_m"].default,
                 rotation_deg: Sequence[float] = _BODY["rotation_deg"].default,
                 motion: str = _BODY["motion"].default,
                 velocity_m_s: Sequence[float] = _BODY["velocity_m_s"].default,
                 path: Sequence[Sequence[float]] = _BODY["path"].default,
                 path_rotation_deg: Sequence[Sequence[float]] = _BODY["path_rotation_deg"].default,
                 path_quaternion: Sequence[Sequence[float]] = _BODY["path_quaternion"].default,
                 interpolation: str = _BODY["interpolation"].default,
                 friction: float = _BODY["friction"].default,
                 collide: bool = _BODY["collide"].default,
                 start_s: float = _BODY["start_s"].default) -> int:
        """A triangle mesh (static or kinematic; docs/meshes.md) from `file` (OBJ, PLY, STL, glTF/GLB, a
        numbered sequence walk.####.obj with frame_time_s seconds between files, or USD with `prim`) or
        from arrays: `vertices_m` (V, 3), or (K, V, 3) keys at `key_times_s`, and `triangles` (T, 3).
        An animated mesh's first key is at scene time start_s + sequence_start_s.
        Its vertices, times `scale`, are in the body's frame: position_m and rotation_deg place it.
        Returns its body index."""
        args = _given(locals())
        from fraytool.scene import mesh_files

        for k in ("vertices_m", "triangles", "key_times_s"):
            args.pop(k, None)
        if (file is None) == (vertices_m is None):
            self._raise("add_mesh", [(None, None, "give either file or vertices_m and triangles")])
        try:
            if file is not None:
                path = mesh_files.resolve(str(file), "")
                problems = mesh_files.file_problems(str(path), prim, "")
                if problems:
                    self._raise("add_mesh", problems)
                if mesh_files.is_sequence(path) and frame_time_s <= 0.0:
                    self._raise("add_mesh", [("frame_time_s", frame_time_s, "a sequence needs the seconds "
                                              "between its files (> 0)")])
                asset = mesh_files.read_asset(path, prim, frame_time_s or 1.0)
            else:
                asset = mesh_files.asset_from_arrays(vertices_m, triangles, key_times_s)
        except mesh_files.MeshFileError as exc:
            raise ModelBuilderError([f"ModelBuilder.add_mesh: {exc}"]) from None
        args["file"] = str(file) if file is not None else "<arrays>"
        index = self._add_body("add_mesh", "mesh", args)
        self._mesh_assets[self.bodies[index].name] = asset
        return index

    @_keys_doc("attachments")
    def add_attachment(self, body: str | int, *, panel: str = "", edge: Optional[str] = None, corner: Optional[str] = None,
                       corner_size: int = _ATTACH["corner_size"].default,
                       warp_range: Optional[Sequence[int]] = None, weft_range: Optional[Sequence[int]] = None,
                       region_center_m: Optional[Sequence[float]] = None,
                       region_radius_m: float = _ATTACH["region_radius_m"].default) -> None:
        """Cloth masses held by a body (its name or index): give exactly one selection. They follow the
        body exactly; a crossing held twice keeps its first holder. Call after add_cloth and the body."""
        args = _given(locals())
        if self.cloth is None:
            self._raise("add_attachment", [(None, None, "call add_cloth first (selections are on its grid)")])
        if isinstance(body, int) and not isinstance(body, bool):
            if not 0 <= body < len(self.bodies):
                self._raise("add_attachment", [("body", body, f"no body has this index ({len(self.bodies)} added)")])
            args["body"] = self.bodies[body].name
        att = AttachmentSpec(**self._check("add_attachment", _ATTACH, args))
        c = self._panels[self._panel_index("add_attachment", att.panel)].spec
        self._raise("add_attachment", rules.attachment_problems(att, (b.name for b in self.bodies),
                                                                c.warp_yarns, c.weft_yarns))
        self.attachments.append(att)

    @_keys_doc("cuts")
    def add_cut(self, *, panel: str = "", start: Optional[Sequence[float]] = None, end: Optional[Sequence[float]] = None,
                path_m: Sequence[Sequence[float]] = _CUT["path_m"].default,
                start_s: float = _CUT["start_s"].default, end_s: float = _CUT["end_s"].default) -> None:
        """A snip made before the shot: every spring whose rest segment meets the line from `start`
        to `end` (yarn indices [i, j]; half-integers fall between yarns) is absent from the first
        frame on. It is not a break (`broken_springs` does not count it), and its yarn ends are
        drawn clean, not frayed. Or scissors: `path_m`, a polyline in the cloth's plane [m] (as
        outline_m), cut from its first point at start_s to its last at end_s (needs tearing on).
        Call after add_cloth."""
        if self.cloth is None:
            self._raise("add_cut", [(None, None, "call add_cloth first (cuts are on its grid)")])
        cut = CutSpec(**self._check("add_cut", _CUT, _given(locals())))
        c = self._panels[self._panel_index("add_cut", cut.panel)].spec
        self._raise("add_cut", rules.cut_problems(cut, c.warp_yarns, c.weft_yarns))
        self.cuts.append(cut)

    @_keys_doc("weak_lines")
    def add_weak_line(self, *, points_m: Sequence[Sequence[float]], width_m: float,
                      factor: float = _WEAK["factor"].default, panel: str = "") -> None:
        """A weaker band along a polyline in the cloth's plane [m] (as outline_m), like a perforation:
        the yarn springs whose middle lies within width_m / 2 of it break at `factor` x their drawn
        break strain (docs/panels.md "Tear control"). Call after add_cloth."""
        if self.cloth is None:
            self._raise("add_weak_line", [(None, None, "call add_cloth first (weak lines are in its plane)")])
        line = WeakLineSpec(**self._check("add_weak_line", _WEAK, _given(locals())))
        self._panel_index("add_weak_line", line.panel)
        self._raise("add_weak_line", rules.weak_line_problems(line))
        self.weak_lines.append(line)

    @_keys_doc("seams")
    def add_seam(self, *, panel_a: str, segment_a: int, panel_b: str, segment_b: int, stitch_spacing_m: float,
                 stiffness_n_per_m: float, break_strain: float,
                 stitch_length_m: float = _SEAM["stitch_length_m"].default,
                 reverse: bool = _SEAM["reverse"].default) -> None:
        """Stitches along segment_a of panel_a's outline to segment_b of panel_b's, every stitch_spacing_m:
        threads of stiffness_n_per_m that pull (never push) and break one by one past their strain
        (docs/panels.md "Seams"). Call after the panels."""
        seam = SeamSpec(**self._check("add_seam", _SEAM, _given(locals())))
        a = self._panels[self._panel_index("add_seam", seam.panel_a)]
        b = self._panels[self._panel_index("add_seam", seam.panel_b)]
        from fraytool.scene.load import seam_problems

        self._raise("add_seam", seam_problems(seam, a.spec, b.spec))
        self.seams.append(seam)

    # --- finalize -------------------------------------------------------------------------------------

    def _grid(self):
        """The panels laid on one grid, block-diagonally (panel p's grid in rows and columns of its own, so no
        spring joins two panels): (crossing grid (ny, nx) -> crossing or -1, each panel's grid offset (I, J),
        and per crossing: its panel, its place in the plane (C, 2) [m], rest position (C, 3), weft on top).
        Crossings are numbered row by row, so each panel's are consecutive (for one rectangle, c = j * nx + i)."""
        nx = sum(p.shape.warp_yarns for p in self._panels)
        ny = sum(p.shape.weft_yarns for p in self._panels)
        grid = np.full((ny, nx), -1, np.int64)
        offsets = []
        I = J = 0
        for p in self._panels:
            h, w = p.shape.present.shape
            grid[J:J + h, I:I + w][p.shape.present] = len(offsets)  # the panel's index, for now
            offsets.append((I, J))
            I, J = I + w, J + h
        panel = grid[grid >= 0].astype(np.int32)
        grid[grid >= 0] = np.arange(panel.size)
        uv = np.concatenate([p.shape.uv_m[p.shape.present] for p in self._panels])
        rest = np.concatenate([_panel_rest(p.spec, p.shape.uv_m[p.shape.present]) for p in self._panels])
        top = []
        for p in self._panels:
            jj, ii = np.nonzero(p.shape.present)
            table = np.asarray(p.spec.weave_table, dtype=bool)
            top.append(table[jj % table.shape[0], ii % table.shape[1]])
        return grid, offsets, panel, uv, rest, np.concatenate(top)

    @staticmethod
    def _springs(k: dict[str, np.ndarray], grid: np.ndarray, rest: np.ndarray):
        """Springs between crossings of `grid` (ny, nx; -1 where the panel has no crossing): a spring is
        built where all the crossings it joins or spans are there (a bend over its middle crossing, a
        shear spring over its whole cell), and where its kind's stiffness at its first crossing
        (`k[name][c]`, [cloth.springs] of the crossing's panel) is above 0."""
        ny, nx = grid.shape
        parts: list[tuple[int, np.ndarray, np.ndarray, float]] = []
        count = 0
        weft_struct = np.full((ny, max(nx - 1, 0)), -1, np.int32)
        warp_struct = np.full((nx, max(ny - 1, 0)), -1, np.int32)

        def add(kind, a, b, ks, *also):
            """Springs a-b of grid places (arrays of crossings, -1 for none) where a, b and `also` exist and
            the stiffness ks (per crossing) at a is above 0; returns their slots, -1 where not built, in
            the shape of a."""
            nonlocal count
            ok = (a >= 0) & (b >= 0)
            for x in also:
                ok &= x >= 0
            ok &= ks[np.maximum(a, 0)] > 0
            slots = np.full(a.shape, -1, np.int32)
            a, b = np.asarray(a[ok], np.int32).ravel(), np.asarray(b[ok], np.int32).ravel()
            parts.append((kind, a, b, ks[a]))
            count += a.size
            slots[ok] = np.arange(count - a.size, count, dtype=np.int32)
            return slots

        g = grid
        weft_struct[:, :] = add(STRUCT_WEFT, g[:, :-1], g[:, 1:], k["structural_n_per_m"])
        warp_struct[:, :] = add(STRUCT_WARP, g[:-1, :].T, g[1:, :].T, k["structural_n_per_m"])
        if (k["bend_n_per_m"] > 0).any():
            add(BEND_WEFT, g[:, :-2], g[:, 2:], k["bend_n_per_m"], g[:, 1:-1])
            add(BEND_WARP, g[:-2, :].T, g[2:, :].T, k["bend_n_per_m"], g[1:-1, :].T)
        shear_twin_pairs = None
        if (k["shear_n_per_m"] > 0).any():
            cell = (g[:-1, :-1], g[:-1, 1:], g[1:, :-1], g[1:, 1:])  # (i, j), (i+1, j), (i, j+1), (i+1, j+1)
            s1 = add(SHEAR, cell[0], cell[3], k["shear_n_per_m"], cell[1], cell[2])
            s2 = add(SHEAR, cell[1], cell[2], k["shear_n_per_m"], cell[0], cell[3])
            s1, s2 = s1[s1 >= 0], s2[s2 >= 0]
            shear = np.concatenate([s1, s2])
            twins = add(SHEAR_TWIN, np.concatenate([parts[-2][1], parts[-1][1]]),
                        np.concatenate([parts[-2][2], parts[-1][2]]), 0.5 * k["shear_n_per_m"])
            shear_twin_pairs = (shear, twins)
        kind = np.concatenate([np.full(p[1].size, p[0], np.int8) for p in parts]) if parts else np.zeros(0, np.int8)
        a = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0, np.int32)
        b = np.concatenate([p[2] for p in parts]) if parts else np.zeros(0, np.int32)
        stiff = np.concatenate([np.asarray(p[3], float) for p in parts]) if parts else np.zeros(0)
        twin = np.full(count, -1, np.int32)
        if shear_twin_pairs is not None:
            twin[shear_twin_pairs[0]] = shear_twin_pairs[1]
            twin[shear_twin_pairs[1]] = shear_twin_pairs[0]
        rest_len = np.linalg.norm(rest[b] - rest[a], axis=1)
        return kind, a, b, stiff, rest_len, twin, weft_struct, warp_struct

    def _break_strains(self, count: int, spring_uv_m: np.ndarray, spring_panel: np.ndarray) -> tuple:
        """Per-spring break strain ~ Normal(mean, spread), clipped above the transition strain. The mean is
        break_strain, or the tear map's value under the spring's middle (`spring_uv_m`, in the cloth's
        plane); a weak line then scales the draw (docs/panels.md "Tear control"). Returns (break strains, the
        last weak line that weakened each spring or -1; empty without weak lines).

        The floor does not depend on yarn_level, so a base-model-only run of a scene (yarn_level =
        false, for comparison) tears a cloth with exactly the same break strains."""
        t = self.tearing
        rng = np.random.default_rng(self.seed)
        mean: float | np.ndarray = t.break_strain
        for k, p in enumerate(self._panels):
            if p.tear_map is not None:
                lo, hi = p.spec.tear_map_strain
                on = spring_panel == k
                mean = np.full(count, t.break_strain) if np.isscalar(mean) else mean
                mean[on] = lo + (hi - lo) * sample_map(p.tear_map, p.shape.extent_uv_m, spring_uv_m[on])
        draw = mean + t.break_strain_spread * rng.standard_normal(count)
        weak_line = np.full(count if self.weak_lines else 0, -1, np.int32)
        for index, line in enumerate(self.weak_lines):
            on = spring_panel == self._panel_index("finalize", line.panel)
            near = on & (distance_to_polyline(spring_uv_m, np.asarray(line.points_m, float)) <= 0.5 * line.width_m)
            draw[near] *= line.factor
            weak_line[near] = index
        floor = t.transition_strain * 1.01 if t.transition_strain < t.break_strain else 1e-3
        self._rng = rng  # the seams' stitches draw theirs next, from the same stream
        return np.maximum(draw, floor), weak_line

    def _scissor_times(self, kind: np.ndarray, a: np.ndarray, b: np.ndarray, uv: np.ndarray,
                       crossing_panel: np.ndarray) -> np.ndarray:
        """When scissors ([[cuts]] path_m) cut each structural spring [s]; inf for never, shape (S,)."""
        out = np.full(kind.shape[0], np.inf)
        for cut in self.cuts:
            if not cut.path_m:
                continue
            on = crossing_panel[a] == self._panel_index("finalize", cut.panel)
            structural = np.flatnonzero(((kind == STRUCT_WEFT) | (kind == STRUCT_WARP)) & on)
            f = crossing_fraction_along(uv[a[structural]], uv[b[structural]], np.asarray(cut.path_m, float))
            hit = ~np.isnan(f)
            times = cut.start_s + f[hit] * (cut.end_s - cut.start_s)
            out[structural[hit]] = np.minimum(out[structural[hit]], times)
        return out

    def _stitches(self, uv: np.ndarray, crossing_panel: np.ndarray, border: np.ndarray, rest: np.ndarray):
        """The seams' stitches (docs/panels.md "Seams"), each seam's placed by fraytool.sim.seam_layout.stitch_pairs.
        Returns (a, b, rest length [m], stiffness [N/m], break strain, seam index, whether each seam sewn the
        other way round would start within its break strain), the break strains drawn after the cloth's
        from the same seeded stream."""
        out_a, out_b, out_rest, out_k, out_break, out_seam, reverse_fits = [], [], [], [], [], [], []
        for index, seam in enumerate(self.seams):
            pa, pb = self._panel_index("finalize", seam.panel_a), self._panel_index("finalize", seam.panel_b)
            pair = stitch_pairs(self._panels[pa].shape.outline_uv_m, seam.segment_a, pa,
                                self._panels[pb].shape.outline_uv_m, seam.segment_b, pb, seam.reverse,
                                seam.stitch_spacing_m, uv, crossing_panel, border, self.cloth.spacing_m)
            out_a.append(pair[:, 0])
            out_b.append(pair[:, 1])
            length = seam.stitch_length_m or self.cloth.spacing_m
            out_rest.append(np.full(len(pair), length))
            out_k.append(np.full(len(pair), seam.stiffness_n_per_m))
            draw = seam.break_strain + self.tearing.break_strain_spread * self._rng.standard_normal(len(pair))
            out_break.append(np.maximum(draw, 1e-3))
            out_seam.append(np.full(len(pair), index, np.int32))
            # the facts of the start warning (fraytool.sim.seam_layout), at hand here: the other way round
            flipped = stitch_pairs(self._panels[pa].shape.outline_uv_m, seam.segment_a, pa,
                                   self._panels[pb].shape.outline_uv_m, seam.segment_b, pb, not seam.reverse,
                                   seam.stitch_spacing_m, uv, crossing_panel, border, self.cloth.spacing_m)
            flipped_m = np.linalg.norm(rest[flipped[:, 1]] - rest[flipped[:, 0]], axis=1)
            reverse_fits.append(bool(len(flipped)) and bool(flipped_m.max() <= length * (1.0 + out_break[-1].min())))
        cat = np.concatenate
        return (cat(out_a).astype(np.int32), cat(out_b).astype(np.int32), cat(out_rest), cat(out_k), cat(out_break),
                cat(out_seam), np.asarray(reverse_fits, bool))

    def finalize(self) -> Model:
        """Turn everything added into the immutable Model (typed arrays); the builder can go on."""
        c = self.cloth
        if c is None:
            self._raise("finalize", [(None, None, "no cloth: call add_cloth first")])
        if any(cut.path_m for cut in self.cuts) and not self.tearing.enabled:
            self._raise("finalize", [(None, None, "scissors (add_cut with path_m) cut in the tearing stage: "
                                                  "call set_tearing()")])
        if self.multires.factor > 1 and (c.outline_m or c.mask or len(self._panels) > 1):
            self._raise("finalize", [(None, None, "a shaped panel (outline_m or mask) or several panels are "
                                                  "simulated at yarn resolution: set_multires(factor=1)")])
        grid, offsets, crossing_panel, uv, rest, top = self._grid()
        ny, nx = grid.shape
        n = rest.shape[0]
        crossing_j, crossing_i = (x.astype(np.int32) for x in np.nonzero(grid >= 0))
        per_panel = lambda value: np.array([value(p.spec) for p in self._panels], float)[crossing_panel]
        stiffness = {k: per_panel(lambda c, k=k: getattr(c.springs, k))
                     for k in ("structural_n_per_m", "bend_n_per_m", "shear_n_per_m")}
        kind, a, b, stiff, rest_len, twin, weft_struct, warp_struct = self._springs(stiffness, grid, rest)

        cw = np.full((n, 2), -1, np.int32)
        cv = np.full((n, 2), -1, np.int32)
        s = weft_struct[weft_struct >= 0]
        cw[a[s], 1] = s
        cw[b[s], 0] = s
        s = warp_struct[warp_struct >= 0]
        cv[a[s], 1] = s
        cv[b[s], 0] = s
        # the panel's border: a crossing missing one of its four yarn neighbours
        border = border_crossings(cw, cv)
        hemmed = border & np.array([p.spec.edge == "hemmed" for p in self._panels])[crossing_panel]

        bodies = self.bodies
        names = tuple(bd.name for bd in bodies)
        turning = [_orientation_keys(bd) for bd in bodies]
        rot = np.array([euler_rotation(bd.rotation_deg) if not len(keys) else quat_to_matrix(keys[0, 1:])
                        for bd, keys in zip(bodies, turning)]).reshape(-1, 3, 3)
        normals = np.array([_unit(bd.normal) for bd in bodies]).reshape(-1, 3)
        body_pos0 = np.array([bd.position_m for bd in bodies], float).reshape(-1, 3)
        for k, bd in enumerate(bodies):
            if bd.motion == "kinematic" and bd.path:
                body_pos0[k] = bd.path[0][1:]

        mesh_arrays = _mesh_arrays(bodies, self._mesh_assets)
        mesh_radius = dict(zip(mesh_arrays["mesh_body"].tolist(), _mesh_radii(mesh_arrays)))

        att_p, att_b, att_off, att_selected = [], [], [], []
        for att in self.attachments:
            body = names.index(att.body)
            k = self._panel_index("finalize", att.panel)
            (I, J), (h, w) = offsets[k], self._panels[k].shape.present.shape
            local = grid[J:J + h, I:I + w]
            sel = local[local >= 0][select_crossings(att, w, h, rest[local[local >= 0]], local)]
            att_p.extend(sel.tolist())
            att_selected.append(len(sel))
            att_b.extend([body] * len(sel))
            att_off.extend((rot[body].T @ (rest[sel] - body_pos0[body]).T).T.tolist())
        # A crossing held twice keeps its first holder.
        att_p_arr = np.asarray(att_p, np.int32)
        _, first = np.unique(att_p_arr, return_index=True)
        first = np.sort(first)

        precut = np.zeros(len(kind), dtype=bool)
        for cut in self.cuts:
            if not cut.path_m:
                k = self._panel_index("finalize", cut.panel)
                (I, J) = offsets[k]
                precut |= springs_across(cut.start, cut.end, a, b, crossing_i - I, crossing_j - J) & \
                    (crossing_panel[a] == k)
        precut &= kind != SHEAR_TWIN  # a twin is born with its shear spring; a cut one has none

        t = self.tearing
        strain = self.strain
        break_strain, spring_weak_line = self._break_strains(len(kind), 0.5 * (uv[a] + uv[b]), crossing_panel[a])
        cut_time = self._scissor_times(kind, a, b, uv, crossing_panel)
        spring_seam = np.zeros(0, np.int32)
        seam_reverse_fits = np.zeros(0, bool)
        if self.seams:  # the stitches come after every spring of the cloth
            st_a, st_b, st_rest, st_k, st_break, st_seam, seam_reverse_fits = self._stitches(uv, crossing_panel,
                                                                                              border, rest)
            spring_seam = np.concatenate([np.full(len(kind), -1, np.int32), st_seam])
            if spring_weak_line.size:
                spring_weak_line = np.concatenate([spring_weak_line, np.full(st_a.size, -1, np.int32)])
            kind = np.concatenate([kind, np.full(st_a.size, STITCH, np.int8)])
            a, b = np.concatenate([a, st_a]), np.concatenate([b, st_b])
            rest_len = np.concatenate([rest_len, st_rest])
            stiff = np.concatenate([stiff, st_k])
            twin = np.concatenate([twin, np.full(st_a.size, -1, np.int32)])
            precut = np.concatenate([precut, np.zeros(st_a.size, bool)])
            break_strain = np.concatenate([break_strain, st_break])
            cut_time = np.concatenate([cut_time, np.full(st_a.size, np.inf)])
        if c.edge == "hemmed":  # a hem folds the border over: two layers of yarn hold it
            along_hem = ((kind == STRUCT_WEFT) | (kind == STRUCT_WARP)) & hemmed[a] & hemmed[b]
            break_strain[along_hem] *= 2.0
        # the lowest strain at which a spring could split its crossings or be cut: coarse cells refine
        # at refine_fraction of it (docs/multires.md "When a cell refines")
        structural = (kind == STRUCT_WEFT) | (kind == STRUCT_WARP)
        tear_from = (t.transition_strain if t.yarn_level else float(break_strain[structural].min())) \
            if t.enabled and structural.any() else math.inf
        mr = self.multires
        return Model(
            warp_yarns=nx,
            weft_yarns=ny,
            crossing_count=n,
            spacing_m=c.spacing_m,
            thickness_m=c.thickness_m,
            gravity_m_s2=np.asarray(self.gravity_m_s2, float),
            crossing_mass_kg=per_panel(lambda c: c.mass_per_crossing_kg),
            crossing_rest_position_m=rest,
            crossing_weft_on_top=top,
            crossing_weft_springs=cw,
            crossing_warp_springs=cv,
            crossing_grid_i=crossing_i,
            crossing_grid_j=crossing_j,
            crossing_hemmed=hemmed,
            crossing_plane_uv_m=uv,
            crossing_panel=crossing_panel,
            panel_names=tuple(self.panel_names),
            spring_kind=kind,
            spring_crossing_a=a,
            spring_crossing_b=b,
            spring_rest_length_m=rest_len,
            spring_base_stiffness_n_per_m=stiff,
            spring_break_strain=break_strain,
            spring_twin=twin,
            spring_precut=precut,
            spring_cut_time_s=cut_time,
            weft_structural_spring=weft_struct,
            warp_structural_spring=warp_struct,
            attachment_particle=att_p_arr[first],
            attachment_body=np.asarray(att_b, np.int32)[first],
            attachment_offset_m=np.asarray(att_off, float).reshape(-1, 3)[first],
            body_names=names,
            body_shape=np.array([SHAPE_NAMES.index(bd.shape) for bd in bodies], np.int8),
            body_motion=np.array([MOTION_NAMES.index(bd.motion) for bd in bodies], np.int8),
            body_params=np.array([_body_params(bd, normals[k], mesh_radius.get(k, 0.0), mesh_arrays, k)
                                  for k, bd in enumerate(bodies)], float).reshape(-1, 3),
            body_rotation=rot,
            body_mass_kg=np.array([bd.mass_kg for bd in bodies], float),
            body_gravity=np.array([bd.gravity for bd in bodies], bool),
            body_friction=np.array([bd.friction for bd in bodies], float),
            body_collide=np.array([bd.collide for bd in bodies], bool),
            body_start_s=np.array([bd.start_s for bd in bodies], float),
            body_initial_position_m=body_pos0,
            body_initial_velocity_m_s=np.array([bd.velocity_m_s for bd in bodies], float).reshape(-1, 3),
            body_path=tuple(np.asarray(bd.path, float).reshape(-1, 4) for bd in bodies),
            body_orientation_path=tuple(turning),
            body_interpolation=tuple(bd.interpolation for bd in bodies),
            **mesh_arrays,
            strain_limit=strain.limit,
            strain_max_iterations=strain.max_iterations,
            strain_tolerance=strain.tolerance,
            strain_stiffness_n_per_m=strain.stiffness_n_per_m,
            strain_damping_n_s_per_m=2.0 * strain.damping_ratio * math.sqrt(strain.stiffness_n_per_m
                                                                            * c.mass_per_crossing_kg),
            damping=c.springs.damping,
            tearing=t.enabled,
            yarn_level=t.enabled and t.yarn_level,
            transition_strain=t.transition_strain,
            propagation_inclusive=t.propagation == "inclusive",
            ineffective_length=t.ineffective_length,
            disconnect_distance_m=t.disconnect_factor * c.thickness_m,
            self_collision=self.self_collision.enabled,
            self_collision_iterations=self.self_collision.iterations,
            self_collision_friction=self.self_collision.friction,
            seed=self.seed,
            coarse_factor=mr.factor,
            refine_strain=mr.refine_fraction * tear_from,
            refine_band_cells=max(mr.band_cells, split_walk_band(top.reshape(ny, nx), mr.factor)) if mr.factor > 1 and n == nx * ny else mr.band_cells,
            refine_near_bodies=mr.refine_near_bodies,
            spring_seam=spring_seam,
            spring_weak_line=spring_weak_line,
            attachment_entry_crossings=np.asarray(att_selected, np.int64),
            seam_reverse_fits=seam_reverse_fits,
        )


def _panel_rest(c: ClothSpec, uv: np.ndarray) -> np.ndarray:
    """World rest positions [m] of a panel's crossings from their places in its plane (u, v) [m]: along the
    plane's axes from origin_m, wrapped around a cylinder of wrap_radius_m (its axis along the second
    axis, the panel bending towards first axis x second axis), then turned by rotation_deg about origin_m."""
    a0, a1 = _PLANE_AXES[c.plane]
    rest = np.zeros((uv.shape[0], 3))
    if c.wrap_radius_m == 0.0 and not any(c.rotation_deg):
        rest[:, a0] = uv[:, 0]
        rest[:, a1] = uv[:, 1]
        return rest + np.asarray(c.origin_m)
    e0, e1 = np.eye(3)[a0], np.eye(3)[a1]
    if c.wrap_radius_m > 0.0:
        r, theta = c.wrap_radius_m, uv[:, 0] / c.wrap_radius_m
        local = (r * np.sin(theta))[:, None] * e0 + uv[:, 1:2] * e1 \
            + (r * (1.0 - np.cos(theta)))[:, None] * np.cross(e0, e1)
    else:
        local = uv[:, 0:1] * e0 + uv[:, 1:2] * e1
    return np.asarray(c.origin_m) + local @ euler_rotation(c.rotation_deg).T


def _orientation_keys(body: BodySpec) -> np.ndarray:
    """A body's orientation keys (t, w, x, y, z), unit and sign-consistent (fraytool.sim.paths), shape (K, 5);
    (0, 5) for a body that does not turn."""
    if body.path_rotation_deg:
        return orientation_keys(body.path_rotation_deg, euler_deg=True)
    if body.path_quaternion:
        return orientation_keys(body.path_quaternion, euler_deg=False)
    return np.zeros((0, 5))


def _body_params(body: BodySpec, unit_normal: np.ndarray, mesh_radius_m: float, mesh_arrays: dict,
                 k: int) -> tuple:
    """A body's parameter vector by its kind (fraytool.sim.kernels.bodies)."""
    if body.shape == "sphere":
        return (body.radius_m, 0.0, 0.0)
    if body.shape == "box":
        return tuple(body.half_extents_m)
    if body.shape == "mesh":
        m = int(np.flatnonzero(mesh_arrays["mesh_body"] == k)[0])
        return (mesh_radius_m, float(mesh_arrays["mesh_closed"][m]), float(m))
    return tuple(unit_normal)  # a plane


def _mesh_arrays(bodies: Sequence[BodySpec], assets: dict) -> dict[str, np.ndarray]:
    """The Model's mesh arrays (fraytool.meshes) from the mesh bodies' assets, scaled, key times from
    the body's start_s + sequence_start_s."""
    from fraytool.meshes import empty_fields

    out = empty_fields()
    meshes = [(k, bd, assets[bd.name]) for k, bd in enumerate(bodies) if bd.shape == "mesh"]
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


def _mesh_radii(mesh_arrays: dict) -> list[float]:
    """Each mesh's bounding radius about its body's centre over all its keys [m]."""
    from fraytool.meshes import MeshTable

    table = MeshTable(mesh_arrays)
    radii = []
    for m in range(table.count):
        r = 0.0
        for k in range(table.key_count(m)):
            r = max(r, float(np.linalg.norm(table.key_vertices(m, k), axis=1).max()))
        radii.append(r)
    return radii


def longest_float(weft_on_top: np.ndarray) -> int:
    """The most consecutive crossings along any yarn where the same yarn stays on top (a float),
    from the weave pattern (crossing_weft_on_top as (weft_yarns, warp_yarns))."""
    longest = 1
    for grid in (weft_on_top, weft_on_top.T):
        for row in grid:
            change = np.flatnonzero(np.diff(row.astype(np.int8)) != 0)
            edges = np.concatenate([[-1], change, [row.size - 1]])
            longest = max(longest, int(np.diff(edges).max()))
    return longest


def split_walk_band(weft_on_top: np.ndarray, factor: int) -> int:
    """Fewest coarse cells of band that hold a split's walk (docs/method.md §3.4: a split runs along the
    yarn up to and including the crossing where the weave flips, up to longest_float + 1 crossings past
    the spring), plus one so that no crossing the walk reaches sits on the border of a coarse cell."""
    return -(-(longest_float(weft_on_top) + 1) // factor) + 1


_SHAPE_METHOD = {"sphere": "add_sphere", "box": "add_box", "plane": "add_plane", "mesh": "add_mesh"}


def _panel_arguments(c: ClothSpec, scene_file: str) -> dict[str, Any]:
    """add_cloth / add_panel arguments of a [cloth] panel, its files found from the scene file."""
    from fraytool.scene.panel_shape import resolve

    args = {k: getattr(c, k) for k in _CLOTH if k != "table"}
    for k in ("mask", "tear_map"):
        args[k] = str(resolve(args[k], scene_file)) if args[k] else ""
    args["table"] = [[int(v) for v in row] for row in c.weave_table] if c.weave == "table" else None
    args.update(dataclasses.asdict(c.springs))
    return args


def build_model(spec: SceneSpec) -> Model:
    """Build the immutable Model of a scene: the ModelBuilder calls that the scene's tables stand for."""
    return scene_builder(spec).finalize()


def scene_builder(spec: SceneSpec) -> ModelBuilder:
    """A ModelBuilder with a scene's tables added, not finalized: add more in code (a mesh, a body), then
    call finalize()."""
    c = spec.cloth
    builder = ModelBuilder(seed=spec.scene.seed, gravity_m_s2=spec.gravity_m_s2)
    for k, panel in enumerate(spec.all_panels):
        args = _panel_arguments(panel, spec.source_file)
        if k == 0:
            builder.add_cloth(**args)
        else:
            # what the panels share is the first panel's (a spec edited in code, as the studies do, edits it there)
            args.update(spacing_m=c.spacing_m, thickness_m=c.thickness_m, damping=c.springs.damping)
            builder.add_panel(args.pop("name"), **args)
    builder.set_strain_limit(**dataclasses.asdict(c.strain))
    builder.set_tearing(**dataclasses.asdict(c.tearing))
    builder.set_self_collision(**dataclasses.asdict(spec.self_collision))
    builder.set_multires(**dataclasses.asdict(c.multires))
    for body in spec.bodies:
        # Each shape's method takes the keys that apply to it (a sphere has no normal, a plane no
        # mass); the others keep their defaults in the Model, where nothing reads them.
        add = getattr(builder, _SHAPE_METHOD[body.shape])
        takes = _parameters(add)
        given = {k: v for k, v in dataclasses.asdict(body).items() if k in takes}
        if body.shape == "mesh":
            from fraytool.scene.mesh_files import frame_time_default, resolve

            given["file"] = str(resolve(body.file, spec.source_file))  # relative to the scene file
            given["frame_time_s"] = body.frame_time_s or frame_time_default(spec)
        add(**given)
    for att in spec.attachments:
        builder.add_attachment(**dataclasses.asdict(att))
    for cut in spec.cuts:
        builder.add_cut(**dataclasses.asdict(cut))
    for line in spec.weak_lines:
        builder.add_weak_line(**dataclasses.asdict(line))
    for seam in spec.seams:
        builder.add_seam(**dataclasses.asdict(seam))
    return builder
