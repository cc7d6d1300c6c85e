"""The scene camera as a USD camera that sees what the renderer draws (fraytool.render.camera).

The renderer's camera (`Camera`: eye, view matrix from look_at, near = distance / 200, far =
distance x 200) and a perspective of vertical field of view `fov_deg` at the image's aspect (width /
height of [render] resolution). USD's camera looks down its local -z with +y up, as the renderer's view
space does, so its transform is the inverse of the view matrix: translate to the eye, orient by the
rotation whose columns are the view's right, up and backward axes. Its lens is a pinhole with a film
FILM_HEIGHT_MM high and as wide as the aspect asks, and the focal length that gives the vertical field
of view: GfCamera's frustum window at unit distance is +-(aperture / 2) / focalLength, so
tan(fov / 2) = (verticalAperture / 2) / focalLength. clippingRange is the renderer's (near, far).

A static camera (no [camera] keys; a fitted one, [camera] fit = true, is one camera for the whole shot
too) is written once, without time samples. A moving camera (position_keys_m, target_keys_m,
fov_keys_deg: fraytool.render.camera.camera_at) gets a time sample of its translate, orient and clipping
range at every exported frame, and of its focal length when the fov is keyed: the pose of the frame
record's time, as the renderer draws that frame; the default values are its pose at time 0.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from fraytool.geometry.rotations import quaternion_wxyz
from fraytool.render.camera import Camera, is_animated
from fraytool.scene.spec import CameraSpec

FILM_HEIGHT_MM = 24.0
"""Vertical aperture [mm]: the height of a 35 mm full-frame film, so that the focal length is the
full-frame equivalent for the vertical field of view. Only the ratio to the focal length sets the view."""


def lens_mm(fov_y_deg: float, aspect: float) -> tuple[float, float, float]:
    """(focalLength, horizontalAperture, verticalAperture) [mm] of a pinhole with vertical field of view
    `fov_y_deg` and image aspect width / height (module docstring)."""
    vertical = FILM_HEIGHT_MM
    focal = 0.5 * vertical / math.tan(math.radians(fov_y_deg) / 2.0)
    return focal, vertical * aspect, vertical


def camera_to_world(camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """(eye [m], rotation R with x_world = R x_camera) of the renderer's camera: the inverse of its view
    matrix, whose rotation rows are the camera's axes in world space."""
    return camera.eye.copy(), camera.view[:3, :3].T.copy()


def define_camera(stage, path: str, spec: CameraSpec, resolution: Sequence[int]):
    """A UsdGeom.Camera at `path` seeing what the renderer draws with `spec` at `resolution` (width,
    height in pixels); returns it."""
    from pxr import Gf, UsdGeom

    camera = Camera(spec)
    width, height = resolution
    focal, horizontal, vertical = lens_mm(camera.spec.fov_deg, width / height)
    usd = UsdGeom.Camera.Define(stage, path)
    usd.CreateProjectionAttr(UsdGeom.Tokens.perspective)
    usd.CreateFocalLengthAttr(focal)
    usd.CreateHorizontalApertureAttr(horizontal)
    usd.CreateVerticalApertureAttr(vertical)
    usd.CreateClippingRangeAttr(Gf.Vec2f(camera.near, camera.far))
    eye, rotation = camera_to_world(camera)
    usd.AddTranslateOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(*map(float, eye)))
    w, x, y, z = quaternion_wxyz(rotation)
    usd.AddOrientOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Quatd(float(w), float(x), float(y), float(z)))
    return usd


def sample_camera(usd, spec: CameraSpec, resolution: Sequence[int], time_code: float, time_s: float) -> None:
    """A moving camera's pose at time_s as time samples at time_code of the camera `define_camera` made
    (its lens too when the fov is keyed); nothing for a static camera (module docstring)."""
    from pxr import Gf, UsdGeom

    if not is_animated(spec):
        return
    camera = Camera(spec, time_s)
    translate, orient = UsdGeom.Xformable(usd).GetOrderedXformOps()
    eye, rotation = camera_to_world(camera)
    translate.Set(Gf.Vec3d(*map(float, eye)), time_code)
    w, x, y, z = quaternion_wxyz(rotation)
    orient.Set(Gf.Quatd(float(w), float(x), float(y), float(z)), time_code)
    usd.GetClippingRangeAttr().Set(Gf.Vec2f(camera.near, camera.far), time_code)
    if spec.fov_keys_deg:
        width, height = resolution
        usd.GetFocalLengthAttr().Set(lens_mm(camera.spec.fov_deg, width / height)[0], time_code)
