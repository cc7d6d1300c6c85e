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

    from fraytool.files import not_a_regular_file

    folder = scene_dir(golden_dir, spec)

    def damaged(why: str) -> InputError:
        return InputError(f"{folder}: the golden of scene {spec.name} is damaged ({why}); make it again with "
                          f"`{command}`")

    def readable(name: str) -> Path:
        why = not_a_regular_file(folder / name)
        if why == "no such file":
            raise InputError(f"{folder}: no golden for scene {spec.name} ({name} missing): make it with `{command}`")
        if why is not None:
            raise damaged(f"{name}: {why}")
        return folder / name

    try:
        meta = json.loads(readable(METADATA).read_text())
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise damaged(f"{METADATA}: {type(exc).__name__}: {str(exc)[:120]}") from None
    entries = meta.get("frames") if isinstance(meta, dict) else None
    if not isinstance(entries, list) or not entries or not all(
            isinstance(e, dict) and _is_int(e.get("frame")) and _is_int(e.get("torn_springs")) for e in entries):
        raise damaged(f"{METADATA}: not a golden's metadata (a `frames` list of {{frame, torn_springs}} integers)")
    if not isinstance(meta.get("settings", {}), dict) or not (
            "thickness_m" not in meta or (isinstance(meta["thickness_m"], (int, float))
                                          and not isinstance(meta["thickness_m"], bool) and meta["thickness_m"] > 0)):
        raise damaged(f"{METADATA}: `settings` must be a table and `thickness_m` a positive number")
    frames = {}
    for entry in entries:
        f = entry["frame"]
        if not 0 <= f < spec.time.frames:
            raise damaged(f"{METADATA} lists frame {f}, outside the scene's frames 0..{spec.time.frames - 1}")
        try:
            with np.load(readable(f"yarns_{f:06d}.npz"), allow_pickle=False) as yarns:
                points, offsets = np.asarray(yarns["points_m"]), np.asarray(yarns["offsets"])
            image = read_png16(readable(f"frame_{f:06d}.png"))
        except InputError:
            raise
        except Exception as exc:  # zipfile, PNG and format errors of a damaged or foreign file: one line
            raise damaged(f"frame {f}: {type(exc).__name__}: {str(exc)[:120]}") from None
        if points.ndim != 2 or points.shape[1] != 3 or not np.issubdtype(points.dtype, np.floating) \
                or offsets.ndim != 1 or not np.issubdtype(offsets.dtype, np.integer) or offsets.size < 1 \
                or offsets[0] != 0 or offsets[-1] != len(points) or (np.diff(offsets) < 0).any():
            raise damaged(f"yarns_{f:06d}.npz: points_m {points.shape} {points.dtype} and offsets {offsets.shape} "
                          f"{offsets.dtype} are not yarn pieces")
        if image.ndim != 3 or image.shape[2] not in (3, 4):
            raise damaged(f"frame_{f:06d}.png: {image.shape} is not an RGB image")
        frames[f] = {"image": image[..., :3], "points": points, "offsets": offsets,
                     "torn_springs": int(entry["torn_springs"])}
    return meta, frames


def _is_int(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


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
