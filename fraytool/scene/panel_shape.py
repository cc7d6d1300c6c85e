"""Which crossings of a panel's weave grid exist: a rectangle, a polygon (`outline_m`) or an image (`mask`).

A panel keeps the regular weave grid of docs/method.md §3.2 (yarns `spacing_m` apart), laid in the cloth's
plane at `grain_deg` from the plane's first axis; its shape only decides which crossings of that grid are
cloth. Crossing (i, j) of the grid lies at

    (u, v) = R(grain) (i0 + i, j0 + j) spacing_m

in the plane's coordinates [m] from origin_m (u along the plane's first axis, v along its second), with
(i0, j0) the grid's lowest index that the shape reaches. A rectangle is the grid of warp_yarns x
weft_yarns crossings from (0, 0). Crossings outside the shape are not built at all (docs/panels.md).

Pure NumPy and the image reader; no simulation. Problems come back as one line each, for the loader
(fraytool.scene.load) and the builder alike.
"""
from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from fraytool.files import scene_path

MAX_IMAGE_PIXELS = 64_000_000
"""Largest mask or tear map, in pixels (8000 x 8000): more than any panel's crossings (MAX_GRID); a header
claiming more is refused before its pixels are decoded."""
MIN_CROSSINGS = 4
"""Fewest crossings of a shaped panel: one cell of 2 x 2."""
MAX_GRID = 4096
"""Largest side of a panel's grid, in crossings (as warp_yarns and weft_yarns)."""


class PanelShapeError(ValueError):
    """A panel's shape cannot be made: (key, value, what is allowed) problems."""

    def __init__(self, problems: list):
        super().__init__("; ".join(p[2] for p in problems))
        self.problems = problems


@dataclass(frozen=True)
class PanelShape:
    present: np.ndarray
    """Crossings that are cloth, shape (weft_yarns, warp_yarns) = (H, W), bool."""
    uv_m: np.ndarray
    """Plane coordinates of every grid crossing [m], shape (H, W, 2), float64."""
    outline_uv_m: np.ndarray
    """The outline the panel's seams refer to, shape (K, 2) [m]: the polygon, the mask's rectangle, or the
    rectangle's four corners (segment 0 bottom, 1 right, 2 top, 3 left)."""
    extent_uv_m: tuple[float, float, float, float]
    """(u0, v0, u1, v1) of the rectangle a tear_map covers [m]."""

    @property
    def warp_yarns(self) -> int:
        return int(self.present.shape[1])

    @property
    def weft_yarns(self) -> int:
        return int(self.present.shape[0])


def _rotation(deg: float) -> np.ndarray:
    a = math.radians(deg)
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def segments_cross(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray) -> bool:
    """Closed segments a0-a1 and b0-b1 in the plane share a point."""
    def orient(p, q, r):
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])

    d1, d2 = orient(b0, b1, a0), orient(b0, b1, a1)
    d3, d4 = orient(a0, a1, b0), orient(a0, a1, b1)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and d1 != 0 and d2 != 0 and d3 != 0 and d4 != 0:
        return True

    def on(p, q, r):  # r on segment p-q, given collinear
        return min(p[0], q[0]) <= r[0] <= max(p[0], q[0]) and min(p[1], q[1]) <= r[1] <= max(p[1], q[1])

    return ((d1 == 0 and on(b0, b1, a0)) or (d2 == 0 and on(b0, b1, a1))
            or (d3 == 0 and on(a0, a1, b0)) or (d4 == 0 and on(a0, a1, b1)))


def outline_problems(outline: np.ndarray) -> list:
    """A polygon fit for a panel: at least 3 corners, no zero-length edge, no edge crossing another. The
    crossing test bins the edges on a grid and tests only edges that share a cell (a pattern exported from a
    CAD tool has thousands of points: benchmarks/outline_check.py times 2,000 and 20,000)."""
    k = outline.shape[0]
    if k < 3:
        return [("outline_m", outline.tolist(), "needs at least 3 points [u, v] (a polygon)")]
    nxt = np.roll(outline, -1, axis=0)
    same = np.flatnonzero((outline == nxt).all(axis=1))
    if same.size:
        e = int(same[0])
        return [("outline_m", f"[... {k} points]", f"points {e} and {(e + 1) % k} are equal (an edge of length 0)")]
    pair = first_crossing_edges(outline)
    if pair is not None:
        e, f = pair
        return [("outline_m", f"[... {k} points]",
                 f"edges {e} (points {e}-{(e + 1) % k}) and {f} (points {f}-{(f + 1) % k}) cross: a panel's "
                 "outline must not cross itself")]
    return []


def first_crossing_edges(outline: np.ndarray) -> Optional[tuple[int, int]]:
    """The first pair (e, f), e < f, in that order, of non-neighbouring edges of the closed polygon that share a
    point (as segments_cross), or None. Edges are binned by their bounding boxes on a grid of about k cells;
    only pairs sharing a cell are tested, all at once."""
    k = outline.shape[0]
    a, b = outline, np.roll(outline, -1, axis=0)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    origin = outline.min(axis=0)
    extent = np.maximum(outline.max(axis=0) - origin, 1e-300)
    cells = max(1, int(math.sqrt(k)))
    c0 = np.clip(np.floor((lo - origin) / extent * cells), 0, cells - 1).astype(np.int64)
    c1 = np.clip(np.floor((hi - origin) / extent * cells), 0, cells - 1).astype(np.int64)
    spans = (c1 - c0 + 1)
    count = spans[:, 0] * spans[:, 1]
    edge = np.repeat(np.arange(k), count)
    local = np.arange(int(count.sum())) - np.repeat(np.cumsum(count) - count, count)
    cx = c0[edge, 0] + local % spans[edge, 0]
    cy = c0[edge, 1] + local // spans[edge, 0]
    cell = cy * cells + cx
    order = np.lexsort((edge, cell))
    cell, edge = cell[order], edge[order]
    starts = np.flatnonzero(np.r_[True, cell[1:] != cell[:-1]])
    sizes = np.diff(np.r_[starts, cell.size])
    pairs = []
    for start, size in zip(starts[sizes > 1], sizes[sizes > 1]):
        members = edge[start:start + size]
        i, j = np.triu_indices(size, 1)
        pairs.append(np.stack([members[i], members[j]], axis=1))
    if not pairs:
        return None
    pairs = np.unique(np.sort(np.concatenate(pairs), axis=1), axis=0)
    e, f = pairs[:, 0], pairs[:, 1]
    keep = (f - e >= 2) & ~((e == 0) & (f == k - 1))  # neighbours share a corner by construction
    e, f = e[keep], f[keep]
    hit = _segments_cross_rows(a[e], b[e], a[f], b[f])
    if not hit.any():
        return None
    first = np.lexsort((f[hit], e[hit]))[0]
    return int(e[hit][first]), int(f[hit][first])


def _segments_cross_rows(a0, a1, b0, b1) -> np.ndarray:
    """segments_cross for rows of segments (N, 2 each), the same tests in the same arithmetic."""
    def orient(p, q, r):
        return (q[:, 0] - p[:, 0]) * (r[:, 1] - p[:, 1]) - (q[:, 1] - p[:, 1]) * (r[:, 0] - p[:, 0])

    def on(p, q, r):
        return ((np.minimum(p[:, 0], q[:, 0]) <= r[:, 0]) & (r[:, 0] <= np.maximum(p[:, 0], q[:, 0]))
                & (np.minimum(p[:, 1], q[:, 1]) <= r[:, 1]) & (r[:, 1] <= np.maximum(p[:, 1], q[:, 1])))

    d1, d2 = orient(b0, b1, a0), orient(b0, b1, a1)
    d3, d4 = orient(a0, a1, b0), orient(a0, a1, b1)
    proper = ((d1 > 0) != (d2 > 0)) & ((d3 > 0) != (d4 > 0)) & (d1 != 0) & (d2 != 0) & (d3 != 0) & (d4 != 0)
    touch = (((d1 == 0) & on(b0, b1, a0)) | ((d2 == 0) & on(b0, b1, a1))
             | ((d3 == 0) & on(a0, a1, b0)) | ((d4 == 0) & on(a0, a1, b1)))
    return proper | touch


def inside_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd test of points (N, 2) against a closed polygon (K, 2): True inside; shape (N,), bool. Each
    edge toggles only the points whose v it straddles (found by a sort), so the cost follows the points near
    each edge's span, not K x N."""
    inside = np.zeros(points.shape[0], bool)
    x, y = points[:, 0], points[:, 1]
    order = np.argsort(y, kind="stable")
    ys = y[order]
    k = polygon.shape[0]
    p0, p1 = polygon, np.roll(polygon, -1, axis=0)
    ylo, yhi = np.minimum(p0[:, 1], p1[:, 1]), np.maximum(p0[:, 1], p1[:, 1])
    first = np.searchsorted(ys, ylo, side="left")   # straddles: ylo <= y < yhi ((y0 > y) != (y1 > y))
    last = np.searchsorted(ys, yhi, side="left")
    for e in np.flatnonzero(last > first):
        (x0, y0), (x1, y1) = polygon[e], polygon[(e + 1) % k]
        sel = order[first[e]:last[e]]
        xc = x0 + (y[sel] - y0) * (x1 - x0) / (y1 - y0)
        inside[sel] ^= x[sel] < xc
    return inside


def read_grey(path: Path, key: str) -> np.ndarray:
    """A greyscale image in [0, 1], row 0 at the top, shape (rows, columns); PanelShapeError if it is
    not an image."""
    from PIL import Image, UnidentifiedImageError

    from fraytool.files import not_a_regular_file

    why = not_a_regular_file(path)
    if why == "no such file":
        raise PanelShapeError([(key, str(path), "no such file (relative to the scene file)")])
    if why is not None:
        raise PanelShapeError([(key, str(path), f"{why}: give a greyscale PNG")])
    try:
        with _image_header_first(Image), Image.open(path) as im:
            width, height = im.size
            if width * height > MAX_IMAGE_PIXELS:
                raise PanelShapeError([(key, str(path), f"its header claims {width} x {height} pixels, more than "
                                                        f"{MAX_IMAGE_PIXELS:,} (a panel needs no more than one per "
                                                        "crossing)")])
            im.load()
            a = np.asarray(im.convert("F"), dtype=np.float64)
            peak = 65535.0 if im.mode.startswith("I") else 255.0
    except PanelShapeError:
        raise
    except FileNotFoundError:
        raise PanelShapeError([(key, str(path), "no such file (relative to the scene file)")]) from None
    except (UnidentifiedImageError, OSError, ValueError, Image.DecompressionBombError, EOFError) as exc:
        raise PanelShapeError([(key, str(path), f"not an image PIL can read ({type(exc).__name__}); give a "
                                                "greyscale PNG")]) from None
    if a.size == 0 or min(a.shape) < 1:
        raise PanelShapeError([(key, str(path), "an empty image")])
    return np.clip(a / peak, 0.0, 1.0)


class _image_header_first:
    """Open an image with PIL's decompression-bomb check off, so that read_grey sees the size its header claims
    and refuses it by name (MAX_IMAGE_PIXELS) before any pixel is decoded."""

    def __init__(self, image_module):
        self.image = image_module

    _lock = threading.Lock()  # PIL's limit is one global: one such open at a time in a process

    def __enter__(self):
        self._lock.acquire()
        self.saved = self.image.MAX_IMAGE_PIXELS
        self.image.MAX_IMAGE_PIXELS = None

    def __exit__(self, *exc):
        self.image.MAX_IMAGE_PIXELS = self.saved
        self._lock.release()
        return False


resolve = scene_path
"""The image a panel names (fraytool.files.scene_path: the one rule for a scene's files)."""


def panel_shape(cloth, scene_file: str = "") -> PanelShape:
    """The crossings of a [cloth] panel (see the module docstring); raises PanelShapeError."""
    s = cloth.spacing_m
    outline = np.asarray(cloth.outline_m, float).reshape(-1, 2)
    if not cloth.outline_m and not cloth.mask:
        W, H = cloth.warp_yarns, cloth.weft_yarns
        jj, ii = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
        uv = np.stack([ii * s, jj * s], axis=-1).astype(float)
        w, h = (W - 1) * s, (H - 1) * s
        corners = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
        # a tear map covers a cell of spacing_m around every crossing: W x H pixels, one per crossing
        return PanelShape(np.ones((H, W), bool), uv, corners, (-0.5 * s, -0.5 * s, w + 0.5 * s, h + 0.5 * s))
    image = None
    if cloth.mask:
        w, h = cloth.mask_size_m
        outline = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
        image = read_grey(resolve(cloth.mask, scene_file), "mask")
    else:
        problems = outline_problems(outline)
        if problems:
            raise PanelShapeError(problems)
    rot = _rotation(cloth.grain_deg)
    q = outline @ rot / s  # outline in grid units: (u, v) = R q s  ->  q = R^T (u, v) / s
    lo = np.ceil(q.min(axis=0) - 1e-9).astype(np.int64)
    hi = np.floor(q.max(axis=0) + 1e-9).astype(np.int64)
    W, H = int(hi[0] - lo[0] + 1), int(hi[1] - lo[1] + 1)
    if W > MAX_GRID or H > MAX_GRID:
        key = "mask_size_m" if cloth.mask else "outline_m"
        raise PanelShapeError([(key, f"{W} x {H} crossings", f"the shape spans more than {MAX_GRID} yarns "
                                f"at spacing_m = {s:g}")])
    W, H = max(W, 1), max(H, 1)
    jj, ii = np.meshgrid(np.arange(H) + lo[1], np.arange(W) + lo[0], indexing="ij")
    grid = np.stack([ii, jj], axis=-1).astype(float) * s
    uv = grid @ rot.T
    flat = uv.reshape(-1, 2)
    if image is not None:
        rows, cols = image.shape
        px = np.floor(flat[:, 0] / w * cols).astype(np.int64)
        py = np.floor((1.0 - flat[:, 1] / h) * rows).astype(np.int64)
        ok = (px >= 0) & (px < cols) & (py >= 0) & (py < rows)
        present = np.zeros(flat.shape[0], bool)
        present[ok] = image[py[ok], px[ok]] >= 0.5
    else:
        present = inside_polygon(flat, outline)
    present = present.reshape(H, W)
    count = int(present.sum())
    if count < MIN_CROSSINGS:
        key, value = ("mask", cloth.mask) if cloth.mask else ("outline_m", f"[... {len(outline)} points]")
        raise PanelShapeError([(key, value, f"holds {count} crossing(s) at spacing_m = {s:g}; a panel needs at "
                                            f"least {MIN_CROSSINGS} (one 2 x 2 cell)")])
    if not (present[:-1, :-1] & present[1:, :-1] & present[:-1, 1:] & present[1:, 1:]).any():
        key, value = ("mask", cloth.mask) if cloth.mask else ("outline_m", f"[... {len(outline)} points]")
        raise PanelShapeError([(key, value, f"holds {count} crossings at spacing_m = {s:g} but no 2 x 2 cell of "
                                            "them (a strip one yarn wide): a panel needs at least one")])
    # trim empty rows and columns at the border of the grid
    rows_used = np.flatnonzero(present.any(axis=1))
    cols_used = np.flatnonzero(present.any(axis=0))
    sl = (slice(rows_used[0], rows_used[-1] + 1), slice(cols_used[0], cols_used[-1] + 1))
    u0, v0 = outline.min(axis=0)
    u1, v1 = outline.max(axis=0)
    return PanelShape(present[sl].copy(), uv[sl].copy(), outline, (float(u0), float(v0), float(u1), float(v1)))


def _problems(make, cloth, scene_file: str) -> list:
    """The (key, value, allowed) problems `make(cloth, scene_file)` raises: [] when it works."""
    try:
        make(cloth, scene_file)
    except PanelShapeError as exc:
        return exc.problems
    return []


def shape_problems(cloth, scene_file: str = "") -> list:
    """The shape's problems: [] when panel_shape(cloth) works."""
    return _problems(panel_shape, cloth, scene_file)


def grid_size(cloth, scene_file: str = "") -> Optional[tuple[int, int]]:
    """(warp_yarns, weft_yarns) of the panel's grid, or None when the shape has problems."""
    if not cloth.outline_m and not cloth.mask:
        return cloth.warp_yarns, cloth.weft_yarns
    try:
        shape = panel_shape(cloth, scene_file)
    except PanelShapeError:
        return None
    return shape.warp_yarns, shape.weft_yarns


TEAR_MAP_ASPECT_TOLERANCE = 0.05
"""A tear map's width / height may differ from its panel extent's by this fraction."""


def tear_map_image(cloth, scene_file: str = "") -> np.ndarray:
    """The tear map in [0, 1] (row 0 at the top), checked against the panel's extent; PanelShapeError."""
    image = read_grey(resolve(cloth.tear_map, scene_file), "tear_map")
    u0, v0, u1, v1 = panel_shape(cloth, scene_file).extent_uv_m
    rows, cols = image.shape
    want, got = (u1 - u0) / (v1 - v0), cols / rows
    if abs(got / want - 1.0) > TEAR_MAP_ASPECT_TOLERANCE:
        raise PanelShapeError([("tear_map", cloth.tear_map,
                                f"is {cols} x {rows} pixels (width / height {got:.3g}); it covers the panel's "
                                f"extent of {u1 - u0:.4g} x {v1 - v0:.4g} m (width / height {want:.3g}): give an image "
                                f"of that shape (within {TEAR_MAP_ASPECT_TOLERANCE:.0%})")])
    return image


def tear_map_problems(cloth, scene_file: str = "") -> list:
    """The tear map's problems: [] when tear_map_image(cloth) works."""
    return _problems(tear_map_image, cloth, scene_file)


def sample_map(image: np.ndarray, extent_uv_m, uv_m: np.ndarray) -> np.ndarray:
    """The image's value at plane points uv_m (N, 2) [m], the image spread over extent (u0, v0, u1, v1),
    its top row at v1 (nearest pixel, clamped at the border): shape (N,)."""
    u0, v0, u1, v1 = extent_uv_m
    rows, cols = image.shape
    px = np.clip(np.floor((uv_m[:, 0] - u0) / (u1 - u0) * cols), 0, cols - 1).astype(np.int64)
    py = np.clip(np.floor((1.0 - (uv_m[:, 1] - v0) / (v1 - v0)) * rows), 0, rows - 1).astype(np.int64)
    return image[py, px]


def distance_to_polyline(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance [m] of plane points (N, 2) to a polyline (K, 2), shape (N,)."""
    best = np.full(points.shape[0], np.inf)
    for a, b in zip(line[:-1], line[1:]):
        d = b - a
        t = np.clip(((points - a) @ d) / max(float(d @ d), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(points - (a + t[:, None] * d), axis=1))
    return best


def crossing_fraction_along(a_uv: np.ndarray, b_uv: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Where each segment a-b (N, 2 each) first meets a polyline path (K, 2), as the fraction of the
    path's length from its first point, in [0, 1]; NaN where it does not meet it: shape (N,)."""
    seg = np.diff(path, axis=0)
    lengths = np.linalg.norm(seg, axis=1)
    total = float(lengths.sum())
    before = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    out = np.full(a_uv.shape[0], np.nan)
    e = b_uv - a_uv
    for k in range(seg.shape[0]):
        p, d = path[k], seg[k]
        den = d[0] * e[:, 1] - d[1] * e[:, 0]
        w = a_uv - p
        ok = den != 0.0
        safe = np.where(ok, den, 1.0)
        t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / safe   # along the path segment
        u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / safe          # along the spring
        hit = ok & (t >= 0) & (t <= 1) & (u >= 0) & (u <= 1) & np.isnan(out)
        out[hit] = (before[k] + t[hit] * lengths[k]) / total
    return out
