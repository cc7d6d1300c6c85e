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
import typing
from typing import Any, Callable, Optional, Sequence

import numpy as np

from fraytool.errors import SceneError
from fraytool.kinds import SHEAR_TWIN
from fraytool.scene import rules, schema
from fraytool.scene.keys import REQUIRED, Key, show
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
                                       tear_map_image)
from fraytool.sim.attachment_warnings import empty_attachment_warning
from fraytool.sim.body_layout import BodyLayout, body_fields, lay_out_body
from fraytool.sim.cloth_assembly import crossing_fields, is_structural, numbering, spread, spring_fields, with_stitches
from fraytool.sim.model import Model
from fraytool.sim.panel_layout import PanelLayout, lay_out_panel, structural_slots
from fraytool.sim.seam_layout import seam_start_error, seam_start_warning, stitch_pairs

Vec3 = tuple[float, float, float]

_SCENE, _WORLD, _CLOTH, _SPRINGS = (schema.TOP[t] for t in ("scene", "world", "cloth", "cloth.springs"))
_STRAIN, _TEARING, _SELF = (schema.TOP[t] for t in ("cloth.strain", "cloth.tearing", "self_collision"))
_MULTIRES = schema.TOP["cloth.multires"]
_BODY, _ATTACH, _CUT = schema.TOP["bodies"], schema.TOP["attachments"], schema.TOP["cuts"]
_WEAK, _SEAM = schema.TOP["weak_lines"], schema.TOP["seams"]


class ModelBuilderError(SceneError, ValueError):
    """Bad arguments to a ModelBuilder method: one line per problem, "ModelBuilder.method: arg = value:
    what is allowed". A SceneError (exit code 2 from the CLI) and a ValueError (for Python callers)."""


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


PANEL_KEYS: dict[str, Key] = {**_CLOTH, **_SPRINGS}
"""A panel's settings: the keys of [cloth] and [cloth.springs], each with its one declaration."""


def _panel_config_fields() -> list:
    hints = {**typing.get_type_hints(ClothSpec), **typing.get_type_hints(SpringSpec)}
    out = []
    for name, k in PANEL_KEYS.items():
        kind = hints.get(name, Optional[Sequence[Sequence[int]]])  # `table`: the weave repeat as rows of 0 / 1
        out.append((name, kind) if k.default is REQUIRED else (name, kind, dataclasses.field(default=k.default)))
    return out


PanelConfig = dataclasses.make_dataclass("PanelConfig", _panel_config_fields(), frozen=True, kw_only=True)
PanelConfig.__module__ = __name__
PanelConfig.__doc__ = (
    "One panel's settings, as one typed record (the keys of [cloth] and [cloth.springs], docs/scene-format.md; "
    "spacing_m, thickness_m, mass_per_crossing_kg and structural_n_per_m required):\n\n"
    "    shirt = PanelConfig(spacing_m=0.004, thickness_m=0.0008, mass_per_crossing_kg=2e-5, "
    "structural_n_per_m=20.0)\n    builder.add_cloth(shirt, outline_m=front)\n    builder.add_panel(\"back\", shirt, "
    "outline_m=back)\n\nKeywords given to add_cloth / add_panel replace the record's values.\n\n"
    + "\n".join(f"    {name}: {k.allowed()}. {k.doc}" for name, k in PANEL_KEYS.items()))


@dataclasses.dataclass
class _PanelEntry:
    """A panel as added: its layout, and what the cuts added since have done to its springs."""

    layout: PanelLayout
    precut: np.ndarray  # (S,) bool: cut before the shot (add_cut with start and end)
    cut_time_s: np.ndarray  # (S,) when scissors cut the spring; inf for never


@dataclasses.dataclass(frozen=True, eq=False)
class _Held:
    """An attachment as added: the crossings it selected (Model numbering), its body, their offsets in the
    body's frame; on a mesh body, their places on its surface (fraytool.sim.surface_pins)."""

    crossings: np.ndarray
    body: int
    offset_m: np.ndarray
    release_force_n: float = 0.0
    catch_s: float = 0.0
    triangle: Optional[np.ndarray] = None  # the mesh's own triangle numbering
    barycentric: Optional[np.ndarray] = None
    normal_offset_m: Optional[np.ndarray] = None


@dataclasses.dataclass(frozen=True, eq=False)
class _Stitches:
    """A seam as added: its stitches (crossing pairs, Model numbering), their rest length and stiffness, and
    whether sewn the other way round every stitch would start within the seam's break strain."""

    pairs: np.ndarray
    rest_length_m: np.ndarray
    stiffness_n_per_m: np.ndarray
    break_strain: float
    reverse_fits: bool
    sew_s: float = 0.0  # sewn over the shot's first sew_s seconds (0: sewn from the start)
    start_length_m: Optional[np.ndarray] = None  # each stitch's length where the panels are placed


class ModelBuilder:
    """Collects cloth panels, their solver settings, rigid bodies, attachments, cuts, weak lines and seams;
    `finalize()` makes the Model.

    Each add_* does its work when it is called: a panel lays out its crossings and springs, a body its
    frame, an attachment selects its crossings, a cut and a weak line mark the springs they meet, a seam
    places its stitches; a warning is recorded where its facts are at hand (`warnings`, and the Model's
    build_warnings). `finalize()` draws the random break strains (they depend on set_tearing, which may come
    last), concatenates and validates (docs/architecture.md, "Where each derived fact is computed").

    Settings of the cloth that the solver reads (strain limiting, tearing, self-collision) have their
    own `set_*` method, one per scene table; without the call, the scene file's defaults hold
    (strain limit 0.10, no tearing, no self-collision). Seed and gravity are given to the constructor.
    """

    @_keys_doc("scene", "world")
    def __init__(self, *, seed: int = _SCENE["seed"].default,
                 gravity_m_s2: Sequence[float] = _WORLD["gravity_m_s2"].default,
                 gravity_start_s: float = _WORLD["gravity_start_s"].default,
                 wind_m_s: Sequence[float] = _WORLD["wind_m_s"].default,
                 air_density_kg_m3: float = _WORLD["air_density_kg_m3"].default,
                 gust_strength_m_s: float = _WORLD["gust_strength_m_s"].default,
                 gust_length_m: float = _WORLD["gust_length_m"].default,
                 gust_time_s: float = _WORLD["gust_time_s"].default):
        """A builder with nothing added yet. `seed` seeds every random draw (break strains, gusts)."""
        v = self._check("ModelBuilder", {**_SCENE, **_WORLD}, dict(
            seed=seed, gravity_m_s2=gravity_m_s2, gravity_start_s=gravity_start_s, wind_m_s=wind_m_s,
            air_density_kg_m3=air_density_kg_m3, gust_strength_m_s=gust_strength_m_s, gust_length_m=gust_length_m,
            gust_time_s=gust_time_s))
        self.seed: int = v["seed"]
        self.gravity_m_s2: Vec3 = v["gravity_m_s2"]
        self.gravity_start_s: float = v["gravity_start_s"]
        self.air = {k: v[k] for k in ("wind_m_s", "air_density_kg_m3", "gust_strength_m_s", "gust_length_m",
                                      "gust_time_s")}
        """The [world] air keys (docs/wind.md), as given."""
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
        self.warnings: list[str] = []
        """What the builder noticed that no range check can (an attachment holding nothing, a seam that starts
        torn, an open mesh), one line each, naming the entry; the Model keeps them (Model.build_warnings)."""
        self.source = "ModelBuilder"
        """What the warnings name the entries after: the scene file for scene_builder."""
        self.scene_file = ""
        """Files named to add_mesh are found relative to it (scene_builder: the scene file); "" for the
        current directory."""
        self._panels: list[_PanelEntry] = []
        self._bodies: list[BodyLayout] = []
        self._held: list[_Held] = []
        self._weak: list[tuple[int, np.ndarray]] = []  # per weak line: its panel, the panel's springs it weakens
        self._stitches: list[_Stitches] = []

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

    def _entry(self, table: str, index: int) -> str:
        return f"{self.source}: [{table}.{index}]"

    # --- the cloth and its solver settings ----------------------------------------------------------

    def add_cloth(self, config: Optional[PanelConfig] = None, /, **keys: Any) -> int:
        """The woven cloth: a grid of warp_yarns x weft_yarns crossings, spacing_m apart, in `plane`
        from `origin_m`, with its weave and springs ([cloth] and [cloth.springs]); or a panel cut from
        that grid by `outline_m` (a polygon in the plane [m]) or `mask` (a greyscale image file), its
        weave turned by `grain_deg` (docs/panels.md). Its settings: a PanelConfig, keywords (the keys of
        PanelConfig), or both (keywords win). The first panel; add_panel adds more. Returns its index (0)."""
        if self._panels:
            self._raise("add_cloth", [(None, None, "add_cloth makes the first panel and was already called; "
                                                   "add_panel adds more")])
        return self._add_panel("add_cloth", config, keys)

    def add_panel(self, name: str, config: Optional[PanelConfig] = None, /, **keys: Any) -> int:
        """One more cloth panel ([[cloth]] written again; docs/panels.md), with its own shape, weave, springs,
        mass, place and colours, given as for add_cloth. Every panel shares the first's spacing_m, thickness_m,
        damping and solver settings; panels collide with each other through self-collision and are joined by
        add_seam. Returns the panel's index."""
        if not self._panels:
            self._raise("add_panel", [(None, None, "call add_cloth first (the first panel)")])
        return self._add_panel("add_panel", config, {**keys, "name": name})

    def _add_panel(self, method: str, config: Optional[PanelConfig], keys: dict) -> int:
        given = {**(dataclasses.asdict(config) if config is not None else {}), **keys}
        unknown = [k for k in given if k not in PANEL_KEYS]
        missing = [k for k, key in PANEL_KEYS.items() if key.default is REQUIRED and k not in given]
        if unknown or missing:  # as a Python signature would say it
            raise TypeError(f"ModelBuilder.{method}() " + "; ".join(
                ([f"got an unexpected keyword argument {', '.join(map(repr, unknown))}"] if unknown else [])
                + ([f"is missing the required setting {', '.join(map(repr, missing))}"] if missing else []))
                + " (a panel's settings are the fields of PanelConfig: the keys of [cloth] and [cloth.springs])")
        v = self._check(method, PANEL_KEYS, {k: given.get(k, key.default) for k, key in PANEL_KEYS.items()})
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
        first = self._panels[0].layout.spec if self._panels else None
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
        layout = lay_out_panel(cloth, shape, tear_map)
        self._panels.append(_PanelEntry(layout, np.zeros(layout.spring_count, bool),
                                        np.full(layout.spring_count, np.inf)))
        if first is None:
            self.cloth = cloth
        return len(self._panels) - 1

    @property
    def panel_names(self) -> list[str]:
        return [p.layout.spec.name for p in self._panels]

    def _panel_index(self, method: str, name: str) -> int:
        """Index of the panel called `name` ("": the first)."""
        if not name:
            return 0
        if name not in self.panel_names:
            self._raise(method, [("panel", name, "must name one of the panels: " + ", ".join(self.panel_names))])
        return self.panel_names.index(name)

    def _crossing_start(self, panel: int) -> int:
        """The Model's number of panel `panel`'s first crossing (panels keep their numbers as more are added)."""
        return sum(p.layout.crossing_count for p in self._panels[:panel])

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

    def _add_body(self, method: str, shape: str, args: dict[str, Any], mesh=None) -> int:
        v = self._check(method, _BODY, args)
        body = BodySpec(shape=shape, **v)
        self._raise(method, rules.body_name_problems(body.name, (b.name for b in self.bodies))
                    + rules.body_problems(body))
        self.bodies.append(body)
        self._bodies.append(lay_out_body(body, mesh))
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
                path = mesh_files.resolve(str(file), self.scene_file)
                problems = mesh_files.file_problems(str(file), prim, self.scene_file)
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
        index = self._add_body("add_mesh", "mesh", args, mesh=asset)
        if not asset.closed:
            from fraytool.sim.mesh_report import border_edge_count, open_mesh_warning

            self.warnings.append(open_mesh_warning(f"{self._entry('bodies', index)} file = {args['file']!r}",
                                                   border_edge_count(asset.triangles), len(asset.triangles)))
        return index

    @_keys_doc("attachments")
    def add_attachment(self, body: str | int, *, panel: str = "", edge: Optional[str] = None, corner: Optional[str] = None,
                       corner_size: int = _ATTACH["corner_size"].default,
                       warp_range: Optional[Sequence[int]] = None, weft_range: Optional[Sequence[int]] = None,
                       region_center_m: Optional[Sequence[float]] = None,
                       region_radius_m: float = _ATTACH["region_radius_m"].default,
                       release_force_n: float = _ATTACH["release_force_n"].default,
                       catch_s: float = _ATTACH["catch_s"].default) -> None:
        """Cloth masses held by a body (its name or index): give exactly one selection. They follow the
        body exactly; on a mesh body each is pinned to its place on the surface and follows the mesh's
        animation too (fraytool.sim.surface_pins). With release_force_n > 0 a held mass lets go when its pull
        passes that force. With catch_s > 0 the masses are free until then and held from then on where they
        are relative to the body. A crossing held twice keeps its first holder. Call after add_cloth and the
        body."""
        args = _given(locals())
        if self.cloth is None:
            self._raise("add_attachment", [(None, None, "call add_cloth first (selections are on its grid)")])
        if isinstance(body, int) and not isinstance(body, bool):
            if not 0 <= body < len(self.bodies):
                self._raise("add_attachment", [("body", body, f"no body has this index ({len(self.bodies)} added)")])
            args["body"] = self.bodies[body].name
        att = AttachmentSpec(**self._check("add_attachment", _ATTACH, args))
        c = self._panels[self._panel_index("add_attachment", att.panel)].layout.spec
        self._raise("add_attachment", rules.attachment_problems(att, (b.name for b in self.bodies),
                                                                c.warp_yarns, c.weft_yarns))
        k = self._panel_index("add_attachment", att.panel)
        panel = self._panels[k].layout
        h, w = panel.grid.shape
        chosen = select_crossings(att, w, h, panel.rest_m, panel.grid)
        body = [bd.name for bd in self.bodies].index(att.body)
        frame = self._bodies[body]
        offset_m = (frame.rotation.T @ (panel.rest_m[chosen] - frame.initial_position_m).T).T.reshape(-1, 3)
        held = _Held(self._crossing_start(k) + chosen.astype(np.int64), body, offset_m, att.release_force_n,
                     att.catch_s)
        if frame.mesh is not None and chosen.size:
            held = self._pin_to_surface(held, frame, len(self.attachments), att)
        self._held.append(held)
        if not chosen.size:
            self.warnings.append(empty_attachment_warning(self._entry("attachments", len(self.attachments)), att,
                                                          panel))
        self.attachments.append(att)

    def _pin_to_surface(self, held: _Held, frame: BodyLayout, index: int, att: AttachmentSpec) -> _Held:
        """An attachment to a mesh body: each crossing at its place on the mesh's surface (nearest triangle at
        rest; fraytool.sim.surface_pins); refused when the mesh is out of reach of a crossing."""
        from fraytool.sim.surface_pins import REACH_SPACINGS, pin_to_surface

        vertices = frame.mesh.key_vertices[0] * np.asarray(frame.spec.scale, float)
        tri, bary, offset, dist = pin_to_surface(held.offset_m, vertices, frame.mesh.triangles)
        reach_m = REACH_SPACINGS * self.cloth.spacing_m
        if dist.max() > reach_m:
            worst = int(np.argmax(dist))
            raise ModelBuilderError([
                f"{self._entry('attachments', index)} body {att.body!r}: crossing {int(held.crossings[worst])} lies "
                f"{dist[worst]:.4g} m from the mesh's surface, beyond the reach of a surface pin ({REACH_SPACINGS:g} "
                f"yarn spacings = {reach_m:.4g} m): {int((dist > reach_m).sum())} of {dist.size} selected crossings "
                "have no triangle within reach; place the panel on the body or select crossings that touch it"])
        return dataclasses.replace(held, triangle=tri, barycentric=bary, normal_offset_m=offset)

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
        entry = self._panels[self._panel_index("add_cut", cut.panel)]
        p = entry.layout
        self._raise("add_cut", rules.cut_problems(cut, p.spec.warp_yarns, p.spec.weft_yarns))
        if not cut.path_m:  # a twin is born with its shear spring: a cut one has none
            entry.precut |= springs_across(cut.start, cut.end, p.spring_a, p.spring_b, p.crossing_i, p.crossing_j) \
                & (p.spring_kind != SHEAR_TWIN)
        else:
            structural = np.flatnonzero(is_structural(p.spring_kind))
            f = crossing_fraction_along(p.uv_m[p.spring_a[structural]], p.uv_m[p.spring_b[structural]],
                                        np.asarray(cut.path_m, float))
            hit = ~np.isnan(f)
            times = cut.start_s + f[hit] * (cut.end_s - cut.start_s)
            entry.cut_time_s[structural[hit]] = np.minimum(entry.cut_time_s[structural[hit]], times)
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
        k = self._panel_index("add_weak_line", line.panel)
        self._raise("add_weak_line", rules.weak_line_problems(line))
        p = self._panels[k].layout
        self._weak.append((k, distance_to_polyline(p.spring_uv_m, np.asarray(line.points_m, float))
                           <= 0.5 * line.width_m))
        self.weak_lines.append(line)

    @_keys_doc("seams")
    def add_seam(self, *, panel_a: str, segment_a: int, panel_b: str, segment_b: int, stitch_spacing_m: float,
                 stiffness_n_per_m: float, break_strain: float,
                 stitch_length_m: float = _SEAM["stitch_length_m"].default,
                 reverse: bool = _SEAM["reverse"].default, sew_s: float = _SEAM["sew_s"].default) -> None:
        """Stitches along segment_a of panel_a's outline to segment_b of panel_b's, every stitch_spacing_m:
        threads of stiffness_n_per_m that pull (never push) and break one by one past their strain
        (docs/panels.md "Seams"). With sew_s > 0 the panels may lie apart: each stitch is pulled from its
        length where they are placed to stitch_length_m over the first sew_s seconds, and cannot break
        until then (docs/garments.md). Call after the panels."""
        seam = SeamSpec(**self._check("add_seam", _SEAM, _given(locals())))
        a = self._panels[self._panel_index("add_seam", seam.panel_a)]
        b = self._panels[self._panel_index("add_seam", seam.panel_b)]
        from fraytool.scene.load import seam_problems

        self._raise("add_seam", seam_problems(seam, a.layout.spec, b.layout.spec))
        self._stitches.append(self._place_stitches(len(self.seams), seam))
        self.seams.append(seam)

    def _place_stitches(self, index: int, seam: SeamSpec) -> _Stitches:
        """A seam's stitches on the panels as placed (fraytool.sim.seam_layout.stitch_pairs), refused when they
        start too long to sew, and a warning when some start past the seam's break strain."""
        pa, pb = self._panel_index("add_seam", seam.panel_a), self._panel_index("add_seam", seam.panel_b)
        layouts = [p.layout for p in self._panels]
        uv = np.concatenate([p.uv_m for p in layouts])
        rest = np.concatenate([p.rest_m for p in layouts])
        panel_of = np.concatenate([np.full(p.crossing_count, k, np.int32) for k, p in enumerate(layouts)])
        border = np.concatenate([p.border for p in layouts])

        def place(reverse: bool) -> np.ndarray:
            return stitch_pairs(layouts[pa].shape.outline_uv_m, seam.segment_a, pa, layouts[pb].shape.outline_uv_m,
                                seam.segment_b, pb, reverse, seam.stitch_spacing_m, uv, panel_of, border,
                                self.cloth.spacing_m)

        pairs, flipped = place(seam.reverse), place(not seam.reverse)
        rest_m = seam.stitch_length_m or self.cloth.spacing_m
        start_m = np.linalg.norm(rest[pairs[:, 1]] - rest[pairs[:, 0]], axis=1)
        flipped_m = np.linalg.norm(rest[flipped[:, 1]] - rest[flipped[:, 0]], axis=1)
        limit_m = rest_m * (1.0 + seam.break_strain)
        reverse_fits = bool(len(flipped)) and bool(flipped_m.max() <= limit_m)
        where = self._entry("seams", index)
        if seam.sew_s == 0.0:  # a seam sewn over time starts at any length (docs/garments.md)
            error = seam_start_error(where, seam, start_m, rest_m)
            if error:
                raise ModelBuilderError([error])
            line = seam_start_warning(where, seam, start_m, rest_m, limit_m, reverse_fits)
            if line:
                self.warnings.append(line)
        return _Stitches(pairs, np.full(len(pairs), rest_m), np.full(len(pairs), seam.stiffness_n_per_m),
                         seam.break_strain, reverse_fits, seam.sew_s, np.maximum(start_m, rest_m))

    # --- finalize -------------------------------------------------------------------------------------

    def finalize(self) -> Model:
        """Turn everything added into the immutable Model (typed arrays); the builder can go on. Draws the
        break strains, concatenates what each add_* made, and validates the whole."""
        self._validate()
        panels = [p.layout for p in self._panels]
        num = numbering(panels)
        crossings = crossing_fields(panels, num)
        springs = spring_fields(panels, num, crossings["crossing_rest_position_m"])
        cw, cv = structural_slots(crossings["weft_structural_spring"], crossings["warp_structural_spring"],
                                  springs["spring_crossing_a"], springs["spring_crossing_b"], num.crossing_start[-1])
        break_strain, weak_line, stitch_break = self._draw_break_strains(panels, num)
        springs.update(spring_precut=spread(panels, num, [p.precut for p in self._panels], False, bool),
                       spring_cut_time_s=spread(panels, num, [p.cut_time_s for p in self._panels], np.inf, float),
                       spring_break_strain=break_strain, spring_weak_line=weak_line,
                       spring_seam=np.zeros(0, np.int32))
        springs = with_stitches(springs, self._stitches, stitch_break)
        kind, a, b = springs["spring_kind"], springs["spring_crossing_a"], springs["spring_crossing_b"]
        hemmed = crossings["crossing_hemmed"]  # a hem folds the border over: two layers of yarn hold it
        springs["spring_break_strain"][is_structural(kind) & hemmed[a] & hemmed[b]] *= 2.0
        held = [np.concatenate([h.crossings for h in self._held]).astype(np.int32) if self._held
                else np.zeros(0, np.int32)]
        _, first = np.unique(held[0], return_index=True)
        first = np.sort(first)  # a crossing held twice keeps its first holder
        c = self.cloth
        return Model(
            **crossings, **springs, **body_fields(self._bodies), **self._solver_fields(crossings, springs),
            spacing_m=c.spacing_m, thickness_m=c.thickness_m, gravity_m_s2=np.asarray(self.gravity_m_s2, float),
            gravity_start_s=self.gravity_start_s, **self._air_fields(),
            crossing_weft_springs=cw, crossing_warp_springs=cv, panel_names=tuple(self.panel_names),
            attachment_particle=held[0][first],
            attachment_body=np.concatenate([np.full(h.crossings.size, h.body, np.int32) for h in self._held]
                                           + [np.zeros(0, np.int32)])[first],
            attachment_offset_m=np.concatenate([h.offset_m for h in self._held] + [np.zeros((0, 3))])[first],
            attachment_entry_crossings=np.array([h.crossings.size for h in self._held], np.int64),
            **self._surface_fields(first),
            seam_reverse_fits=np.array([s.reverse_fits for s in self._stitches], bool),
            seed=self.seed, build_warnings=tuple(self.warnings + self._scale_warnings(crossings) + self._air_warnings()),
        )

    def _air_fields(self) -> dict:
        """The air's Model fields (docs/wind.md): empty drag arrays where no panel has drag, so a scene without
        wind or drag builds no air stage and keeps its digest."""
        drag = np.array([[p.layout.spec.drag_normal, p.layout.spec.drag_tangential] for p in self._panels], float)
        if not drag.any():
            drag = np.zeros((0, 2))
        return dict(panel_drag_normal=drag[:, 0].copy(), panel_drag_tangential=drag[:, 1].copy(),
                    wind_m_s=np.asarray(self.air["wind_m_s"], float), air_density_kg_m3=self.air["air_density_kg_m3"],
                    gust_strength_m_s=self.air["gust_strength_m_s"], gust_length_m=self.air["gust_length_m"],
                    gust_time_s=self.air["gust_time_s"])

    def _air_warnings(self) -> list[str]:
        """Wind that moves nothing: no panel has drag."""
        windy = any(self.air["wind_m_s"]) or self.air["gust_strength_m_s"] > 0.0
        if windy and not any(p.layout.spec.drag_normal or p.layout.spec.drag_tangential for p in self._panels):
            return [f"{self.source}: [world] wind_m_s or gust_strength_m_s is set but no [cloth] panel has drag_normal "
                    "or drag_tangential above 0: the wind moves nothing"]
        return []

    def _surface_fields(self, first: np.ndarray) -> dict[str, np.ndarray]:
        """The attachments' surface pins and release forces (Model.attachment_triangle ...), in the order of
        attachment_particle; none where every attachment is rigid and never lets go."""
        if not any(h.triangle is not None or h.release_force_n > 0.0 or h.catch_s > 0.0 for h in self._held):
            return {}
        mesh_triangle_start, m = {}, 0
        for k, b in enumerate(self._bodies):
            if b.mesh is not None:
                mesh_triangle_start[k] = m
                m += b.mesh.triangles.shape[0]
        cat = np.concatenate
        n = [h.crossings.size for h in self._held]
        return dict(
            attachment_triangle=cat([h.triangle + mesh_triangle_start[h.body] if h.triangle is not None
                                     else np.full(c, -1, np.int64) for h, c in zip(self._held, n)])[first],
            attachment_barycentric=cat([h.barycentric if h.triangle is not None else np.zeros((c, 3))
                                        for h, c in zip(self._held, n)]).reshape(-1, 3)[first],
            attachment_normal_offset_m=cat([h.normal_offset_m if h.triangle is not None else np.zeros(c)
                                            for h, c in zip(self._held, n)])[first],
            attachment_release_force_n=cat([np.full(c, h.release_force_n) for h, c in zip(self._held, n)])[first],
            attachment_catch_s=cat([np.full(c, h.catch_s) for h, c in zip(self._held, n)])[first],
        )

    def _validate(self) -> None:
        """What only the whole can show: a cloth at all, scissors without tearing, a coarse model with drag."""
        c = self.cloth
        if c is None:
            self._raise("finalize", [(None, None, "no cloth: call add_cloth first")])
        if any(cut.path_m for cut in self.cuts) and not self.tearing.enabled:
            self._raise("finalize", [(None, None, "scissors (add_cut with path_m) cut in the tearing stage: "
                                                  "call set_tearing()")])
        if self.multires.factor > 1 and any(p.layout.spec.drag_normal or p.layout.spec.drag_tangential
                                            for p in self._panels):
            self._raise("finalize", [(None, None, "air drag (drag_normal, drag_tangential) acts at yarn resolution: "
                                                  "set_multires(factor=1)")])

    def _draw_break_strains(self, panels, num) -> tuple:
        """The random break limits (docs/method.md §3.4), drawn here because they depend on set_tearing, which
        may come after the panels: one seeded stream, the cloth's springs in the Model's order, then the
        stitches seam by seam. A spring's mean is break_strain, or its panel's tear map under its middle; a weak
        line then scales the draw (docs/panels.md "Tear control"). Returns (the cloth's break strains, the last
        weak line that weakened each spring or -1, empty without weak lines; each seam's stitches').

        The floor does not depend on yarn_level, so a base-model-only run of a scene (yarn_level =
        false, for comparison) tears a cloth with exactly the same break strains."""
        t = self.tearing
        rng = np.random.default_rng(self.seed)
        mean: float | np.ndarray = t.break_strain
        if any(p.spring_mean_break_strain is not None for p in panels):
            mean = spread(panels, num, [p.spring_mean_break_strain if p.spring_mean_break_strain is not None
                                        else t.break_strain for p in panels], t.break_strain, float)
        draw = mean + t.break_strain_spread * rng.standard_normal(num.spring_count)
        weak_line = np.full(num.spring_count if self._weak else 0, -1, np.int32)
        for index, (k, near) in enumerate(self._weak):
            springs = num.spring_index[k][near]
            draw[springs] *= self.weak_lines[index].factor
            weak_line[springs] = index
        floor = t.transition_strain * 1.01 if t.transition_strain < t.break_strain else 1e-3
        stitches = [np.maximum(s.break_strain + t.break_strain_spread * rng.standard_normal(len(s.pairs)), 1e-3)
                    for s in self._stitches]
        return np.maximum(draw, floor), weak_line, stitches

    def _solver_fields(self, crossings: dict, springs: dict) -> dict[str, Any]:
        """The Model's solver settings, from set_* and the cloth (strain limiting, tearing, self-collision,
        the coarse model's refinement)."""
        c, t, strain, mr = self.cloth, self.tearing, self.strain, self.multires
        kind = springs["spring_kind"]
        structural = is_structural(kind)
        # the lowest strain at which a spring could split its crossings or be cut: coarse cells refine
        # at refine_fraction of it (docs/multires.md "When a cell refines")
        tear_from = (t.transition_strain if t.yarn_level else float(springs["spring_break_strain"][structural].min())) \
            if t.enabled and structural.any() else math.inf
        nx, ny, n = crossings["warp_yarns"], crossings["weft_yarns"], crossings["crossing_count"]
        band = mr.band_cells
        if mr.factor > 1:
            weft_on_top = np.zeros((ny, nx), bool)
            present = np.zeros((ny, nx), bool)
            gi, gj = crossings["crossing_grid_i"], crossings["crossing_grid_j"]
            weft_on_top[gj, gi] = crossings["crossing_weft_on_top"]
            present[gj, gi] = True
            band = max(band, split_walk_band(weft_on_top, mr.factor, present))
        return dict(
            strain_limit=strain.limit, strain_max_iterations=strain.max_iterations, strain_tolerance=strain.tolerance,
            strain_stiffness_n_per_m=strain.stiffness_n_per_m,
            strain_damping_n_s_per_m=2.0 * strain.damping_ratio * math.sqrt(strain.stiffness_n_per_m
                                                                            * c.mass_per_crossing_kg),
            damping=c.springs.damping,
            tearing=t.enabled, yarn_level=t.enabled and t.yarn_level, transition_strain=t.transition_strain,
            propagation_inclusive=t.propagation == "inclusive", ineffective_length=t.ineffective_length,
            disconnect_distance_m=t.disconnect_factor * c.thickness_m,
            self_collision=self.self_collision.enabled, self_collision_iterations=self.self_collision.iterations,
            self_collision_friction=self.self_collision.friction,
            coarse_factor=mr.factor, refine_strain=mr.refine_fraction * tear_from, refine_band_cells=band,
            refine_near_bodies=mr.refine_near_bodies,
        )

    def _scale_warnings(self, crossings: dict) -> list[str]:
        """A mesh far larger than the cloth (fraytool.sim.units): known only once both are added."""
        from fraytool.sim.units import mesh_scale_warning

        rest = crossings["crossing_rest_position_m"]
        cloth_m = float(np.ptp(rest, axis=0).max()) if len(rest) else 0.0
        out = []
        for k, body in enumerate(self._bodies):
            if body.mesh is not None:
                extent_m = float(np.ptp(body.mesh.key_vertices[0] * np.asarray(body.spec.scale, float), axis=0).max())
                line = mesh_scale_warning(f"{self._entry('bodies', k)} file = {body.spec.file!r}", body.spec.scale,
                                          extent_m, cloth_m)
                if line:
                    out.append(line)
        return out


def longest_float(weft_on_top: np.ndarray, present: Optional[np.ndarray] = None) -> int:
    """The most consecutive crossings along any yarn where the same yarn stays on top (a float),
    from the weave pattern (crossing_weft_on_top as (weft_yarns, warp_yarns)); with `present` (same
    shape), a place without a crossing (a shaped panel's outside, the grid between panels) ends a run."""
    code = weft_on_top.astype(np.int8)
    if present is not None:
        code = np.where(present, code, np.int8(-1))
    longest = 1
    for grid in (code, code.T):
        for row in grid:
            change = np.flatnonzero(np.diff(row) != 0)
            edges = np.concatenate([[-1], change, [row.size - 1]])
            runs = np.diff(edges)
            if present is not None:
                runs = runs[row[edges[1:]] >= 0]  # each run's last place says what it is a run of
            if runs.size:
                longest = max(longest, int(runs.max()))
    return longest


def split_walk_band(weft_on_top: np.ndarray, factor: int, present: Optional[np.ndarray] = None) -> int:
    """Fewest coarse cells of band that hold a split's walk (docs/method.md §3.4: a split runs along the
    yarn up to and including the crossing where the weave flips, up to longest_float + 1 crossings past
    the spring), plus one so that no crossing the walk reaches sits on the border of a coarse cell."""
    return -(-(longest_float(weft_on_top, present) + 1) // factor) + 1


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
    builder = ModelBuilder(seed=spec.scene.seed, **{k: getattr(spec, k) for k in _WORLD})
    builder.source, builder.scene_file = spec.source, spec.source_file
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
        if body.shape == "mesh":  # its file is found relative to the scene file (builder.scene_file)
            from fraytool.scene.mesh_files import frame_time_default

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
