"""RenderJob: one render request resolved from a scene and the `fraytool render` flags.

It fixes everything that decides the pixels (scene with camera and render overrides applied, image
size, samples, wireframe mode) and where files go:

    <out>/<scene><PASS>.mp4                      whole scene (no --frames)
    <out>/<scene><PASS>_START-END[_stepS].mp4    a --frames range (END exclusive), e.g. for farm shards
    <out>/png<PASS>/frame_000000.png ...         --png: numbered by scene frame, so shards share one sequence

PASS (PASS_SUFFIX) is "" for the yarns (beauty), "_wireframe" for --wireframe only and "_beside" for
--wireframe beside, so no pass or range ever overwrites another's files.

`digest()` names the pixels: it hashes the simulation (scene_hash), camera, render settings, size,
samples, wireframe mode, the shader sources and RENDER_REVISION. A PNG carries the digest of the job
that drew it; a resumed render keeps only PNGs with its own digest.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

from fraytool.errors import InputError
from fraytool.render.options import (
    FrameRange,
    check_fov,
    check_samples,
    parse_frame_range,
    parse_resolution,
    parse_vec3,
)
from fraytool.resources import shader_dir
from fraytool.scene import scene_hash
from fraytool.scene.spec import SceneSpec

PASS_SUFFIX = {"off": "", "only": "_wireframe", "beside": "_beside"}
"""File-name suffix of each render pass (the --wireframe mode)."""

RENDER_REVISION = 1
"""Bump when a change in the Python side of the renderer changes pixels (shader edits count by themselves)."""


@dataclass(frozen=True)
class RenderJob:
    spec: SceneSpec
    """The scene with camera / resolution / samples overrides applied."""
    out_dir: Path
    frames: FrameRange
    ranged: bool
    """True when a --frames range was given (the MP4 name then carries the range)."""
    wireframe: str = "off"
    png: bool = False
    mp4: bool = True
    alpha: bool = False
    """Transparent background: RGBA PNGs (straight alpha); the MP4 is composited over the background."""

    @property
    def size(self) -> tuple[int, int]:
        """Output image size: the requested size, or twice its width with --wireframe beside (each
        panel keeps the requested size and aspect)."""
        w, h = self.spec.render.resolution
        return (2 * int(w) if self.wireframe == "beside" else int(w)), int(h)

    @property
    def samples(self) -> int:
        return int(self.spec.render.samples)

    @property
    def pass_suffix(self) -> str:
        return PASS_SUFFIX[self.wireframe]

    @property
    def mp4_path(self) -> Path:
        name = self.spec.name + self.pass_suffix
        if self.ranged:
            name += f"_{self.frames.label()}"
        return self.out_dir / f"{name}.mp4"

    @property
    def png_dir(self) -> Path:
        return self.out_dir / f"png{self.pass_suffix}"

    def png_path(self, frame: int) -> Path:
        return self.png_dir / f"frame_{frame:06d}.png"

    def digest(self, effective_samples: int | None = None) -> str:
        """Digest of the pixels; `effective_samples` is the MSAA count after clamping to the context."""
        shaders = hashlib.sha256()
        for p in sorted(shader_dir().glob("*.*")):
            if p.suffix in (".vert", ".frag", ".geom"):
                shaders.update(p.name.encode() + b"\0" + p.read_bytes())
        blob = json.dumps({
            "scene_hash": scene_hash(self.spec),
            "camera": dataclasses.asdict(self.spec.camera),
            "render": dataclasses.asdict(self.spec.render),
            "wireframe": self.wireframe,
            "alpha": self.alpha,
            "effective_samples": effective_samples,
            "revision": RENDER_REVISION,
            "shaders": shaders.hexdigest(),
        }, sort_keys=True, default=list).encode()
        return hashlib.sha256(blob).hexdigest()[:16]


def with_overrides(spec: SceneSpec, *, resolution=None, samples=None, camera_position=None, camera_target=None,
                   fov=None) -> SceneSpec:
    """The scene with command-line overrides applied (None keeps the scene's value)."""
    cam = spec.camera
    cam = dataclasses.replace(
        cam,
        position_m=tuple(camera_position) if camera_position is not None else cam.position_m,
        target_m=tuple(camera_target) if camera_target is not None else cam.target_m,
        fov_deg=float(fov) if fov is not None else cam.fov_deg,
    )
    render = spec.render
    render = dataclasses.replace(
        render,
        resolution=tuple(resolution) if resolution is not None else render.resolution,
        samples=int(samples) if samples is not None else render.samples,
    )
    return dataclasses.replace(spec, camera=cam, render=render)


def build_job(spec: SceneSpec, args, out: Path) -> RenderJob:
    """Validate the `fraytool render` flags (an argparse namespace: png, no_mp4, resolution, samples,
    camera_position, camera_target, fov, frames, wireframe) against the scene and resolve them into a
    RenderJob writing to `out`."""
    png = bool(getattr(args, "png", False)) or spec.output.png
    mp4 = spec.output.mp4 and not getattr(args, "no_mp4", False)
    if not png and not mp4:
        raise InputError("--no-mp4 without --png (and the scene's [output] png = false): nothing to write")
    resolution = parse_resolution(args.resolution, need_even=mp4) if args.resolution else None
    if resolution is None and mp4:
        w, h = spec.render.resolution
        if w % 2 or h % 2:
            raise InputError(f"{spec.source}: [render] resolution = [{w}, {h}]: the MP4 (H.264, yuv420p) needs "
                             "an even width and height; fix the scene or pass --resolution WxH")
    position = parse_vec3("--camera-position", args.camera_position) if args.camera_position else None
    target = parse_vec3("--camera-target", args.camera_target) if args.camera_target else None
    spec = with_overrides(spec, resolution=resolution, samples=check_samples(args.samples),
                          camera_position=position, camera_target=target, fov=check_fov(args.fov))
    if args.frames:
        frames, ranged = parse_frame_range(args.frames, spec.time.frames), True
    else:
        frames, ranged = FrameRange(0, spec.time.frames, 1), False
    from fraytool.render.camera import Camera

    try:
        Camera(spec.camera)  # position == target or up parallel to the view: fail now, not later
    except InputError as exc:
        where = ", ".join(f for f, v in (("--camera-position", position), ("--camera-target", target)) if v)
        raise InputError(f"{where or spec.source + ': [camera]'}: {exc}") from None
    return RenderJob(spec=spec, out_dir=out, frames=frames, ranged=ranged,
                     wireframe=getattr(args, "wireframe", None) or "off", png=png, mp4=mp4,
                     alpha=bool(getattr(args, "alpha", False)))
