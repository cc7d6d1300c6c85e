"""SceneSpec: the plain, validated description of a scene, as read from a TOML file.

Every field is SI (metres, kilograms, seconds, newtons). The TOML schema, with defaults and
allowed ranges, is in `fraytool.scene.schema` and documented in docs/scene-format.md.
A SceneSpec is immutable and hashable to a stable digest (`scene_hash`), which names the
simulated frames so that a render can reuse them.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

Vec3 = tuple[float, float, float]


@dataclass(frozen=True)
class SceneInfo:
    name: str
    """Scene name; default output folder is outputs/<name>/."""
    description: str = ""
    seed: int = 0
    """Seed of every random draw (break strains); same seed, same frames."""


@dataclass(frozen=True)
class TimeSpec:
    step_s: float
    """Explicit Euler step h [s]."""
    steps_per_frame: int
    frames: int
    """Number of frames to simulate and render (frame 0 is the initial state)."""
    fps: float
    """Playback frame rate of the video [1/s]."""
    stability: str = "warn"
    """What to do when step_s exceeds the explicit stability bound: "warn" or "refuse"."""


@dataclass(frozen=True)
class SpringSpec:
    structural_n_per_m: float
    bend_n_per_m: float
    shear_n_per_m: float
    """Shear springs act only in compression (METHOD.md §3.2)."""
    damping: float
    """PBD velocity damping k_damping in [0, 1] per step (Müller et al. 2007 §3.5)."""


@dataclass(frozen=True)
class StrainSpec:
    limit: float = 0.10
    """Strain limit: springs are projected to at most (1 + limit) x rest length (§4.1)."""
    max_iterations: int = 40
    """Cap on strain-limiting projection sweeps per step."""
    tolerance: float = 1e-4
    """Projection stops once every structural spring is within limit + tolerance."""


@dataclass(frozen=True)
class TearingSpec:
    enabled: bool = False
    """Cut springs whose strain exceeds their (randomised) break strain."""
    yarn_level: bool = True
    """Switch torn regions to the yarn-level model (frays); false = base-model-only tear (clean cut)."""
    transition_strain: float = 0.12
    """Strain above which both end masses of a spring split into mass couples (§3.4)."""
    break_strain: float = 0.2
    """Mean break strain of a spring."""
    break_strain_spread: float = 0.03
    """Standard deviation of the per-spring break strain (normal, clipped above the transition)."""
    disconnect_factor: float = 3.0
    """A couple disconnects when its weft and warp springs are farther apart than this x thickness."""


@dataclass(frozen=True)
class ClothSpec:
    warp_yarns: int
    """Number of warp yarns (columns, index i); they run along the cloth's second axis."""
    weft_yarns: int
    """Number of weft yarns (rows, index j); they run along the cloth's first axis."""
    spacing_m: float
    """Distance between neighbouring yarns at rest [m]."""
    thickness_m: float
    """Cloth thickness T [m]: weft and warp masses of a couple are T apart (§3.3)."""
    mass_per_crossing_kg: float
    origin_m: Vec3
    """World position of crossing (i=0, j=0) [m]."""
    plane: str
    """Plane the cloth spans at rest: "xz" (horizontal, y up), "xy" (vertical) or "yz"."""
    weave: str
    """"plain", "twill", "satin" or "table"."""
    weave_table: tuple[tuple[bool, ...], ...]
    """Resolved repeat: weave_table[j % rows][i % cols] is True where the weft lies on top."""
    springs: SpringSpec
    strain: StrainSpec
    tearing: TearingSpec
    twill: str = "2/1"
    satin_shafts: int = 5


@dataclass(frozen=True)
class BodySpec:
    name: str
    shape: str
    """"sphere", "box" or "plane"."""
    motion: str
    """"static", "kinematic" or "dynamic"."""
    position_m: Vec3
    radius_m: float = 0.0
    half_extents_m: Vec3 = (0.0, 0.0, 0.0)
    normal: Vec3 = (0.0, 1.0, 0.0)
    rotation_deg: Vec3 = (0.0, 0.0, 0.0)
    """Fixed orientation as x, y, z Euler angles [degrees] (boxes)."""
    velocity_m_s: Vec3 = (0.0, 0.0, 0.0)
    """Kinematic: constant velocity. Dynamic: initial velocity."""
    path: tuple[tuple[float, float, float, float], ...] = ()
    """Kinematic keyframes (t [s], x, y, z [m]), linearly interpolated; held after the last."""
    mass_kg: float = 1.0
    gravity: bool = True
    friction: float = 0.3
    """Coulomb-style friction coefficient against the cloth."""
    collide: bool = True
    """Cloth masses collide with this body."""
    start_s: float = 0.0
    """Kinematic/dynamic motion starts at this time [s]; the body rests before it."""


@dataclass(frozen=True)
class AttachmentSpec:
    body: str
    """Name of the rigid body that holds these cloth masses."""
    edge: Optional[str] = None
    corner: Optional[str] = None
    corner_size: int = 1
    warp_range: Optional[tuple[int, int]] = None
    weft_range: Optional[tuple[int, int]] = None
    region_center_m: Optional[Vec3] = None
    region_radius_m: float = 0.0


@dataclass(frozen=True)
class CameraSpec:
    position_m: Vec3 = (0.0, 0.3, 0.6)
    target_m: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov_deg: float = 40.0


@dataclass(frozen=True)
class RenderSpec:
    resolution: tuple[int, int] = (640, 360)
    samples: int = 4
    warp_color: Vec3 = (0.80, 0.30, 0.25)
    weft_color: Vec3 = (0.90, 0.85, 0.70)
    background: Vec3 = (0.08, 0.09, 0.11)
    light_direction: Vec3 = (-0.4, 1.0, 0.6)
    light_intensity: float = 1.0
    ambient: float = 0.25
    specular: float = 0.35
    shininess: float = 40.0
    yarn_radius_m: float = 0.0
    """Tube radius [m]; 0 means half the cloth thickness."""
    fade_length_m: float = 0.0
    """Length over which a broken yarn end fades to transparent [m]; 0 means 2 x spacing."""
    spline_samples: int = 4
    """Catmull-Rom samples per yarn segment."""
    tube_sides: int = 6
    ground_plane: bool = False
    ground_height_m: float = 0.0
    body_color: Vec3 = (0.55, 0.6, 0.7)


@dataclass(frozen=True)
class OutputSpec:
    mp4: bool = True
    png: bool = False
    crf: int = 18


@dataclass(frozen=True)
class SelfCollisionSpec:
    enabled: bool = False
    iterations: int = 4
    """Cap on collision-response passes per step."""
    friction: float = 0.2


@dataclass(frozen=True)
class CheckSpec:
    """What must hold after the scene's frames (scenes carry their own checks)."""

    frames: int = 0
    """Frames to run for the checks; 0 means the scene's frame count."""
    all_finite: bool = True
    max_strain_below: Optional[float] = None
    min_broken_springs: Optional[int] = None
    max_broken_springs: Optional[int] = None
    min_yarn_level_masses: Optional[int] = None
    max_yarn_level_masses: Optional[int] = None
    attachments_follow: bool = True


@dataclass(frozen=True)
class SceneSpec:
    source: str
    """Path of the TOML file the scene came from (for messages)."""
    scene: SceneInfo
    time: TimeSpec
    cloth: ClothSpec
    gravity_m_s2: Vec3
    bodies: tuple[BodySpec, ...] = ()
    attachments: tuple[AttachmentSpec, ...] = ()
    self_collision: SelfCollisionSpec = field(default_factory=SelfCollisionSpec)
    camera: CameraSpec = field(default_factory=CameraSpec)
    render: RenderSpec = field(default_factory=RenderSpec)
    output: OutputSpec = field(default_factory=OutputSpec)
    checks: CheckSpec = field(default_factory=CheckSpec)

    @property
    def name(self) -> str:
        return self.scene.name
