"""A warning for an [[attachments]] entry that holds no crossing (docs/scene-format.md, [[attachments]]).

Each key of an attachment can be valid while the whole selects nothing: a region whose centre is off the
cloth, a corner block or a yarn range where a shaped panel has no crossing. The body then holds nothing and
the cloth falls or hangs where it was not meant to, with no error. The builder counts what each entry
selected when it adds it (Model.attachment_entry_crossings); this names an entry that selected nothing, with the
nearest crossing for a region.
"""
from __future__ import annotations

import numpy as np


def empty_attachment_warnings(spec, model) -> list[str]:
    """One line per [[attachments]] entry that selected no crossing when the builder added it
    (Model.attachment_entry_crossings): nothing is selected again here, and no image is read again."""
    counts = np.asarray(getattr(model, "attachment_entry_crossings", np.zeros(0)))
    if not spec.attachments or counts.size != len(spec.attachments):
        return []  # a Model built in Python from other entries, or saved before the builder counted them
    panels = spec.all_panels
    names = [p.name for p in panels]
    crossing_panel = np.asarray(model.crossing_panel)
    rest = np.asarray(model.crossing_rest_position_m, dtype=np.float64)
    out = []
    for n, att in enumerate(spec.attachments):
        if counts[n]:
            continue
        k = names.index(att.panel) if att.panel in names else 0
        where = f"{spec.source}: [attachments.{n}] body {att.body!r}"
        if att.region_center_m is not None:
            mine = rest[crossing_panel == k]
            nearest = float(np.linalg.norm(mine - np.asarray(att.region_center_m), axis=1).min())
            why = (f"region_radius_m = {att.region_radius_m:g} around region_center_m = "
                   f"[{', '.join(f'{x:g}' for x in att.region_center_m)}] holds no crossing of panel "
                   f"{panels[k].name!r} (the nearest is {nearest:.4g} m from the centre)")
        else:
            why = f"selects no crossing of panel {panels[k].name!r} (a shaped panel has none there)"
        out.append(f"{where}: {why}; the body holds nothing")
    return out
