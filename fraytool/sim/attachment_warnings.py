"""A warning for an [[attachments]] entry that holds no crossing (docs/scene-format.md, [[attachments]]).

Each key of an attachment can be valid while the whole selects nothing: a region whose centre is off the
cloth, a corner block or a yarn range where a shaped panel has no crossing. The body then holds nothing and
the cloth falls or hangs where it was not meant to, with no error. The builder drops such an attachment
silently (it adds no held crossing); this names it, with the nearest crossing for a region.
"""
from __future__ import annotations

import numpy as np

from fraytool.sim.builder import select_crossings


def empty_attachment_warnings(spec, model) -> list[str]:
    """One line per [[attachments]] entry that selects no crossing of its panel, as the builder selects them."""
    if not spec.attachments:
        return []
    from fraytool.scene.panel_shape import PanelShapeError, panel_shape

    panels = spec.all_panels
    names = [p.name for p in panels]
    crossing_panel = np.asarray(model.crossing_panel)
    rest = np.asarray(model.crossing_rest_position_m, dtype=np.float64)
    out = []
    for n, att in enumerate(spec.attachments):
        k = names.index(att.panel) if att.panel in names else 0
        try:  # the shape as the builder made it: a mask image relative to the scene file
            present = panel_shape(panels[k], spec.source_file).present
        except (PanelShapeError, OSError):
            return out
        mine = np.flatnonzero(crossing_panel == k)
        if mine.size != int(present.sum()):
            return out  # a Model edited after building: not the scene's to judge
        local = np.full(present.shape, -1, np.int64)
        local[present] = mine  # a panel's crossings are numbered row by row over its own grid
        h, w = present.shape
        if select_crossings(att, w, h, rest[mine], local).size:
            continue
        where = f"{spec.source}: [attachments.{n}] body {att.body!r}"
        if att.region_center_m is not None:
            nearest = float(np.linalg.norm(rest[mine] - np.asarray(att.region_center_m), axis=1).min())
            why = (f"region_radius_m = {att.region_radius_m:g} around region_center_m = "
                   f"[{', '.join(f'{x:g}' for x in att.region_center_m)}] holds no crossing of panel "
                   f"{panels[k].name!r} (the nearest is {nearest:.4g} m from the centre)")
        else:
            why = f"selects no crossing of panel {panels[k].name!r} (a shaped panel has none there)"
        out.append(f"{where}: {why}; the body holds nothing")
    return out
