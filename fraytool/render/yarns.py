"""Yarn centre lines of one frame: control points of every weft and warp yarn, split at cuts.

Input contract (docs/architecture.md): crossing c = j * warp_yarns + i; weft yarn j runs through
crossings (0, j), (1, j), ...; warp yarn i through (i, 0), (i, 1), ....
- A base-level crossing gives a weft point and a warp point x_c ± (T/2) n_c, the weft up where the
  weave says so (docs/method.md §5, `fraytool.grid.base_yarn_points`).
- A yarn-level crossing (mass couple, §3.3) gives its own masses: particle slot c is the weft mass,
  slot crossing_count + c the warp mass.
- A dead structural spring (`weft_structural_spring[j, i]` between crossings i and i+1 of weft j,
  `warp_structural_spring[i, j]` between crossings j and j+1 of warp i) splits its yarn there. The
  two ends it leaves are *broken* ends (they fade out); the first and last point of a yarn are the
  cloth border (they do not), and so are the ends at a spring cut before the shot (`spring_precut`,
  a [[cuts]] snip: scissors leave a clean edge).
Pieces of a single point (a crossing cut off on both sides) are dropped: there is no yarn to draw.
One numba loop per family (`_family_pieces`) walks every yarn of the frame and cuts its pieces.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Mapping

import numba
import numpy as np

from fraytool.grid import base_yarn_points, crossing_normals, yarn_neighbours
from fraytool.kinds import STITCH

WEFT = 0
WARP = 1


@dataclass(frozen=True)
class YarnPieces:
    points: np.ndarray
    """Control points of all pieces [m], shape (N, 3), float64; piece p owns offsets[p]:offsets[p+1]."""
    offsets: np.ndarray
    """Shape (K + 1,), int64."""
    kind: np.ndarray
    """WEFT (0) or WARP (1) per piece, shape (K,), int8."""
    yarn: np.ndarray
    """Yarn index per piece (j for a weft, i for a warp), shape (K,), int32."""
    first_crossing: np.ndarray
    """Crossing at the piece's first control point, shape (K,), int32."""
    broken_start: np.ndarray
    """True where the piece starts at a cut (not at the cloth border), shape (K,), bool."""
    broken_end: np.ndarray
    """True where the piece ends at a cut, shape (K,), bool."""
    normal: np.ndarray
    """Cloth normal at the piece's first crossing (orients the tube frames), shape (K, 3)."""
    place: np.ndarray = None
    """Grid place j * warp_yarns + i of each control point, (N,) int64; -1 on a seam's stitch; None when
    not asked for (yarn_pieces' `with_places`)."""
    color: np.ndarray = None
    """Palette index per piece (fraytool.render.color.yarn_palette: 2 panel + kind for yarns, 2 P for a
    seam's stitch), shape (K,), float32; None: the kind (one panel)."""

    @property
    def count(self) -> int:
        return int(self.kind.shape[0])

    @property
    def color_index(self) -> np.ndarray:
        """Palette index per piece (see `color`), float32."""
        return self.kind.astype(np.float32) if self.color is None else self.color


def _scalar(topology: Mapping[str, np.ndarray], key: str) -> float:
    return np.asarray(topology[key]).item()


def yarn_points(topology: Mapping[str, np.ndarray], particle_position_m: np.ndarray,
                crossing_yarn_level: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(weft point, warp point, cloth normal) of every crossing, each (C, 3) float64."""
    C = int(_scalar(topology, "crossing_count"))
    W = int(_scalar(topology, "warp_yarns"))
    H = int(_scalar(topology, "weft_yarns"))
    T = float(_scalar(topology, "thickness_m"))
    pos = np.ascontiguousarray(particle_position_m, dtype=np.float64)
    level = np.ascontiguousarray(crossing_yarn_level, dtype=np.bool_)
    # The crossing's centre: its base mass, or the middle of its couple.
    centre = np.empty((C, 3))
    _centres(pos, level, centre)
    n = crossing_normals(centre, W, H, _neighbours(topology, C, W, H))
    weft_pt, warp_pt = base_yarn_points(centre, n, np.asarray(topology["crossing_weft_on_top"]), T)
    couple = np.flatnonzero(level)                     # yarn level: the couple's own masses
    weft_pt[couple] = pos[couple]
    warp_pt[couple] = pos[C + couple]
    return weft_pt, warp_pt, n


@numba.njit(cache=True)
def _centres(pos, level, centre_out):  # pragma: no cover - numba
    """Crossing c's centre: its weft (base) mass, or the middle of its couple where it is at yarn level."""
    C = centre_out.shape[0]
    for c in range(C):
        for k in range(3):
            centre_out[c, k] = 0.5 * (pos[c, k] + pos[C + c, k]) if level[c] else pos[c, k]


def _neighbours(topology: Mapping[str, np.ndarray], C: int, W: int, H: int):
    """Yarn neighbours of a shaped panel's crossings (fraytool.grid.yarn_neighbours); None for a full grid."""
    if C == W * H:
        return None
    return yarn_neighbours(np.asarray(topology["crossing_weft_springs"]), np.asarray(topology["crossing_warp_springs"]),
                           np.asarray(topology["spring_crossing_a"]), np.asarray(topology["spring_crossing_b"]))


def crossing_places(topology: Mapping[str, np.ndarray]) -> np.ndarray:
    """Place j * warp_yarns + i on the grid of every crossing, shape (C,), int64 (a full grid: 0..C-1)."""
    C = int(_scalar(topology, "crossing_count"))
    if "crossing_grid_i" not in topology:  # frames written before shaped panels
        return np.arange(C, dtype=np.int64)
    W = int(_scalar(topology, "warp_yarns"))
    return np.asarray(topology["crossing_grid_j"], np.int64) * W + np.asarray(topology["crossing_grid_i"], np.int64)


def _on_grid(points: np.ndarray, places: np.ndarray, size: int) -> np.ndarray:
    out = np.zeros((size, 3))
    out[places] = points
    return out


def yarn_pieces(topology: Mapping[str, np.ndarray], particle_position_m: np.ndarray,
                crossing_yarn_level: np.ndarray, spring_alive: np.ndarray, hidden=None,
                with_places: bool = False, points=None) -> YarnPieces:
    """All yarn pieces of a frame (see the module docstring for the rules).

    `hidden`: optional (weft (H, W - 1), warp (W, H - 1)) bool links that another representation draws
    (the far field, fraytool.render.farfield): the yarn is split there like at a cut, and the ends it
    leaves are clean (they do not fade). `with_places`: also give each control point's grid place.
    `points`: yarn_points of this frame, if already computed."""
    W = int(_scalar(topology, "warp_yarns"))
    H = int(_scalar(topology, "weft_yarns"))
    alive = np.asarray(spring_alive, dtype=bool)
    precut = np.asarray(topology["spring_precut"], dtype=bool) if "spring_precut" in topology \
        else np.zeros(alive.shape, dtype=bool)  # frames written before cuts existed
    if "spring_cut_time_s" in topology:  # scissors leave clean ends too
        precut = precut | np.isfinite(np.asarray(topology["spring_cut_time_s"]))
    weft_pt, warp_pt, normal = points if points is not None else \
        yarn_points(topology, particle_position_m, crossing_yarn_level)
    places = crossing_places(topology)
    if places.size != W * H:  # a shaped panel: lay its crossings on the full grid (gaps are never drawn)
        crossing = np.full(W * H, -1, np.int64)
        crossing[places] = np.arange(places.size)
        weft_pt, warp_pt = (_on_grid(p, places, W * H) for p in (weft_pt, warp_pt))
        crossing = crossing.reshape(H, W)
    else:
        crossing = np.arange(W * H).reshape(H, W)

    # Weft yarn j = row j; warp yarn i = column i. No spring (-1, a shaped panel's gap): a clean end.
    weft_s = np.asarray(topology["weft_structural_spring"])
    warp_s = np.asarray(topology["warp_structural_spring"])
    weft_link = (weft_s >= 0) & alive[weft_s]
    warp_link = (warp_s >= 0) & alive[warp_s]
    weft_clean = (weft_s < 0) | precut[weft_s]
    warp_clean = (warp_s < 0) | precut[warp_s]
    if hidden is not None:
        hw, hv = (np.asarray(h, dtype=bool).reshape(s.shape) for h, s in zip(hidden, (weft_s, warp_s)))
        weft_link, warp_link = weft_link & ~hw, warp_link & ~hv
        weft_clean, warp_clean = weft_clean | hw, warp_clean | hv
    weft = _cut_family(WEFT, weft_pt, weft_link.reshape(H, W - 1), weft_clean.reshape(H, W - 1), crossing, W, normal)
    warp = _cut_family(WARP, warp_pt, warp_link.reshape(W, H - 1), warp_clean.reshape(W, H - 1), crossing, W, normal)
    pieces = YarnPieces(
        points=np.concatenate([weft.points, warp.points]),
        offsets=np.concatenate([weft.offsets[:-1], len(weft.points) + warp.offsets]),
        kind=np.concatenate([weft.kind, warp.kind]),
        yarn=np.concatenate([weft.yarn, warp.yarn]),
        first_crossing=np.concatenate([weft.first_crossing, warp.first_crossing]),
        broken_start=np.concatenate([weft.broken_start, warp.broken_start]),
        broken_end=np.concatenate([weft.broken_end, warp.broken_end]),
        normal=np.concatenate([weft.normal, warp.normal]),
        place=np.concatenate([weft.place, warp.place]) if with_places else None,
    )
    if "crossing_panel" not in topology or int(np.asarray(topology["crossing_panel"]).max(initial=0)) == 0:
        if not (np.asarray(topology["spring_kind"]) == STITCH).any():
            return pieces  # one panel, no seams: colours by kind, as always
    return _with_panels_and_stitches(pieces, topology, particle_position_m, alive, normal)


def _cut_family(kind: int, grid_pt: np.ndarray, link: np.ndarray, clean: np.ndarray, crossing: np.ndarray, W: int,
                normal: np.ndarray) -> YarnPieces:
    """The pieces of the wefts (kind WEFT: link, clean (H, W - 1)) or the warps (WARP: (W, H - 1)), with
    their places (_family_pieces). grid_pt: points by grid place; crossing (H, W): the crossing at each
    place; normal: per crossing."""
    Y, n = link.shape[0], link.shape[1] + 1
    most = Y * n // 2                                           # a piece has at least 2 points
    points, place = np.empty((Y * n, 3)), np.empty(Y * n, np.int64)
    offsets, yarn, first = np.empty(most + 1, np.int64), np.empty(most, np.int32), np.empty(most, np.int32)
    broken = np.empty((most, 2), np.bool_)
    count = _family_pieces(np.ascontiguousarray(grid_pt, dtype=np.float64), kind == WEFT, W, np.ascontiguousarray(link),
                           np.ascontiguousarray(clean), crossing.reshape(-1), points, place, offsets, yarn, first,
                           broken)
    rows = offsets[count]
    return YarnPieces(points=points[:rows], offsets=offsets[:count + 1], kind=np.full(count, kind, dtype=np.int8),
                      yarn=yarn[:count], first_crossing=first[:count], broken_start=broken[:count, 0],
                      broken_end=broken[:count, 1], normal=normal[first[:count]], place=place[:rows])


@numba.njit(cache=True)
def _family_pieces(grid_pt, weft, W, link, clean, crossing, points_out, place_out, offsets_out, yarn_out, first_out,
                   broken_out):  # pragma: no cover - numba
    """The pieces of one family (module docstring): yarn y (a weft row j, or a warp column i) runs through
    its n points, split where `link` (Y, n - 1) is dead; runs of one point are dropped. grid_pt (W H, 3):
    points by grid place j W + i; crossing (W H,): the crossing at each place. A piece's start (end) is
    broken unless it is the yarn's first (last) point or `clean` says the link before (after) it was
    snipped (broken_out[p]: start, end). Returns the piece count; offsets_out[p] is piece p's first row,
    offsets_out[count] the rows."""
    Y, n = link.shape[0], link.shape[1] + 1
    count = 0
    row = 0
    for y in range(Y):
        k = 0
        while k < n:
            e = k
            while e < n - 1 and link[y, e]:
                e += 1
            if e > k:
                offsets_out[count] = row
                yarn_out[count] = y
                first_out[count] = crossing[y * W + k] if weft else crossing[k * W + y]
                broken_out[count, 0] = k != 0 and not clean[y, k - 1]
                broken_out[count, 1] = e != n - 1 and not clean[y, e]
                for q in range(k, e + 1):
                    place = y * W + q if weft else q * W + y
                    place_out[row] = place
                    points_out[row, 0] = grid_pt[place, 0]
                    points_out[row, 1] = grid_pt[place, 1]
                    points_out[row, 2] = grid_pt[place, 2]
                    row += 1
                count += 1
            k = e + 1
    offsets_out[count] = row
    return count


def _with_panels_and_stitches(pieces: YarnPieces, topology: Mapping[str, np.ndarray], particle_position_m: np.ndarray,
                              alive: np.ndarray, normal: np.ndarray) -> YarnPieces:
    """Colour each piece by its panel, and add every live stitch of a seam as a piece of two points (its
    two masses), in the thread's colour (fraytool.render.color)."""
    from fraytool.render.color import color_index

    panel = np.asarray(topology["crossing_panel"]) if "crossing_panel" in topology else \
        np.zeros(int(_scalar(topology, "crossing_count")), np.int32)
    color = color_index(pieces.kind, panel[pieces.first_crossing])
    kind = np.asarray(topology["spring_kind"])
    st = np.flatnonzero((kind == STITCH) & alive)
    if not st.size:
        return replace(pieces, color=color)
    a, b = np.asarray(topology["spring_crossing_a"])[st], np.asarray(topology["spring_crossing_b"])[st]
    x = np.asarray(particle_position_m, np.float64)
    thread = color_index(np.zeros(1, np.int8), np.array([int(panel.max()) + 1]))[0]
    return YarnPieces(
        points=np.concatenate([pieces.points, np.stack([x[a], x[b]], axis=1).reshape(-1, 3)]),
        offsets=np.concatenate([pieces.offsets, pieces.offsets[-1] + 2 * np.arange(1, st.size + 1)]),
        kind=np.concatenate([pieces.kind, np.full(st.size, WEFT, np.int8)]),
        yarn=np.concatenate([pieces.yarn, np.full(st.size, -1, np.int32)]),
        first_crossing=np.concatenate([pieces.first_crossing, a.astype(np.int32)]),
        broken_start=np.concatenate([pieces.broken_start, np.zeros(st.size, bool)]),
        broken_end=np.concatenate([pieces.broken_end, np.zeros(st.size, bool)]),
        normal=np.concatenate([pieces.normal, normal[a]]),
        place=None if pieces.place is None else np.concatenate([pieces.place, np.full(2 * st.size, -1, np.int64)]),
        color=np.concatenate([color, np.full(st.size, thread, np.float32)]),
    )
