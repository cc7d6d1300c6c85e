"""A golden folder (docs/golden.md):

    DIR/<scene name>/golden.json              metadata: fraytool version, scene hash, settings, frames,
                                              renderer (GL renderer and version), CPU
    DIR/<scene name>/frame_NNNNNN.png         16-bit sRGB image of the frame
    DIR/<scene name>/yarns_NNNNNN.npz         yarn centre-line points (float32) and piece offsets, compressed

A frame's PNG and yarns are a few hundred kB at 1280 x 720; docs/golden.md says how to keep them in git.
"""
from __future__ import annotations

import json
import platform
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np

from fraytool.errors import InputError
from fraytool.golden.capture import Capture, machine
from fraytool.scene.spec import CameraSpec, RenderSpec, SceneSpec

METADATA = "golden.json"


def scene_dir(golden_dir: Path, spec: SceneSpec) -> Path:
    return Path(golden_dir) / spec.name


def settings_of(spec: SceneSpec, sets: list[str]) -> dict:
    """What a golden's pixels depend on besides the code: the --set overrides, the render and camera tables."""
    return {"set": list(sets), "render": asdict(spec.render), "camera": asdict(spec.camera)}


def write(golden_dir: Path, spec: SceneSpec, captured: Capture, sets: list[str]) -> Path:
    """Store a capture as the scene's golden (replacing an earlier one); returns its folder."""
    from fraytool import __version__
    from fraytool.render.png16 import write_png16
    from fraytool.scene.load import scene_hash, simulation_keys

    out = scene_dir(golden_dir, spec)
    out.mkdir(parents=True, exist_ok=True)
    for old in list(out.glob("frame_*.png")) + list(out.glob("yarns_*.npz")):
        old.unlink()
    frames = []
    for f in captured.frames:
        write_png16(out / f"frame_{f.frame:06d}.png", f.image)
        np.savez_compressed(out / f"yarns_{f.frame:06d}.npz", points_m=f.points_m, offsets=f.offsets)
        frames.append({"frame": f.frame, "torn_springs": f.torn_springs})
    meta = {"fraytool_version": __version__, "scene": spec.name, "scene_file": spec.source_file or spec.source,
            "scene_hash": scene_hash(spec), "scene_keys": simulation_keys(spec),
            "settings": settings_of(spec, sets), "frames": frames,
            "renderer": captured.renderer, "cpu": machine(), "python": platform.python_version(),
            "numpy": np.__version__, "thickness_m": spec.cloth.thickness_m}
    (out / METADATA).write_text(json.dumps(meta, indent=2, sort_keys=True) + "\n")
    return out


def read(golden_dir: Path, spec: SceneSpec, command: str) -> tuple[dict, dict[int, dict]]:
    """(metadata, frame -> {image, points, offsets, torn_springs}) of a scene's golden; InputError naming
    the command that makes it when it is missing or damaged."""
    from fraytool.render.png16 import read_png16

    folder = scene_dir(golden_dir, spec)
    try:
        meta = json.loads((folder / METADATA).read_text())
        frames = {}
        for entry in meta["frames"]:
            f = int(entry["frame"])
            yarns = np.load(folder / f"yarns_{f:06d}.npz")
            frames[f] = {"image": read_png16(folder / f"frame_{f:06d}.png")[..., :3], "points": yarns["points_m"],
                         "offsets": yarns["offsets"], "torn_springs": int(entry["torn_springs"])}
    except FileNotFoundError as exc:
        raise InputError(f"{folder}: no golden for scene {spec.name} ({Path(exc.filename).name} missing): make it "
                         f"with `{command}`") from None
    except (OSError, ValueError, KeyError) as exc:
        raise InputError(f"{folder}: the golden of scene {spec.name} is damaged ({type(exc).__name__}: {exc}); "
                         f"make it again with `{command}`") from None
    return meta, frames


def settings_differences(meta: dict, spec: SceneSpec, sets: list[str], renderer: str) -> list[str]:
    """What differs between the golden's metadata and this check: version, scene, settings, renderer, CPU."""
    from fraytool import __version__
    from fraytool.scene.load import key_changes, scene_hash, simulation_keys

    now = {"fraytool_version": __version__, "scene_hash": scene_hash(spec), "renderer": renderer, "cpu": machine()}
    out = [f"{k}: golden {meta.get(k)!r}, now {v!r}" for k, v in now.items() if meta.get(k) != v]
    if isinstance(meta.get("scene_keys"), dict) and meta.get("scene_hash") != now["scene_hash"]:
        # the scene keys that differ, by key and value (golden -> now), after the hash line
        out += key_changes(meta["scene_keys"], simulation_keys(spec), limit=20)
    old = meta.get("settings", {})
    for k, v in settings_of(spec, sets).items():
        v, was = json.loads(json.dumps(v)), old.get(k)
        if isinstance(v, dict) and isinstance(was, dict):     # [render], [camera]: the keys that differ
            added = _new_at_default(k, was, v)
            out += [f"settings.{k}.{key}: golden {_shown(was.get(key))}, now {_shown(v.get(key))}"
                    for key in sorted(set(v) | set(was)) if v.get(key) != was.get(key) and key not in added]
        elif v != was:
            out.append(f"settings.{k}: golden {_shown(was)}, now {_shown(v)}")
    return out


def _new_at_default(table: str, was: dict, now: dict) -> set:
    """Keys of [render] / [camera] that a golden's record lacks (fraytool gained them after it was made) and that
    this check has at their default: they change no pixel, so they are no difference."""
    cls = {"render": RenderSpec, "camera": CameraSpec}.get(table)
    if cls is None:
        return set()
    defaults = json.loads(json.dumps({f.name: f.default for f in fields(cls)}, default=list))
    return {key for key in now if key not in was and key in defaults and now[key] == defaults[key]}


def _shown(value, limit: int = 120) -> str:
    """A setting's value in a difference line, as JSON, cut with an ellipsis past `limit` characters."""
    text = json.dumps(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."
