"""The TOML scene schema: every table, key, type, default and allowed range.

A key is described by `Key`; tables are dicts of keys. `fraytool.scene.load` walks a parsed TOML
document against these tables and reports every problem as "file: [table] key = value: what is
allowed". docs/scene-format.md documents the same schema for people.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

REQUIRED = object()


@dataclass(frozen=True)
class Key:
    kind: str
    """"float", "int", "bool", "str", "vec3", "color", "int2", "path", "table2d"."""
    default: Any = REQUIRED
    lo: Optional[float] = None
    hi: Optional[float] = None
    lo_open: bool = False
    """True: value must be > lo (not >=)."""
    hi_open: bool = False
    choices: Optional[tuple[str, ...]] = None
    doc: str = ""

    def allowed(self) -> str:
        """Human-readable statement of what the key accepts."""
        if self.choices:
            return "one of " + ", ".join(f'"{c}"' for c in self.choices)
        what = {
            "float": "a number",
            "int": "an integer",
            "bool": "true or false",
            "str": "a string",
            "vec3": "an array of 3 numbers",
            "color": "an array of 3 numbers in [0, 1]",
            "int2": "an array of 2 integers",
            "path": "an array of [t, x, y, z] arrays",
            "table2d": "an array of equal-length arrays of 0/1",
        }[self.kind]
        bounds = []
        if self.lo is not None:
            bounds.append(f"{'>' if self.lo_open else '>='} {self.lo:g}")
        if self.hi is not None:
            bounds.append(f"{'<' if self.hi_open else '<='} {self.hi:g}")
        return what + (" " + " and ".join(bounds) if bounds else "")

    def in_range(self, x: float) -> bool:
        if not math.isfinite(x):
            return False
        if self.lo is not None and (x <= self.lo if self.lo_open else x < self.lo):
            return False
        if self.hi is not None and (x >= self.hi if self.hi_open else x > self.hi):
            return False
        return True


SCENE = {
    "name": Key("str", None, doc="scene name (default: file name without .toml)"),
    "description": Key("str", ""),
    "seed": Key("int", 0, lo=0, doc="seed of all random draws"),
}

TIME = {
    "step_s": Key("float", lo=0, lo_open=True, hi=0.1, doc="explicit Euler step [s]"),
    "steps_per_frame": Key("int", lo=1, hi=100000),
    "frames": Key("int", lo=1, hi=1000000),
    "fps": Key("float", 24.0, lo=0, lo_open=True, hi=1000),
    "stability": Key("str", "warn", choices=("warn", "refuse")),
}

WORLD = {
    "gravity_m_s2": Key("vec3", (0.0, -9.81, 0.0)),
}

CLOTH = {
    "warp_yarns": Key("int", lo=2, hi=4096, doc="number of warp yarns (columns)"),
    "weft_yarns": Key("int", lo=2, hi=4096, doc="number of weft yarns (rows)"),
    "spacing_m": Key("float", lo=0, lo_open=True, hi=1.0),
    "thickness_m": Key("float", lo=0, lo_open=True, hi=0.1),
    "mass_per_crossing_kg": Key("float", lo=0, lo_open=True, hi=10.0),
    "origin_m": Key("vec3", (0.0, 0.0, 0.0)),
    "plane": Key("str", "xz", choices=("xz", "xy", "yz")),
    "weave": Key("str", "plain", choices=("plain", "twill", "satin", "table")),
    "twill": Key("str", "2/1", doc='floats over/under, e.g. "2/1", "2/2", "3/1"'),
    "satin_shafts": Key("int", 5, lo=5, hi=16),
    "table": Key("table2d", None, doc="with weave = \"table\": rows of 1 (weft on top) / 0 (warp on top)"),
}

SPRINGS = {
    "structural_n_per_m": Key("float", lo=0, lo_open=True, hi=1e9),
    "bend_n_per_m": Key("float", 0.0, lo=0, hi=1e9),
    "shear_n_per_m": Key("float", 0.0, lo=0, hi=1e9),
    "damping": Key("float", 0.01, lo=0, hi=1),
}

STRAIN = {
    "limit": Key("float", 0.10, lo=0, lo_open=True, hi=10),
    "max_iterations": Key("int", 40, lo=0, hi=100000),
    "tolerance": Key("float", 1e-4, lo=0, hi=1),
}

TEARING = {
    "enabled": Key("bool", False),
    "yarn_level": Key("bool", True),
    "transition_strain": Key("float", 0.12, lo=0, lo_open=True, hi=10),
    "break_strain": Key("float", 0.2, lo=0, lo_open=True, hi=10),
    "break_strain_spread": Key("float", 0.03, lo=0, hi=10),
    "disconnect_factor": Key("float", 3.0, lo=1, hi=1000),
}

SELF_COLLISION = {
    "enabled": Key("bool", False),
    "iterations": Key("int", 4, lo=1, hi=1000),
    "friction": Key("float", 0.2, lo=0, hi=10),
}

BODY = {
    "name": Key("str"),
    "shape": Key("str", choices=("sphere", "box", "plane")),
    "motion": Key("str", "static", choices=("static", "kinematic", "dynamic")),
    "position_m": Key("vec3", (0.0, 0.0, 0.0)),
    "radius_m": Key("float", None, lo=0, lo_open=True, hi=100),
    "half_extents_m": Key("vec3", None),
    "normal": Key("vec3", (0.0, 1.0, 0.0)),
    "rotation_deg": Key("vec3", (0.0, 0.0, 0.0)),
    "velocity_m_s": Key("vec3", (0.0, 0.0, 0.0)),
    "path": Key("path", ()),
    "mass_kg": Key("float", 1.0, lo=0, lo_open=True, hi=1e6),
    "gravity": Key("bool", True),
    "friction": Key("float", 0.3, lo=0, hi=10),
    "collide": Key("bool", True),
    "start_s": Key("float", 0.0, lo=0),
}

ATTACHMENT = {
    "body": Key("str"),
    "edge": Key("str", None, choices=("left", "right", "bottom", "top")),
    "corner": Key("str", None, choices=("bottom_left", "bottom_right", "top_left", "top_right")),
    "corner_size": Key("int", 1, lo=1, hi=4096),
    "warp_range": Key("int2", None, doc="inclusive range of warp yarn indices i"),
    "weft_range": Key("int2", None, doc="inclusive range of weft yarn indices j"),
    "region_center_m": Key("vec3", None),
    "region_radius_m": Key("float", 0.0, lo=0),
}

CAMERA = {
    "position_m": Key("vec3", (0.0, 0.3, 0.6)),
    "target_m": Key("vec3", (0.0, 0.0, 0.0)),
    "up": Key("vec3", (0.0, 1.0, 0.0)),
    "fov_deg": Key("float", 40.0, lo=1, hi=170),
}

RENDER = {
    "resolution": Key("int2", (640, 360), lo=2, hi=8192),
    "samples": Key("int", 4, lo=0, hi=64),
    "warp_color": Key("color", (0.80, 0.30, 0.25)),
    "weft_color": Key("color", (0.90, 0.85, 0.70)),
    "background": Key("color", (0.08, 0.09, 0.11)),
    "body_color": Key("color", (0.55, 0.6, 0.7)),
    "light_direction": Key("vec3", (-0.4, 1.0, 0.6)),
    "light_intensity": Key("float", 1.0, lo=0, hi=100),
    "ambient": Key("float", 0.25, lo=0, hi=1),
    "specular": Key("float", 0.35, lo=0, hi=10),
    "shininess": Key("float", 40.0, lo=1, hi=10000),
    "yarn_radius_m": Key("float", 0.0, lo=0, hi=1),
    "fade_length_m": Key("float", 0.0, lo=0, hi=10),
    "spline_samples": Key("int", 4, lo=1, hi=64),
    "tube_sides": Key("int", 6, lo=3, hi=64),
    "ground_plane": Key("bool", False),
    "ground_height_m": Key("float", 0.0),
}

OUTPUT = {
    "mp4": Key("bool", True),
    "png": Key("bool", False),
    "crf": Key("int", 18, lo=0, hi=51),
}

CHECKS = {
    "frames": Key("int", 0, lo=0),
    "all_finite": Key("bool", True),
    "max_strain_below": Key("float", None, lo=0, lo_open=True),
    "min_broken_springs": Key("int", None, lo=0),
    "max_broken_springs": Key("int", None, lo=0),
    "min_yarn_level_masses": Key("int", None, lo=0),
    "max_yarn_level_masses": Key("int", None, lo=0),
    "attachments_follow": Key("bool", True),
}

# Top-level layout: name -> (schema, kind) where kind is "table", "array" (array of tables) or a
# nested dict of sub-tables.
TOP = {
    "scene": SCENE,
    "time": TIME,
    "world": WORLD,
    "cloth": CLOTH,
    "cloth.springs": SPRINGS,
    "cloth.strain": STRAIN,
    "cloth.tearing": TEARING,
    "self_collision": SELF_COLLISION,
    "bodies": BODY,
    "attachments": ATTACHMENT,
    "camera": CAMERA,
    "render": RENDER,
    "output": OUTPUT,
    "checks": CHECKS,
}
REQUIRED_TABLES = ("time", "cloth", "cloth.springs")
ARRAY_TABLES = ("bodies", "attachments")
