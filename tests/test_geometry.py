"""fraytool.geometry, each routine once against a plain NumPy version written here: closest points of
segments (against a dense search of the parameter square), triangle normals and closest points (against
np.cross and a dense search of the triangle), world and body frames (against R^T (x - c) and c + R l),
rotations and quaternions (against rotation matrices built axis by axis)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fraytool.geometry.frames import rotate, to_body, to_world
from fraytool.geometry.rotations import (euler_rotation, quat_from_euler_deg, quat_multiply, quat_to_matrix,
                                         quaternion_wxyz, rotation_from_y, rotation_vector, slerp)
from fraytool.geometry.segments import segment_closest_params
from fraytool.geometry.triangles import closest_on_triangle, triangle_normal, unit_normals

pytestmark = pytest.mark.fast

RNG = np.random.default_rng(20261206)


def _axis_rotation(axis: int, deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    i, j = [k for k in range(3) if k != axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    if axis == 1:  # about y: x' = c x + s z
        r[i, j], r[j, i] = s, -s
    return r


def test_closest_points_of_segments_are_the_dense_searchs():
    u = np.linspace(0.0, 1.0, 401)
    for _ in range(40):
        p0, p1, q0, q1 = RNG.normal(size=(4, 3))
        if RNG.random() < 0.25:
            q1 = q0 + 2.0 * (p1 - p0)  # parallel
        s, t = segment_closest_params(*p0, *p1, *q0, *q1)
        assert 0.0 <= s <= 1.0 and 0.0 <= t <= 1.0
        d = np.linalg.norm(p0 + s * (p1 - p0) - (q0 + t * (q1 - q0)))
        grid = (p0 + u[:, None, None] * (p1 - p0)) - (q0 + u[None, :, None] * (q1 - q0))
        assert d <= np.linalg.norm(grid, axis=2).min() + 1e-12


def test_a_triangles_normal_and_closest_point_are_numpys():
    w = np.linspace(0.0, 1.0, 201)
    a_, b_ = np.meshgrid(w, w)
    inside = a_ + b_ <= 1.0
    for _ in range(30):
        a, b, c, p = RNG.normal(size=(4, 3))
        np.testing.assert_allclose(triangle_normal(*a, *b, *c), np.cross(b - a, c - a), rtol=1e-12, atol=1e-15)
        qx, qy, qz, wa, wb, wc = closest_on_triangle(*p, *a, *b, *c)
        q = np.array([qx, qy, qz])
        assert min(wa, wb, wc) >= 0.0 and abs(wa + wb + wc - 1.0) < 1e-12
        np.testing.assert_allclose(wa * a + wb * b + wc * c, q, atol=1e-12)
        samples = a + a_[inside][:, None] * (b - a) + b_[inside][:, None] * (c - a)
        assert np.linalg.norm(p - q) <= np.linalg.norm(samples - p, axis=1).min() + 1e-12


def test_world_and_body_frames_are_the_matrix_products():
    for _ in range(20):
        rot = euler_rotation(tuple(RNG.uniform(-180, 180, 3)))
        c, x = RNG.normal(size=(2, 3))
        local = np.array(to_body(rot, c, *x))
        np.testing.assert_allclose(local, rot.T @ (x - c), atol=1e-14)
        np.testing.assert_allclose(to_world(rot, c, *local), x, atol=1e-14)
        np.testing.assert_allclose(rotate(rot, *local), rot @ local, atol=1e-14)


def test_euler_angles_quaternions_and_matrices_agree():
    for _ in range(30):
        deg = tuple(RNG.uniform(-170, 170, 3))
        R = euler_rotation(deg)
        want = _axis_rotation(2, deg[2]) @ _axis_rotation(1, deg[1]) @ _axis_rotation(0, deg[0])
        np.testing.assert_allclose(R, want, atol=1e-14)                      # R = Rz Ry Rx
        np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
        q = quat_from_euler_deg(deg)
        np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-13)
        back = quaternion_wxyz(R)
        assert min(np.abs(back - q).max(), np.abs(back + q).max()) < 1e-12  # q and -q are one rotation
        v = rotation_vector(R)
        angle = np.linalg.norm(v)
        K = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / max(angle, 1e-300)
        np.testing.assert_allclose(np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K, R, atol=1e-12)


def test_slerp_runs_the_short_great_circle_at_constant_speed():
    a, b = quat_from_euler_deg((0.0, 0.0, 0.0)), quat_from_euler_deg((0.0, 0.0, 90.0))
    half = slerp(a, b, 0.5)
    np.testing.assert_allclose(quat_to_matrix(half), euler_rotation((0.0, 0.0, 45.0)), atol=1e-14)
    np.testing.assert_allclose(slerp(a, b, 1.0), b, atol=1e-15)
    np.testing.assert_allclose(quat_multiply(b, a), b, atol=1e-15)


def test_the_rotation_from_y_takes_y_to_the_normal():
    for _ in range(20):
        n = RNG.normal(size=3)
        R = rotation_from_y(n)
        np.testing.assert_allclose(R @ [0.0, 1.0, 0.0], n / np.linalg.norm(n), atol=1e-14)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


def test_unit_normals_are_the_kernels_normal_made_unit():
    rng = np.random.default_rng(4)
    corners = rng.normal(size=(50, 3, 3))
    expected = np.array([triangle_normal(*c[0], *c[1], *c[2]) for c in corners])
    expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    np.testing.assert_allclose(unit_normals(corners), expected, rtol=1e-12, atol=1e-15)
    assert not unit_normals(np.zeros((1, 3, 3))).any()  # a degenerate triangle: 0, not NaN
