"""RenderJob: one render request resolved from a scene and the `fraytool render` flags.

It fixes everything that decides the pixels (scene with camera and render overrides applied, image
size, samples, wireframe mode, alpha, the colour target) and where files go:

    <out>/<scene><PASS>.mp4                      whole scene (no --frames); .mov with --codec prores
    <out>/<scene><PASS>_START-END[_stepS].mp4    a --frames range (END exclusive), e.g. for farm shards
    <out>/png<PASS>/frame_000000.png ...         --png: numbered by scene frame, so shards share one sequence
    <out>/exr<PASS>/frame_000000.exr ...         --exr: the same numbering

PASS (PASS_SUFFIX) is "" for the yarns (beauty), "_wireframe" for --wireframe only and "_beside" for
--wireframe beside, so no pass or range ever overwrites another's files.

`digest()` names the pixels: it hashes the simulation (scene_hash), camera, render settings, size,
samples, wireframe mode, alpha, the colour target and PNG bit depth, the motion blur (when on), the shader sources, the renderer's
own code (every module of fraytool.render and the grid, kinds and color helpers it draws with:
`renderer_code_digest`), the GL renderer and version strings of the context that draws (another Mesa
draws other pixels) and RENDER_REVISION. A PNG or EXR carries the digest of the job that drew it; a
resumed render keeps only files with its own digest.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from fraytool.errors import InputError
from fraytool.render.encode import VIDEO_SUFFIX
from fraytool.render.motion_blur import MotionBlur, motion_blur_from
from fraytool.render.options import (
    FrameRange,
    RenderRequest,
    check_fov,
    check_samples,
    check_supersample,
    parse_frame_range,
    parse_resolution,
    parse_vec3,
)
from fraytool.resources import shader_dir
from fraytool.scene import scene_hash
from fraytool.scene.spec import SceneSpec

PASS_SUFFIX = {"off": "", "only": "_wireframe", "beside": "_beside"}
"""File-name suffix of each render pass (the --wireframe mode)."""

RENDER_REVISION = 3
"""A hand-kept revision of the renderer; its code and shaders are hashed by themselves (renderer_code_digest)."""

RENDERER_MODULES = ("render", "grid.py", "kinds.py", "meshes.py", "geometry")
"""What the renderer's pixels are computed by, under the fraytool package: the render package and the
leaf modules it draws with (geometry: the quaternions motion blur turns bodies by)."""


def renderer_code_digest(package_dir: Path | None = None) -> str:
    """SHA-256 over the renderer's Python sources (RENDERER_MODULES, by relative path and bytes): a changed
    renderer never keeps frames an older one drew. `package_dir`: the fraytool package (default: this one)."""
    root = Path(package_dir) if package_dir else Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for name in RENDERER_MODULES:
        p = root / name
        files = sorted(p.rglob("*.py")) if p.is_dir() else [p]
        for f in files:
            h.update(str(f.relative_to(root)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


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
    video: bool = True
    """Write the video (the MP4, or the .mov of --codec prores)."""
    alpha: bool = False
    """Transparent background: RGBA PNGs (straight alpha), EXR alpha; the H.264 MP4 is composited
    over the background, ProRes keeps the alpha."""
    png_bits: int = 8
    """Bits per channel of the PNGs: 8, or 16 (--depth 16)."""
    exr: bool = False
    """Also write an EXR sequence (linear premultiplied RGBA + Z)."""
    codec: str = "h264"
    """Video codec: "h264" (MP4) or "prores" (ProRes 4444 with alpha, .mov)."""
    motion_blur: Optional[MotionBlur] = None
    """--motion-blur / --motion-samples; None: off (fraytool.render.motion_blur)."""

    @property
    def target(self) -> str:
        """The renderer's colour target: "float" when an output needs more than 8 bits (16-bit PNGs,
        EXR, 10-bit ProRes) or sub-frames are averaged (motion blur, in linear light), else "srgb8"
        (fraytool.render.renderer)."""
        wide = self.png_bits == 16 or self.exr or self.codec == "prores"
        return "float" if wide or self.motion_blur is not None else "srgb8"

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
    def video_path(self) -> Path:
        name = self.spec.name + self.pass_suffix
        if self.ranged:
            name += f"_{self.frames.label()}"
        return self.out_dir / f"{name}{VIDEO_SUFFIX[self.codec]}"

    @property
    def png_dir(self) -> Path:
        return self.out_dir / f"png{self.pass_suffix}"

    def png_path(self, frame: int) -> Path:
        return self.png_dir / f"frame_{frame:06d}.png"

    @property
    def exr_dir(self) -> Path:
        return self.out_dir / f"exr{self.pass_suffix}"

    def exr_path(self, frame: int) -> Path:
        return self.exr_dir / f"frame_{frame:06d}.exr"

    def digest(self, effective_samples: int | None = None, gl: str = "") -> str:
        """Digest of the pixels; `effective_samples` is the MSAA count after clamping to the context, `gl` the
        context's GL_RENDERER and GL_VERSION (fraytool.render.context.gl_strings)."""
        shaders = hashlib.sha256()
        for p in sorted(shader_dir().glob("*.*")):
            if p.suffix in (".vert", ".frag", ".geom", ".glsl"):
                shaders.update(p.name.encode() + b"\0" + p.read_bytes())
        settings = {
            "scene_hash": scene_hash(self.spec),
            "camera": dataclasses.asdict(self.spec.camera),
            "render": dataclasses.asdict(self.spec.render),
            "wireframe": self.wireframe,
            "alpha": self.alpha,
            "effective_samples": effective_samples,
            "revision": RENDER_REVISION,
            "shaders": shaders.hexdigest(),
            "renderer_code": renderer_code_digest(),
            "gl": gl,
        }
        colors = [(p.warp_color, p.weft_color) for p in self.spec.all_panels]
        if len(colors) > 1 or colors[0] != (None, None):  # panels' own colours (none: the digest as before)
            settings["panel_colors"] = colors
        if self.target != "srgb8":  # only when not the default, so the default digest stays as it was
            settings.update(target=self.target, png_bits=self.png_bits)
        if self.motion_blur is not None:  # likewise only when on: without blur the digest is as before
            settings["motion_blur"] = self.motion_blur.settings()
        blob = json.dumps(settings, sort_keys=True, default=list).encode()
        return hashlib.sha256(blob).hexdigest()[:16]


def with_overrides(spec: SceneSpec, *, resolution=None, samples=None, camera_position=None, camera_target=None,
                   fov=None, fit=False, supersample=None) -> SceneSpec:
    """The scene with command-line overrides applied (None keeps the scene's value). An override of a keyed
    value (a moving camera's position, target or fov) replaces its keys: the value is then static."""
    cam = spec.camera
    cam = dataclasses.replace(
        cam,
        position_m=tuple(camera_position) if camera_position is not None else cam.position_m,
        target_m=tuple(camera_target) if camera_target is not None else cam.target_m,
        fov_deg=float(fov) if fov is not None else cam.fov_deg,
        position_keys_m=() if camera_position is not None else cam.position_keys_m,
        target_keys_m=() if camera_target is not None else cam.target_keys_m,
        fov_keys_deg=() if fov is not None else cam.fov_keys_deg,
        fit=cam.fit or bool(fit),
    )
    render = spec.render
    render = dataclasses.replace(
        render,
        resolution=tuple(resolution) if resolution is not None else render.resolution,
        samples=int(samples) if samples is not None else render.samples,
        supersample=int(supersample) if supersample is not None else render.supersample,
    )
    return dataclasses.replace(spec, camera=cam, render=render)


def _text(vector) -> str:
    """A camera vector as --camera-position gives it ("X,Y,Z"), from text or 3 numbers."""
    return vector if isinstance(vector, str) else ",".join(repr(float(v)) for v in vector)


def parse_depth(value) -> int:
    """--depth: 8 or 16 (bits per channel of the PNGs)."""
    if str(value).strip() in ("8", "16"):
        return int(value)
    raise InputError(f"--depth {value!r}: expected 8 or 16 (bits per channel of the PNGs)")


def build_job(spec: SceneSpec, args: RenderRequest, out: Path, shot_folder: bool = False) -> RenderJob:
    """Check the render options (fraytool.render.options.RenderRequest) against the scene, the one place
    they are checked, and resolve them into a RenderJob writing to `out` (`shot_folder`: the scene is a
    simulated shot's, fixed; an error's hint then says so)."""
    if args.wireframe not in (None, *PASS_SUFFIX):
        raise InputError(f"--wireframe {args.wireframe!r}: expected one of {', '.join(PASS_SUFFIX)}")
    png = args.png or spec.output.png
    video = spec.output.mp4 and args.video
    exr = args.exr
    codec = args.codec or "h264"
    if codec not in VIDEO_SUFFIX:
        raise InputError(f"--codec {codec!r}: expected one of {', '.join(VIDEO_SUFFIX)}")
    png_bits = parse_depth(args.depth or 8)
    blur = motion_blur_from(args.motion_blur, args.motion_samples)
    if codec == "prores" and not video:
        raise InputError("--codec prores chooses the video codec, but no video is written (--no-mp4, or the "
                         "scene's [output] mp4 = false): drop one of them")
    if not png and not video and not exr:
        raise InputError("--no-mp4 without --png or --exr (and the scene's [output] png = false): nothing to write")
    if png_bits == 16 and not png:
        raise InputError("--depth 16 sets the bit depth of the PNG sequence, and no PNGs are written: add --png"
                         + ("" if exr else " (or use --exr for float frames)"))
    h264 = video and codec == "h264"
    size = args.resolution
    if isinstance(size, (tuple, list)):
        size = "x".join(str(v) for v in size)
    resolution = parse_resolution(size, need_even=h264) if size else None
    if resolution is None and h264:
        w, h = spec.render.resolution
        if w % 2 or h % 2:
            raise InputError(f"{spec.source}: [render] resolution = [{w}, {h}]: the MP4 (H.264, yuv420p) needs "
                             "an even width and height; fix the scene, pass --resolution WxH, or write PNGs or "
                             "EXRs only (--no-mp4) or ProRes (--codec prores)")
    position = parse_vec3("--camera-position", _text(args.camera_position)) if args.camera_position else None
    target = parse_vec3("--camera-target", _text(args.camera_target)) if args.camera_target else None
    spec = with_overrides(spec, resolution=resolution, samples=check_samples(args.samples),
                          supersample=check_supersample(args.supersample),
                          camera_position=position, camera_target=target, fov=check_fov(args.fov),
                          fit=args.fit)
    if args.frames:
        frames, ranged = parse_frame_range(args.frames, spec.time.frames, shot_folder), True
    else:
        frames, ranged = FrameRange(0, spec.time.frames, 1), False
    from fraytool.render.camera import check_camera

    try:
        check_camera(spec.camera)  # position == target or up parallel to the view: fail now, not later
    except InputError as exc:
        where = ", ".join(f for f, v in (("--camera-position", position), ("--camera-target", target)) if v)
        raise InputError(f"{where or spec.source + ': [camera]'}: {exc}") from None
    # ProRes 4444 carries alpha, which is what it is for: --codec prores renders a transparent background
    alpha = args.alpha or codec == "prores"
    return RenderJob(spec=spec, out_dir=out, frames=frames, ranged=ranged,
                     wireframe=args.wireframe or "off", png=png, video=video, alpha=alpha,
                     png_bits=png_bits, exr=exr, codec=codec, motion_blur=blur)
