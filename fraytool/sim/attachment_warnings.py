"""A warning for an [[attachments]] entry that holds no crossing (docs/scene-format.md, [[attachments]]).

Each key of an attachment can be valid while the whole selects nothing: a region whose centre is off the
cloth, a corner block or a yarn range where a shaped panel has no crossing. The body then holds nothing and
the cloth falls or hangs where it was not meant to, with no error. The builder selects an entry's crossings
when it is added (ModelBuilder.add_attachment) and, when there are none, records this line, with the nearest
crossing for a region.
"""
from __future__ import annotations

import numpy as np


def empty_attachment_warning(where: str, att, panel) -> str:
    """The line for attachment `att` (an AttachmentSpec) that selected no crossing of `panel` (a PanelLayout);
    `where` names the entry ("scene.toml: [attachments.0]")."""
    if att.region_center_m is not None:
        nearest = float(np.linalg.norm(panel.rest_m - np.asarray(att.region_center_m), axis=1).min())
        why = (f"region_radius_m = {att.region_radius_m:g} around region_center_m = "
               f"[{', '.join(f'{x:g}' for x in att.region_center_m)}] holds no crossing of panel "
               f"{panel.spec.name!r} (the nearest is {nearest:.4g} m from the centre)")
    else:
        why = f"selects no crossing of panel {panel.spec.name!r} (a shaped panel has none there)"
    return f"{where} body {att.body!r}: {why}; the body holds nothing"
