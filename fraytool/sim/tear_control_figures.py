"""Figures per seam and per weak line (docs/panels.md): what a TD asks of a shot with seams and weak lines
(did the belly seam open, and when?), listed by `fraytool simulate --json` and `fraytool check`.

Per [[seams]] entry: its stitches, how many broke, and the frames of its first and last break; per
[[weak_lines]] entry: the springs it weakened, how many of them broke, the same frames. A spring's break frame
is the first frame whose state shows it broken (Simulation records it every frame, ShotFigures keeps it
through a resume)."""
from __future__ import annotations

from typing import Optional

import numpy as np


def tracked_springs(model) -> np.ndarray:
    """The springs whose break frames are recorded: the seams' stitches and the weakened springs."""
    tracked = np.zeros(model.spring_count, bool)
    if model.spring_seam.size:
        tracked |= model.spring_seam >= 0
    if model.spring_weak_line.size:
        tracked |= model.spring_weak_line >= 0
    return np.flatnonzero(tracked)


def tear_control_figures(model, spring_broken: Optional[np.ndarray] = None,
                         break_frame: Optional[np.ndarray] = None, spec=None) -> dict:
    """{"seams": [...], "weak_lines": [...]} (each empty where the Model has none). `spring_broken` (S,) and
    `break_frame` (the frame of each tracked_springs entry, -1 unbroken) from a run; without them the broken
    figures are None (a scene checked without running). `spec` names the panels of each entry."""
    tracked = tracked_springs(model)
    frame_of = np.full(model.spring_count, -1, np.int64)
    if break_frame is not None and break_frame.size == tracked.size:
        frame_of[tracked] = break_frame
    out = {"seams": [], "weak_lines": []}
    for table, index, key in (("seams", model.spring_seam, "stitches"), ("weak_lines", model.spring_weak_line,
                                                                          "springs_weakened")):
        if not index.size:
            continue
        entries = getattr(spec, table, None) if spec is not None else None
        for k in range(int(index.max(initial=-1)) + 1 if entries is None else len(entries)):
            mine = np.flatnonzero(index == k)
            row = {"index": k, key: int(mine.size)}
            if entries is not None:
                e = entries[k]
                row.update({"panels": [e.panel_a, e.panel_b]} if table == "seams" else {"panel": e.panel})
            if spring_broken is None:
                row.update({"broken": None, "first_break_frame": None, "last_break_frame": None})
            else:
                broke = mine[np.asarray(spring_broken, bool)[mine]]
                frames = frame_of[broke]
                frames = frames[frames >= 0]
                row.update({"broken": int(broke.size),
                            "first_break_frame": int(frames.min()) if frames.size else None,
                            "last_break_frame": int(frames.max()) if frames.size else None})
            out[table].append(row)
    return out


def figure_lines(figures: dict) -> list[str]:
    """The figures as `check` prints them, a line per seam and per weak line."""
    lines = []
    for row in figures["seams"]:
        who = f" ({' - '.join(p or 'first panel' for p in row['panels'])})" if "panels" in row else ""
        lines.append(f"seam {row['index']}{who}: {row['stitches']} stitches" + _broken(row))
    for row in figures["weak_lines"]:
        who = (f" (panel {row['panel']})" if row["panel"] else " (the first panel)") if "panel" in row else ""
        lines.append(f"weak line {row['index']}{who}: {row['springs_weakened']} springs weakened" + _broken(row))
    return lines


def _broken(row: dict) -> str:
    if row["broken"] is None:
        return ""
    if not row["broken"]:
        return ", none broken"
    return f", {row['broken']} broken, first at frame {row['first_break_frame']}, last at {row['last_break_frame']}"
