"""Files a failed run leaves beside its frames: unstable.json (the stability guard's diagnostic, strict
JSON) and the last good state's arrays (same layout as checkpoint.npz). Plain dicts and arrays in."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Optional

import numpy as np

from fraytool.io.frame_record import atomic_save_npz, atomic_write_bytes

UNSTABLE_JSON = "unstable.json"
"""Diagnostic written beside the frames of a run that became unstable."""
LAST_GOOD_STATE = "unstable_last_good_state.npz"
"""Full State just before the failed step (found by the replay), same layout as checkpoint.npz."""


def write_failure(folder: Path, diagnostic: dict, last_good_state: Optional[dict[str, np.ndarray]]) -> Path:
    """Write unstable.json (and the arrays of the last good state, if known) into `folder`; returns
    the JSON path."""
    folder = Path(folder)
    if last_good_state is not None:
        atomic_save_npz(folder / LAST_GOOD_STATE, last_good_state)
        diagnostic["last_good_state"] = LAST_GOOD_STATE
        diagnostic["last_good_state_step"] = int(last_good_state["step_index"])
    text = json.dumps(finite_json(diagnostic), indent=2, sort_keys=True, default=_json_default).encode()
    path = folder / UNSTABLE_JSON
    atomic_write_bytes(path, lambda f: f.write(text))
    return path


def finite_json(obj):
    """JSON has no NaN or infinity: write them as the strings "nan", "inf", "-inf"."""
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    if isinstance(obj, dict):
        return {k: finite_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_json(v) for v in obj]
    return obj


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return str(obj)
