"""SceneSpec: the plain, validated description of a scene, and the one declaration of every scene key.

Every field that a scene file sets is declared here once with `key(type, default, range, doc)`:
the dataclass default, the TOML schema (`fraytool.scene.schema`, which the file loader checks
against) and the checks on `ModelBuilder`'s arguments all come from that declaration;
docs/scene-format.md documents the same keys for people (tests/test_docs.py keeps them in step).
Fields that are not keys (`source`, `ClothSpec.weave_table`, the sub-tables) have docstrings.

Every value is SI (metres, kilograms, seconds, newtons). A SceneSpec is immutable and hashable to a
stable digest (`scene_hash`), which names the simulated frames so that a render can reuse them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

from fraytool.kinds import INTERPOLATION_NAMES, MOTION_NAMES, SHAPE_NAMES
from fraytool.scene.keys import key

Vec3 = tuple[float, float, float]

WORLD_M = 1.0e4
"""Largest coordinate of a position key [m]: 10 km, far beyond any cloth shot, and small enough that
positions keep sub-micrometre precision in float64 and stay finite in the float32 frame records."""
PATH_MAX_DEG = 1.0e5
"""Largest angle of an orientation key [degrees]: hundreds of turns."""


@dataclass(frozen=True, kw_only=True)
class SceneInfo:
    """[scene]"""

    name: str = key("str", "", doc="scene name; outputs go to outputs/<name>/ (default: file name without .toml)")
    description: str = key("str", "", doc="free text")
    seed: int = key("int", 0, lo=0, hi=2 ** 63 - 1,
                    doc="seed of every random draw (break strains); same seed, same frames")


@dataclass(frozen=True, kw_only=True)
class TimeSpec:
    """[time]"""

    step_s: float = key("float", lo=1e-9, hi=0.1, doc="explicit Euler step h [s]")
    steps_per_frame: int = key("int", lo=1, hi=100000, doc="steps between two frames")
    frames: int = key("int", lo=1, hi=1000000, doc="frames to simulate and render; frame 0 is the initial state")
    fps: float = key("float", 24.0, lo=1, hi=1000, doc="playback frame rate of the video [1/s]")
    stability: str = key("str", "warn", choices=("warn", "refuse"),
                         doc="what to do when step_s exceeds the explicit stability bound")


@dataclass(frozen=True, kw_only=True)
class SpringSpec:
    """[cloth.springs]"""

    structural_n_per_m: float = key("float", lo=0, lo_open=True, hi=1e9,
                                    doc="stiffness of springs between grid neighbours along weft and warp [N/m]")
    bend_n_per_m: float = key("float", 0.0, lo=0, hi=1e9,
                              doc="stiffness of skip-one springs along weft and warp [N/m]; 0: none")
    shear_n_per_m: float = key("float", 0.0, lo=0, hi=1e9,
                               doc="stiffness of diagonal springs, acting only in compression [N/m]; 0: none")
    damping: float = key("float", 0.01, lo=0, hi=1,
                         doc="PBD velocity damping k_damping per step (Müller et al. 2007 §3.5)")


@dataclass(frozen=True, kw_only=True)
class StrainSpec:
    """[cloth.strain]"""

    limit: float = key("float", 0.10, lo=0, lo_open=True, hi=10,
                       doc="structural springs are projected to at most (1 + limit) x rest length (§4.1)")
    max_iterations: int = key("int", 40, lo=0, hi=100000, doc="cap on strain-limiting projection sweeps per step")
    tolerance: float = key("float", 1e-4, lo=0, hi=1,
                           doc="projection stops once every structural spring is within limit + tolerance")
    stiffness_n_per_m: float = key("float", 0.0, lo=0, hi=1e9,
                                   doc="stiffness of a yarn spring past the limit [N/m]: 0 holds the limit hard "
                                       "(the paper's projection); > 0 makes it a compliant constraint (XPBD) "
                                       "that converges where the limit cannot be met (docs/tearing.md)")
    damping_ratio: float = key("float", 0.0, lo=0, hi=100,
                               doc="damping ratio of a yarn spring past the limit: a dashpot 2 x ratio x "
                                   "sqrt(stiffness_n_per_m x mass_per_crossing_kg) [N s/m] resists its "
                                   "stretching while it is past the limit; 0: none; needs stiffness_n_per_m > 0 "
                                   "(docs/tearing.md)")


@dataclass(frozen=True, kw_only=True)
class TearingSpec:
    """[cloth.tearing]"""

    enabled: bool = key("bool", False, doc="cut springs whose strain exceeds their (randomised) break strain")
    yarn_level: bool = key("bool", True, doc="torn regions switch to the yarn-level model and fray; "
                                             "false: base-model-only tearing (a clean cut)")
    transition_strain: float = key("float", 0.12, lo=0, lo_open=True, hi=10,
                                   doc="strain above which a spring's end masses split into mass couples (§3.4)")
    propagation: str = key("str", "inclusive", choices=("inclusive", "exclusive"),
                           doc="how far a split spreads along the spring's yarn (§3.4): up to and including "
                               "the crossing where the weave flips (the paper), or up to just before it")
    ineffective_length: int = key("int", 5, lo=1, hi=100000,
                                  doc="crossings a yarn needs from a free end (a cut or the border) to carry "
                                      "breaking tension again: no break leaves a yarn piece shorter "
                                      "(docs/tearing.md \"Cutting\")")
    break_strain: float = key("float", 0.2, lo=0, lo_open=True, hi=10, doc="mean break strain of a spring")
    break_strain_spread: float = key("float", 0.03, lo=0, hi=10,
                                     doc="standard deviation of the per-spring break strain, drawn from the seed")
    disconnect_factor: float = key("float", 3.0, lo=1, hi=1000,
                                   doc="a couple disconnects when its weft and warp springs are farther apart "
                                       "than this x thickness")


@dataclass(frozen=True, kw_only=True)
class MultiresSpec:
    """[cloth.multires]: a coarse base model where the cloth is whole (docs/multires.md)."""

    factor: int = key("int", 1, lo=1, hi=8,
                      doc="1, 2, 4 or 8: the whole cloth starts as a base model whose cells span factor x factor "
                          "yarn spacings; cells refine to yarn resolution ahead of any strain that could tear "
                          "them (1: yarn resolution everywhere, the paper's model)")
    refine_fraction: float = key("float", 0.5, lo=0, lo_open=True, hi=1, hi_open=True,
                                 doc="a coarse cell refines when a structural spring in or next to it is strained "
                                     "past this fraction of the lowest strain that could split or cut a spring")
    band_cells: int = key("int", 2, lo=1, hi=64,
                          doc="width of the band of coarse cells refined around a cell past the refine strain "
                              "(and around a moving body)")
    refine_near_bodies: bool = key("bool", True,
                                   doc="cells within band_cells of a moving analytic body's bounding sphere refine "
                                       "before the body reaches them (near a mesh a cell refines by its own test, "
                                       "always)")


@dataclass(frozen=True, kw_only=True)
class ClothSpec:
    """[cloth] with its sub-tables [cloth.springs], [cloth.strain], [cloth.tearing] and [cloth.multires]."""

    name: str = key("str", "", doc="panel name, unique among [[cloth]] panels; seams, attachments, cuts and weak "
                    "lines name their panel by it (default: cloth for the first panel, cloth<k> for panel k)")
    warp_yarns: int = key("int", 0, lo=0, hi=4096,
                          doc="number of warp yarns (columns, index i); they run along the cloth's second axis; "
                              "2 or more for a rectangle; 0 or left out with outline_m or mask (the shape sets the "
                              "grid)")
    weft_yarns: int = key("int", 0, lo=0, hi=4096,
                          doc="number of weft yarns (rows, index j); they run along the cloth's first axis; "
                              "2 or more for a rectangle; 0 or left out with outline_m or mask")
    spacing_m: float = key("float", lo=1e-6, hi=1.0, doc="distance between neighbouring yarns at rest [m]")
    thickness_m: float = key("float", lo=1e-7, hi=0.1,
                             doc="cloth thickness T [m]: weft and warp masses of a couple are T apart")
    mass_per_crossing_kg: float = key("float", lo=1e-12, hi=10.0, doc="mass of one crossing [kg]")
    origin_m: Vec3 = key("vec3", (0.0, 0.0, 0.0), lo=-WORLD_M, hi=WORLD_M, doc="world position of crossing (i = 0, j = 0) [m]")
    plane: str = key("str", "xz", choices=("xz", "xy", "yz"),
                     doc='plane the cloth spans at rest ("xz" flat, y up; "xy" vertical); weft along its first axis')
    rotation_deg: Vec3 = key("vec3", (0.0, 0.0, 0.0), lo=-360, hi=360,
                             doc="turns the panel about origin_m after plane and wrap_radius_m, as x, y, z Euler "
                                 "angles [degrees] (R = Rz Ry Rx)")
    wrap_radius_m: float = key("float", 0.0, lo=0, hi=WORLD_M,
                               doc="wraps the panel's first axis around a cylinder of this radius [m] (a sleeve, a "
                                   "tube), the cylinder's axis along the plane's second axis; 0: flat")
    warp_color: Optional[Vec3] = key("color", None, doc="sRGB colour of this panel's warp yarns (default: [render] warp_color)")
    weft_color: Optional[Vec3] = key("color", None, doc="sRGB colour of this panel's weft yarns (default: [render] weft_color)")
    weave: str = key("str", "plain", choices=("plain", "twill", "satin", "table"), doc="weave pattern")
    weave_table: tuple[tuple[bool, ...], ...]
    """Resolved repeat (from weave, twill, satin_shafts or the `table` key):
    weave_table[j % rows][i % cols] is True where the weft lies on top."""
    springs: SpringSpec
    strain: StrainSpec = field(default_factory=StrainSpec)
    tearing: TearingSpec = field(default_factory=TearingSpec)
    multires: MultiresSpec = field(default_factory=MultiresSpec)
    twill: str = key("str", "2/1", doc='with weave = "twill": floats over/under, e.g. "2/1", "2/2", "3/1"')
    satin_shafts: int = key("int", 5, lo=5, hi=16, doc='with weave = "satin": threads per repeat')
    outline_m: tuple[tuple[float, float], ...] = key(
        "points2", (), lo=-WORLD_M, hi=WORLD_M,
        doc="panel shape: a polygon [[u, v], ...] in the cloth's plane [m], u along the plane's first axis and v "
            "along its second from origin_m; only crossings inside it exist (docs/panels.md)")
    mask: str = key("str", "", doc="panel shape from a greyscale image, relative to the scene file: crossings over "
                    "white (>= 50 %) exist; the image covers mask_size_m from origin_m, its bottom row at v = 0")
    mask_size_m: tuple[float, float] = key("float2", (0.0, 0.0), lo=0, hi=WORLD_M,
                                           doc="with mask: width (u) and height (v) the image covers [m]")
    grain_deg: float = key("float", 0.0, lo=-360, hi=360,
                           doc="with outline_m or mask: angle of the weft yarns from the plane's first axis "
                               "[degrees] (the warp runs at grain_deg + 90)")
    tear_map: str = key("str", "", doc="greyscale image over the panel's extent (the outline's or mask's bounding "
                        "rectangle, or the rectangle of crossings), relative to the scene file: the mean break strain "
                        "of each yarn spring, from tear_map_strain[0] at black to [1] at white")
    tear_map_strain: tuple[float, float] = key("float2", (0.0, 0.0), lo=0, hi=10,
                                               doc="with tear_map: mean break strain at black and at white "
                                                   "(break_strain_spread still draws each spring's own)")
    edge: str = key("str", "raw", choices=("raw", "hemmed"),
                    doc="the panel's border: raw (torn or pulled, its yarns fray) or hemmed (border crossings "
                        "never split into yarns, and border yarns hold twice the break strain)")
    drag_normal: float = key("float", 0.0, lo=0, hi=1000,
                             doc="air drag coefficient across the cloth (a flat plate face-on: about 1.2); the "
                                 "pressure 1/2 rho C v_n |v_n| [N/m^2] from the velocity relative to the air along "
                                 "the local normal (docs/wind.md); loose yarn ends take it as a cylinder's; 0: none")
    drag_tangential: float = key("float", 0.0, lo=0, hi=1000,
                                 doc="air drag coefficient along the cloth's plane (skin friction, about 0.01-0.05): "
                                     "1/2 rho C v_t |v_t| [N/m^2] from the velocity in the plane; 0: none")


@dataclass(frozen=True, kw_only=True)
class BodySpec:
    """One [[bodies]] entry: a rigid sphere, box, plane or triangle mesh (docs/meshes.md)."""

    name: str = key("str", doc="unique; attachments refer to the body by it")
    shape: str = key("str", choices=SHAPE_NAMES, doc="body shape")
    motion: str = key("str", "static", choices=MOTION_NAMES,
                      doc="kinematic bodies follow path or velocity_m_s; dynamic ones fly and are pushed by the cloth")
    position_m: Vec3 = key("vec3", (0.0, 0.0, 0.0), lo=-WORLD_M, hi=WORLD_M, doc="centre (sphere, box) or a point of the plane [m]")
    radius_m: float = key("float", 0.0, lo=0, lo_open=True, hi=100, doc="sphere radius [m]; required for spheres, an error on other shapes")
    half_extents_m: Vec3 = key("vec3", (0.0, 0.0, 0.0), lo=-WORLD_M, hi=WORLD_M, doc="box half sizes [m]; required for boxes, an error on other shapes")
    normal: Vec3 = key("vec3", (0.0, 1.0, 0.0), doc="plane normal, pointing to the free side")
    rotation_deg: Vec3 = key("vec3", (0.0, 0.0, 0.0), doc="fixed orientation as x, y, z Euler angles [degrees]")
    file: str = key("str", "", doc="mesh: OBJ, PLY, STL, glTF/GLB or USD file, relative to the scene file; "
                    "walk.####.obj is a numbered sequence (one file per frame)")
    prim: str = key("str", "", doc="mesh from a USD file: the path of its Mesh prim, e.g. /Root/Body")
    scale: Vec3 = key("vec3", (1.0, 1.0, 1.0), lo=1e-9, hi=1e9, doc="mesh: scale of the file's coordinates "
                      "to metres, per axis (a USD stage's metersPerUnit is applied first)")
    frame_time_s: float = key("float", 0.0, lo=0, hi=1e4, doc="mesh sequence: seconds between two files; "
                              "0 = the scene's frame time (step_s x steps_per_frame)")
    sequence_start_s: float = key("float", 0.0, lo=-1e6, hi=1e6,
                                  doc="animated mesh (a sequence, USD time samples): the scene time [s] of its "
                                      "first file or sample, after start_s; negative: the shot starts part way "
                                      "through (walk.1001.obj at -2 s: `check` names the file at 0 s)")
    velocity_m_s: Vec3 = key("vec3", (0.0, 0.0, 0.0), lo=-1e4, hi=1e4,
                             doc="kinematic: constant velocity; dynamic: initial velocity [m/s]")
    path: tuple[tuple[float, float, float, float], ...] = key(
        "path", (), lo=-WORLD_M, hi=WORLD_M, doc="kinematic keyframes (t [s], x, y, z [m]), interpolated by "
        "`interpolation`; held before the first and after the last")
    path_rotation_deg: tuple[tuple[float, float, float, float], ...] = key(
        "path_deg", (), lo=-PATH_MAX_DEG, hi=PATH_MAX_DEG,
        doc="kinematic orientation keys (t [s], rx, ry, rz [degrees]), x, y, z Euler angles as rotation_deg; "
            "each segment turns the short way (below 180 degrees); held before the first and after the last")
    path_quaternion: tuple[tuple[float, float, float, float, float], ...] = key(
        "path_quat", (), doc="kinematic orientation keys (t [s], w, x, y, z), quaternions (normalised), "
                             "instead of path_rotation_deg")
    interpolation: str = key("str", "linear", choices=INTERPOLATION_NAMES,
                             doc="between the keys of path and of the orientation keys: linear (slerp for "
                                 "orientations) or catmull_rom (a smooth curve through the keys)")
    mass_kg: float = key("float", 1.0, lo=0, lo_open=True, hi=1e6, doc="mass of a dynamic body [kg]")
    gravity: bool = key("bool", True, doc="a dynamic body feels gravity")
    friction: float = key("float", 0.3, lo=0, hi=10, doc="friction coefficient of the cloth against this body")
    collide: bool = key("bool", True, doc="cloth masses collide with this body")
    start_s: float = key("float", 0.0, lo=0, doc="kinematic and dynamic bodies rest until this time [s]")


@dataclass(frozen=True, kw_only=True)
class AttachmentSpec:
    """One [[attachments]] entry: cloth masses held by a body. Exactly one selection is given."""

    body: str = key("str", doc="name of the rigid body that holds these cloth masses")
    panel: str = key("str", "", doc="name of the [[cloth]] panel whose masses are held (default: the first)")
    edge: Optional[str] = key("str", None, choices=("left", "right", "bottom", "top"), doc="a whole edge")
    corner: Optional[str] = key("str", None, choices=("bottom_left", "bottom_right", "top_left", "top_right"),
                                doc="a corner block of corner_size x corner_size masses")
    corner_size: int = key("int", 1, lo=1, hi=4096, doc="side of the corner block, in crossings")
    warp_range: Optional[tuple[int, int]] = key("int2", None, doc="inclusive range of warp yarn indices i")
    weft_range: Optional[tuple[int, int]] = key("int2", None, doc="inclusive range of weft yarn indices j")
    region_center_m: Optional[Vec3] = key("vec3", None, lo=-WORLD_M, hi=WORLD_M, doc="with region_radius_m: centre of a ball of held masses [m]")
    region_radius_m: float = key("float", 0.0, lo=0, doc="with region_center_m: masses this close at rest are held [m]")
    release_force_n: float = key("float", 0.0, lo=0, hi=1e9,
                                 doc="a held mass lets go when the force on it (its springs' pull and its weight) "
                                     "passes this [N], and is free from then on; 0: it never lets go")
    catch_s: float = key("float", 0.0, lo=0, hi=1e6,
                         doc="the body catches the selected masses at this scene time [s], holding each where it "
                             "is then relative to the body (a hook that snags the cloth); free before; 0: held from "
                             "the start")


@dataclass(frozen=True, kw_only=True)
class CutSpec:
    """One [[cuts]] entry: a snip made in the cloth before the shot, like the nick a tailor cuts
    before tearing fabric by hand. Every spring whose rest segment meets the straight line from
    `start` to `end` is absent from the first frame on (not counted as broken). Or scissors: a cut
    along `path_m` that grows from start_s to end_s (docs/panels.md "Tear control")."""

    panel: str = key("str", "", doc="name of the [[cloth]] panel cut (default: the first)")
    start: Optional[tuple[float, float]] = key("float2", None, lo=-1e6, hi=1e6,
                                               doc="[i, j] in yarn indices (warp i, weft j); 39.5 lies between "
                                                   "yarns 39 and 40")
    end: Optional[tuple[float, float]] = key("float2", None, lo=-1e6, hi=1e6,
                                             doc="[i, j] in yarn indices, the other end of the line")
    path_m: tuple[tuple[float, float], ...] = key(
        "points2", (), lo=-WORLD_M, hi=WORLD_M,
        doc="scissors instead of start and end: a polyline [[u, v], ...] in the cloth's plane [m] (as outline_m), "
            "cut from its first point to its last between start_s and end_s")
    start_s: float = key("float", 0.0, lo=0, hi=1e6, doc="with path_m: when the scissors reach the first point [s]")
    end_s: float = key("float", 0.0, lo=0, hi=1e6, doc="with path_m: when they reach the last point [s]; "
                       "the cut advances at a constant speed along the path")


@dataclass(frozen=True, kw_only=True)
class WeakLineSpec:
    """One [[weak_lines]] entry: a band along a polyline where the cloth is weaker, like a perforation
    (docs/panels.md "Tear control")."""

    panel: str = key("str", "", doc="name of the [[cloth]] panel (default: the first)")
    points_m: tuple[tuple[float, float], ...] = key(
        "points2", lo=-WORLD_M, hi=WORLD_M,
        doc="polyline [[u, v], ...] in the cloth's plane [m], as outline_m (at least 2 points)")
    width_m: float = key("float", lo=0, lo_open=True, hi=WORLD_M,
                         doc="width of the band [m]: yarn springs whose middle is within width_m / 2 of the line")
    factor: float = key("float", 0.5, lo=0, lo_open=True, hi=10,
                        doc="their break strain is multiplied by this (below 1: weaker; it stays above the "
                            "transition strain)")


@dataclass(frozen=True, kw_only=True)
class SeamSpec:
    """One [[seams]] entry: stitches joining an edge of one panel to an edge of another (or of itself, to
    close a tube), that break one by one (docs/panels.md "Seams")."""

    panel_a: str = key("str", doc="name of the first [[cloth]] panel")
    segment_a: int = key("int", lo=0, hi=100000, doc="its edge: segment k of its outline, from point k to k + 1 "
                         "(a rectangle: 0 bottom, 1 right, 2 top, 3 left)")
    panel_b: str = key("str", doc="name of the second panel (the same name sews a panel to itself)")
    segment_b: int = key("int", lo=0, hi=100000, doc="its edge, as segment_a")
    reverse: bool = key("bool", False, doc="sew segment_a's first point to segment_b's last (false: first to first)")
    stitch_spacing_m: float = key("float", lo=0, lo_open=True, hi=1, doc="distance between stitches along "
                                  "segment_a [m]")
    stitch_length_m: float = key("float", 0.0, lo=0, hi=1, doc="rest length of a stitch [m] (the thread across the "
                                 "seam); 0: the cloth's spacing_m")
    stiffness_n_per_m: float = key("float", lo=0, lo_open=True, hi=1e9,
                                   doc="stiffness of a stitch [N/m]; a thread: it pulls, never pushes")
    break_strain: float = key("float", lo=0, lo_open=True, hi=10,
                              doc="mean strain at which a stitch breaks; [cloth.tearing] break_strain_spread "
                                  "draws each stitch's own from the seed")
    sew_s: float = key("float", 0.0, lo=0, hi=1e6,
                       doc="sew the seam over the shot's first sew_s seconds [s]: each stitch starts at the length "
                           "the panels are placed apart and its rest length shrinks to the stitch length; while "
                           "sewing it pulls, never pushes, and cannot break (docs/garments.md); 0: the seam is "
                           "sewn from the start, its stitches at their break strain or less")


@dataclass(frozen=True, kw_only=True)
class CameraSpec:
    """[camera]"""

    position_m: Vec3 = key("vec3", (0.0, 0.3, 0.6), lo=-WORLD_M, hi=WORLD_M, doc="eye [m]")
    target_m: Vec3 = key("vec3", (0.0, 0.0, 0.0), lo=-WORLD_M, hi=WORLD_M, doc="point looked at [m]")
    up: Vec3 = key("vec3", (0.0, 1.0, 0.0), doc="up direction")
    fov_deg: float = key("float", 40.0, lo=1, hi=170, doc="vertical field of view [degrees]")
    fit: bool = key("bool", False, doc="frame the cloth: keep the view direction and fov, re-target at the centre "
                                       "of the yarns and bodies over the rendered shot and move the eye along the "
                                       "view axis until they fit (fraytool render --fit)")
    fit_margin: float = key("float", 0.05, lo=0, hi=1,
                            doc="with fit: free border around the fitted bounds, as a fraction of the frame")
    position_keys_m: tuple[tuple[float, float, float, float], ...] = key(
        "path", (), lo=-WORLD_M, hi=WORLD_M, doc="camera animation: eye keyframes (t [s], x, y, z [m]), "
        "interpolated by `interpolation`, held before the first and after the last; instead of position_m")
    target_keys_m: tuple[tuple[float, float, float, float], ...] = key(
        "path", (), lo=-WORLD_M, hi=WORLD_M, doc="camera animation: keyframes of the point looked at "
        "(t [s], x, y, z [m]); instead of target_m")
    fov_keys_deg: tuple[tuple[float, float], ...] = key(
        "path_fov", (), lo=1, hi=170, doc="camera animation: keyframes of the vertical field of view "
        "(t [s], fov [degrees]); instead of fov_deg")
    interpolation: str = key("str", "linear", choices=INTERPOLATION_NAMES,
                             doc="between the camera's keys: linear or catmull_rom (as [[bodies]] paths)")


@dataclass(frozen=True, kw_only=True)
class RenderSpec:
    """[render]"""

    resolution: tuple[int, int] = key("int2", (640, 360), lo=2, hi=8192, doc="image width and height [pixels]")
    samples: int = key("int", 4, lo=0, hi=64, doc="MSAA samples")
    supersample: int = key("int", 1, lo=1, hi=4,
                           doc="pixels drawn per output pixel along each axis, averaged in linear light (SSAA: "
                               "slower by about its square; the level of detail measures yarns in drawn pixels)")
    warp_color: Vec3 = key("color", (0.80, 0.30, 0.25), doc="sRGB colour of warp yarns")
    weft_color: Vec3 = key("color", (0.90, 0.85, 0.70), doc="sRGB colour of weft yarns")
    background: Vec3 = key("color", (0.08, 0.09, 0.11), doc="sRGB background colour")
    light_direction: Vec3 = key("vec3", (-0.4, 1.0, 0.6), doc="direction towards the key light")
    light_intensity: float = key("float", 1.0, lo=0, hi=100, doc="key light intensity")
    ambient: float = key("float", 0.25, lo=0, hi=1, doc="ambient light")
    specular: float = key("float", 0.35, lo=0, hi=10, doc="Kajiya-Kay specular weight")
    shininess: float = key("float", 40.0, lo=1, hi=10000, doc="Kajiya-Kay specular exponent")
    yarn_radius_m: float = key("float", 0.0, lo=0, hi=1, doc="tube radius [m]; 0 means half the cloth thickness")
    fade_length_m: float = key("float", 0.0, lo=0, hi=10,
                               doc="length over which a broken yarn end fades out [m]; 0 means 2 x spacing")
    spline_samples: int = key("int", 4, lo=1, hi=64, doc="Catmull-Rom samples per yarn segment (a maximum)")
    tube_sides: int = key("int", 6, lo=3, hi=64, doc="sides of a yarn tube (a maximum)")
    yarn_shape: str = key("str", "tube", choices=("tube", "ribbon"),
                          doc="how yarns are drawn: tube (swept circles of tube_sides) or ribbon (view-facing "
                              "strips shaded and depth-corrected as round tubes: a sixth of the triangles)")
    far_field: bool = key("bool", True, doc="draw intact cloth whose yarns are under far_field_px apart on screen as "
                                           "one weave-shaded surface (level of detail: no moire, less to draw)")
    far_field_px: float = key("float", 3.0, lo=0.25, hi=64,
                              doc="yarn spacing on screen [pixels] at the middle of the band where yarns blend "
                                  "into the far-field surface (the band runs from 2/3 to 4/3 of it)")
    ground_plane: bool = key("bool", False, doc="draw a ground plane at ground_height_m")
    ground_height_m: float = key("float", 0.0, doc="height of the drawn ground plane [m]")
    body_color: Vec3 = key("color", (0.55, 0.6, 0.7), doc="sRGB colour of rigid bodies")
    shadows: bool = key("bool", False, doc="shadows from the key light (a PCF-filtered shadow map): yarns on yarns, "
                                           "bodies and the ground, bodies on everything")
    shadow_map_size: int = key("int", 2048, lo=256, hi=8192, doc="side of the square shadow map [pixels]")
    fill_intensity: float = key("float", 0.0, lo=0, hi=100,
                                doc="soft fill light: a hemisphere light around fill_direction, N.F mapped "
                                    "from [-1, 1] to [0, 1]; 0: none")
    fill_direction: Vec3 = key("vec3", (0.0, 1.0, 0.0), doc="direction towards the fill light's brightest side")


@dataclass(frozen=True, kw_only=True)
class OutputSpec:
    """[output]"""

    mp4: bool = key("bool", True, doc="write <out>/<name>.mp4")
    png: bool = key("bool", False, doc="also write <out>/png/frame_NNNNNN.png")
    crf: int = key("int", 18, lo=0, hi=51, doc="H.264 quality (lower is better)")


@dataclass(frozen=True, kw_only=True)
class SelfCollisionSpec:
    """[self_collision]"""

    enabled: bool = key("bool", False, doc="edge-edge continuous collision between yarn segments")
    iterations: int = key("int", 4, lo=1, hi=1000, doc="cap on collision-response passes per step")
    friction: float = key("float", 0.2, lo=0, hi=10, doc="friction between yarns")


@dataclass(frozen=True, kw_only=True)
class CheckSpec:
    """[checks]: what must hold after the scene's frames (scenes carry their own checks)."""

    frames: int = key("int", 0, lo=0, doc="frames to run for the checks; 0 means the scene's frame count")
    all_finite: bool = key("bool", True, doc="every position stays finite")
    max_strain_below: Optional[float] = key("float", None, lo=0, lo_open=True,
                                            doc="largest structural strain at the end")
    min_broken_springs: Optional[int] = key("int", None, lo=0, doc="fewest springs cut by tearing")
    max_broken_springs: Optional[int] = key("int", None, lo=0, doc="most springs cut by tearing")
    min_yarn_level_masses: Optional[int] = key("int", None, lo=0, doc="fewest masses in the yarn-level model")
    max_yarn_level_masses: Optional[int] = key("int", None, lo=0, doc="most masses in the yarn-level model")
    min_second_piece_fraction: Optional[float] = key(
        "float", None, lo=0, hi=0.5, doc="at the end, the second largest piece holds at least this mass fraction "
                                         "(the cloth is torn apart, not a strip ripped off)")
    max_small_pieces: Optional[int] = key("int", None, lo=0, doc="most pieces of fewer than 5 masses at the end")
    attachments_follow: bool = key("bool", True, doc="held masses stay exactly on their body")


@dataclass(frozen=True, kw_only=True)
class GoldenSpec:
    """[golden]: the frames `fraytool golden` stores and how closely a check must match them (docs/golden.md).
    Image thresholds are per-channel differences of the 16-bit sRGB values scaled to [0, 1], as idiff's."""

    frames: tuple[int, ...] = key("ints", (), lo=0, hi=1000000,
                                  doc="frames to store and check; empty: the first, middle and last")
    fail: float = key("float", 0.05, lo=0, hi=1, doc="a pixel fails when a channel differs by more than this "
                      "(idiff -fail)")
    failpercent: float = key("float", 0.1, lo=0, hi=100, doc="percent of failing pixels that fails the frame "
                             "(idiff -failpercent)")
    hardfail: float = key("float", 1.0, lo=0, hi=1, doc="one pixel differing by more than this fails the frame "
                          "(idiff -hardfail); 1: off")
    warn: float = key("float", 0.01, lo=0, hi=1, doc="a pixel warns when a channel differs by more than this "
                      "(idiff -warn)")
    warnpercent: float = key("float", 0.05, lo=0, hi=100, doc="percent of warning pixels that warns (idiff "
                             "-warnpercent)")
    ssim_min: float = key("float", 0.98, lo=-1, hi=1, doc="the frame fails when the SSIM of its luma falls below this")
    geometry_thickness: float = key("float", 0.25, lo=0, hi=1e6,
                                    doc="the frame fails when a yarn point moved farther than this many yarn "
                                        "thicknesses")
    torn_springs: int = key("int", 0, lo=0, hi=1000000000,
                            doc="the frame fails when its torn springs differ from the golden's by more than this")


@dataclass(frozen=True, kw_only=True)
class SceneSpec:
    """A whole scene. Its own key, gravity, is the [world] table."""

    source: str
    """Path of the TOML file the scene came from, as named (for messages)."""
    source_file: str = ""
    """The TOML file read (a shipped scene named by its name: its path in the package); the files the scene
    names (a mesh body's `file`) are relative to its folder. Not part of scene_hash."""
    scene: SceneInfo
    time: TimeSpec
    cloth: ClothSpec
    gravity_m_s2: Vec3 = key("vec3", (0.0, -9.81, 0.0), lo=-1e4, hi=1e4, doc="gravity [m/s^2]")
    gravity_start_s: float = key("float", 0.0, lo=0, hi=1e6,
                                 doc="gravity acts from this scene time on [s]: a pre-roll in which panels laid round "
                                     "a body are sewn on ([[seams]] sew_s) before they can fall; 0: from the start")
    wind_m_s: Vec3 = key("vec3", (0.0, 0.0, 0.0), lo=-1e3, hi=1e3,
                         doc="mean wind, the air's velocity [m/s]; a panel feels it through its drag_normal and "
                             "drag_tangential (docs/wind.md)")
    air_density_kg_m3: float = key("float", 1.2, lo=0, hi=1e4, doc="density of the air rho [kg/m^3] in the drag law")
    gust_strength_m_s: float = key("float", 0.0, lo=0, hi=1e3,
                                   doc="gusts: root mean square of each component of a seeded, smooth turbulent "
                                       "velocity added to wind_m_s [m/s]; 0: steady wind")
    gust_length_m: float = key("float", 0.5, lo=1e-4, hi=1e4,
                               doc="gusts: length scale L [m]; two points r apart correlate as exp(-r^2 / 2 L^2)")
    gust_time_s: float = key("float", 0.5, lo=1e-4, hi=1e4,
                             doc="gusts: time scale [s] of the field's change as the wind carries it along; one "
                                 "point, in still mean air, correlates as exp(-tau^2 / 2 T^2)")
    bodies: tuple[BodySpec, ...] = ()
    attachments: tuple[AttachmentSpec, ...] = ()
    cuts: tuple[CutSpec, ...] = ()
    weak_lines: tuple[WeakLineSpec, ...] = ()
    panels: tuple[ClothSpec, ...] = ()
    """The panels after the first ([[cloth]] written more than once; docs/panels.md): the first is `cloth`."""
    seams: tuple[SeamSpec, ...] = ()
    self_collision: SelfCollisionSpec = field(default_factory=SelfCollisionSpec)
    camera: CameraSpec = field(default_factory=CameraSpec)
    render: RenderSpec = field(default_factory=RenderSpec)
    output: OutputSpec = field(default_factory=OutputSpec)
    checks: CheckSpec = field(default_factory=CheckSpec)
    golden: GoldenSpec = field(default_factory=GoldenSpec)

    @property
    def name(self) -> str:
        return self.scene.name

    @property
    def all_panels(self) -> tuple[ClothSpec, ...]:
        """Every cloth panel, the first (`cloth`) first."""
        return (self.cloth,) + self.panels
