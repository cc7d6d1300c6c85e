"""Where a seam's stitches go, and a warning when they start torn (docs/panels.md "Seams").

`stitch_pairs` places one seam's stitches on the two panels' border crossings; the builder calls it when a
seam is added (and the other way round, for the warning's hint), and measures the stitches where the panels
are placed: `seam_start_error` refuses a seam whose panels lie too far apart, `seam_start_warning` names one
whose stitches start torn. A stitch that starts longer than its rest length times
(1 + its break strain) breaks in the first steps: the seam opens before the shot begins. No range check
sees that (each key is valid on its own); it is what sewing the wrong segment, leaving `reverse` the
wrong way or placing the panels apart looks like, so it is named, with the seam and the lengths.
"""
from __future__ import annotations

import numpy as np

from fraytool.kinds import STITCH


SEAM_REACH_SPACINGS = 1.5
"""The seam's span along segment_a is that of panel_a's border crossings at most this many yarn spacings
from the segment's line and between its ends: an outline drawn half a spacing outside the crossings
(seam_rip's), or a spacing (an outline_m whose far edges exclude the crossings on them), keeps its edge's
crossings, and so does a bias cut's staircase of border crossings (up to about 1.2 spacings off a 45 degree
edge). Crossings a little further in change nothing: they lie along the same stretch of the line."""


def stitch_pairs(outline_a: np.ndarray, segment_a: int, panel_a: int, outline_b: np.ndarray, segment_b: int,
                 panel_b: int, reverse: bool, stitch_spacing_m: float, crossing_uv_m: np.ndarray,
                 crossing_panel: np.ndarray, border: np.ndarray, spacing_m: float) -> np.ndarray:
    """One seam's stitches as (n, 2) crossing pairs, sorted, each pair once, none joining a crossing to itself.

    The seam runs along segment_a (outline point k to k + 1, in the panel's plane [m]) over the span of
    panel_a's border crossings beside it (SEAM_REACH_SPACINGS): n + 1 points over that span at fractions
    k / n (n = its length / stitch_spacing_m, rounded; at least 1; the segment's own ends where no crossing
    lies beside it) each take the border crossing of panel_a nearest them. Over the crossings' span, not the
    outline's, an edge along the weave sewn every yarn spacing has a point on each crossing: an outline
    drawn half a spacing outside them put every point midway between two crossings, and the tie left
    crossings unstitched (seam_rip: 3 of 40) and stitched others twice. Each joins panel_b's border
    crossing nearest the point at the same fraction of segment_b as that crossing lies along segment_a
    (1 - fraction with `reverse`). Going through the crossing's own place, not the sample point, keeps a
    point midway between two crossings from pairing a crossing with the other panel's diagonal neighbour."""
    a0, a1 = outline_a[segment_a], outline_a[(segment_a + 1) % len(outline_a)]
    b0, b1 = outline_b[segment_b], outline_b[(segment_b + 1) % len(outline_b)]
    length_m = float(np.linalg.norm(a1 - a0))
    unit = (a1 - a0) / max(length_m, 1e-30)
    mine = np.flatnonzero(border & (crossing_panel == panel_a))
    rel = crossing_uv_m[mine] - a0
    t = rel @ unit
    slack = 1e-9 * max(length_m, spacing_m)  # a corner crossing on the segment's end
    beside = (np.linalg.norm(rel - t[:, None] * unit, axis=1) <= SEAM_REACH_SPACINGS * spacing_m) \
        & (t >= -slack) & (t <= length_m + slack)
    start, end = (a0, a1) if not beside.any() else (a0 + t[beside].min() * unit, a0 + t[beside].max() * unit)
    count = max(1, int(round(float(np.linalg.norm(end - start)) / stitch_spacing_m)))
    f = np.arange(count + 1) / count

    def nearest(p, pts):
        candidates = np.flatnonzero(border & (crossing_panel == p))
        d = np.linalg.norm(crossing_uv_m[candidates][None, :, :] - pts[:, None, :], axis=2)
        return candidates[d.argmin(axis=1)]

    on_a = nearest(panel_a, start + f[:, None] * (end - start))
    along = np.clip(((crossing_uv_m[on_a] - a0) @ (a1 - a0)) / float((a1 - a0) @ (a1 - a0)), 0.0, 1.0)
    fb = 1.0 - along if reverse else along
    pair = np.unique(np.stack([on_a, nearest(panel_b, b0 + fb[:, None] * (b1 - b0))], axis=1), axis=0)
    return pair[pair[:, 0] != pair[:, 1]]


def border_crossings(crossing_weft_springs: np.ndarray, crossing_warp_springs: np.ndarray) -> np.ndarray:
    """Crossings with a structural neighbour missing on some side (a -1 in their spring slots): a panel's
    border, for the builder and for the warnings on a built Model alike."""
    return (np.asarray(crossing_weft_springs) < 0).any(axis=1) | (np.asarray(crossing_warp_springs) < 0).any(axis=1)


MAX_START_STRETCH = 100.0
"""A stitch that starts longer than this many times its rest length is refused: the panels lie too far apart
to be joined by a spring (its first pull would fling the edges away: an unstable run)."""


def seam_start_error(where: str, seam, start_m: np.ndarray, rest_m: float) -> str:
    """The line refusing a seam (ModelBuilder.add_seam) whose stitches start, at the panels' rest positions
    (`start_m`, one per stitch), longer than MAX_START_STRETCH x their rest length `rest_m`: the panels are
    placed too far apart to sew. "" when they are not."""
    if not start_m.size or start_m.max() <= MAX_START_STRETCH * rest_m:
        return ""
    worst = float(start_m.max())
    return (f"{where} panel {seam.panel_a!r} segment {seam.segment_a} to panel {seam.panel_b!r} segment "
            f"{seam.segment_b}: a stitch starts {worst:.4g} m long, {worst / rest_m:.0f} times its "
            f"{1e3 * rest_m:.3g} mm: the panels are placed too far apart to sew (at most {MAX_START_STRETCH:g} "
            "times); place the edges together (origin_m, rotation_deg, wrap_radius_m)")


def seam_start_warning(where: str, seam, start_m: np.ndarray, rest_m: float, limit_m: float,
                       reverse_fits: bool) -> str:
    """The warning for a seam (ModelBuilder.add_seam) some of whose stitches start, at the panels' rest
    positions, longer than rest length x (1 + the seam's break strain), `limit_m`: they break in the first
    steps. `reverse_fits`: sewn the other way round every stitch would start within it. "" when none does."""
    torn = start_m > limit_m
    if not torn.any():
        return ""
    if reverse_fits:
        cause = (f"with reverse = {'false' if seam.reverse else 'true'} every stitch would start within it "
                 "(the two edges run the other way)")
    else:
        cause = ("the two edges lie apart where the panels are placed, or are not the edges meant: check segment_a, "
                 "segment_b, reverse and the panels' origin_m and rotation_deg")
    return (f"{where} panel {seam.panel_a!r} segment {seam.segment_a} to panel {seam.panel_b!r} "
            f"segment {seam.segment_b}{' (reverse)' if seam.reverse else ''}: {int(torn.sum())} of {start_m.size} "
            f"stitches start past their break strain (up to {1e3 * float(start_m.max()):.3g} mm, rest "
            f"{1e3 * rest_m:.3g} mm, breaking at {1e3 * limit_m:.3g} mm) and break in the first steps; {cause}")
