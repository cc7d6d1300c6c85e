"""Camera matrices (right-handed, OpenGL clip space) from a CameraSpec.

Matrices are NumPy float64, row-major, applied to column vectors (p_clip = P @ V @ p_world);
upload them transposed for GLSL's column-major mat4.

A moving camera (docs/rendering.md "A moving camera"): `position_keys_m`, `target_keys_m` and
`fov_keys_deg` key the eye, the target and the field of view over time, each interpolated as a body's
path is (fraytool.sim.paths: linear, or the Barry-Goldman Catmull-Rom through the keys) and held before
its first key and after its last; a value without keys is the static `position_m`, `target_m`, `fov_deg`.
`camera_at(spec, t)` is the static camera of time t; a frame is drawn, exported and projected with the
camera of its record's time.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from fraytool.errors import InputError
from fraytool.scene.spec import CameraSpec

FOV_RANGE_DEG = (1.0, 170.0)
"""A keyed field of view between keys is kept in this range (a Catmull-Rom may overshoot its keys)."""


def is_animated(spec: CameraSpec) -> bool:
    """True when the camera has keys (position, target or field of view)."""
    return bool(spec.position_keys_m or spec.target_keys_m or spec.fov_keys_deg)


def camera_at(spec: CameraSpec, time_s: float) -> CameraSpec:
    """The static camera (no keys) at time_s: each keyed value on its keys (module docstring), the others
    as they are. A camera without keys is returned as it is."""
    if not is_animated(spec):
        return spec
    from fraytool.sim.paths import path_position_m  # here: a static camera does not load the simulator

    kind = spec.interpolation
    position, target, fov = spec.position_m, spec.target_m, spec.fov_deg
    if spec.position_keys_m:
        position = tuple(float(v) for v in path_position_m(np.asarray(spec.position_keys_m, float), kind, time_s))
    if spec.target_keys_m:
        target = tuple(float(v) for v in path_position_m(np.asarray(spec.target_keys_m, float), kind, time_s))
    if spec.fov_keys_deg:
        keys = np.asarray(spec.fov_keys_deg, float)
        padded = np.column_stack([keys, np.zeros((len(keys), 2))])  # (t, fov, 0, 0): a path of one number
        fov = float(np.clip(path_position_m(padded, kind, time_s)[0], *FOV_RANGE_DEG))
    return dataclasses.replace(spec, position_m=position, target_m=target, fov_deg=fov,
                               position_keys_m=(), target_keys_m=(), fov_keys_deg=())


def key_times_s(spec: CameraSpec) -> list[float]:
    """Every key time of the camera, sorted (none for a static camera)."""
    rows = (*spec.position_keys_m, *spec.target_keys_m, *spec.fov_keys_deg)
    return sorted({float(r[0]) for r in rows})


def check_camera(spec: CameraSpec) -> None:
    """InputError when the camera cannot look: its eye on its target or `up` along its view direction, at
    time 0 and at each key's time."""
    for t in [0.0] + key_times_s(spec):
        try:
            Camera(spec, t)
        except InputError as exc:
            raise InputError(f"{exc} (at t = {t:g} s)" if is_animated(spec) else str(exc)) from None


def look_at(eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> np.ndarray:
    """World -> view matrix: the camera at `eye` looks down -z towards `target`, y up."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    f = target - eye
    fl = np.linalg.norm(f)
    if fl < 1e-12:
        raise InputError(f"camera position {_fmt(eye)} equals its target: the view direction is undefined")
    f /= fl
    s = np.cross(f, up)
    sl = np.linalg.norm(s)
    if sl < 1e-9:
        raise InputError(f"camera up {_fmt(up)} is parallel to the view direction {_fmt(f)}: "
                         "choose a different up vector or camera position")
    s /= sl
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def gl_matrix_bytes(m: np.ndarray) -> bytes:
    """A row-major matrix (3 x 3 or 4 x 4) as the float32 column-major bytes a GLSL mat3 / mat4
    uniform takes (the transpose, module docstring)."""
    return np.ascontiguousarray(np.asarray(m, dtype=np.float32).T).tobytes()


def _fmt(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{float(x):g}" for x in v) + ")"


def perspective(fov_y_deg: float, aspect: float, near: float, far: float) -> np.ndarray:
    """View -> clip matrix for a vertical field of view."""
    f = 1.0 / math.tan(math.radians(fov_y_deg) / 2.0)
    m = np.zeros((4, 4))
    m[0, 0] = f / aspect
    m[1, 1] = f
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2.0 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def window_depth_to_distance(depth: np.ndarray, near: float, far: float) -> np.ndarray:
    """Window depth d in [0, 1] (the depth buffer, glDepthRange 0..1) of the `perspective` projection
    -> distance along the view axis [m] (-z in view space), +inf where d = 1 (cleared: nothing drawn).

    The projection maps view z (< 0 in front) to clip z_c = A z + B with w_c = -z, where
    A = (f + n) / (n - f) and B = 2 f n / (n - f); so z_ndc = z_c / w_c = -A + B / D with D = -z,
    and with z_ndc = 2 d - 1: D = B / (z_ndc + A). d = 0 gives D = n and d = 1 gives D = f."""
    d = np.asarray(depth, dtype=np.float64)
    a = (far + near) / (near - far)
    b = 2.0 * far * near / (near - far)
    with np.errstate(divide="ignore"):
        distance = b / ((2.0 * d - 1.0) + a)
    return np.where(d >= 1.0, np.inf, distance).astype(np.float32)


class Camera:
    """A CameraSpec with its view matrix and clip planes (near/far scale with the target distance).

    A keyed camera is its pose at `time_s` (`spec` is then that static pose, `keyed` the CameraSpec with
    its keys); `at(t)` gives the camera of another time (itself when the camera has no keys)."""

    def __init__(self, spec: CameraSpec, time_s: float = 0.0):
        self.keyed = spec
        self.time_s = float(time_s)
        spec = camera_at(spec, time_s)
        self.spec = spec
        self.eye = np.asarray(spec.position_m, dtype=np.float64)
        self.target = np.asarray(spec.target_m, dtype=np.float64)
        self.view = look_at(self.eye, self.target, spec.up)
        distance = float(np.linalg.norm(self.target - self.eye))
        self.near = distance / 200.0
        self.far = distance * 200.0

    def at(self, time_s: float) -> "Camera":
        """The camera at time_s: this one when it has no keys (or is of that time), else a new one."""
        if not is_animated(self.keyed) or float(time_s) == self.time_s:
            return self
        return Camera(self.keyed, time_s)

    def view_distance(self, window_depth: np.ndarray) -> np.ndarray:
        """Depth-buffer values -> distance along the view axis [m], +inf where nothing was drawn."""
        return window_depth_to_distance(window_depth, self.near, self.far)

    def view_proj(self, aspect: float) -> np.ndarray:
        return perspective(self.spec.fov_deg, aspect, self.near, self.far) @ self.view

    def view_depth(self, points: np.ndarray) -> np.ndarray:
        """Signed view-space z of points (more negative = farther), shape (N,)."""
        return np.asarray(points, dtype=np.float64) @ self.view[2, :3] + self.view[2, 3]
