"""Geometry, written once and used everywhere (docs/architecture.md): each routine here is the only one of
its kind in fraytool, tested against a plain NumPy version (tests/test_geometry.py).

- segments.py   closest points of two segments (numba; the CCD, the yarn contact, self-collision, meshes)
- triangles.py  a triangle's normal, the closest point of a triangle to a point (numba)
- frames.py     world and body frames: x_body = R^T (x - c), x_world = c + R x_body (numba)
- rotations.py  rotation matrices and unit quaternions: Euler angles, slerp-ready quaternion maths, the
                matrix <-> quaternion maps, rotation vectors (NumPy)

A leaf: NumPy and numba only.
"""
