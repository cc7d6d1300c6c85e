"""Parsing and checking `fraytool render` flag values; every problem is an InputError (exit 2)
that names the flag, the value given and what is allowed."""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Optional

from fraytool.errors import InputError

MAX_SIDE = 8192
"""Largest image side accepted (as in the scene schema's [render] resolution)."""


@dataclass(frozen=True)
class RenderRequest:
    """What a render is asked for, beyond the scene: the `fraytool render` flags as one typed record. The
    command line (`from_args`), fraytool.api.render and the farm's tasks (from a shot's
    fraytool.farm.shots.RenderOptions) each make one; build_job
    (fraytool.render.job) checks it against the scene, once, and resolves it into a RenderJob. None: the
    scene's own setting. Values are as the flags give them (resolution "WxH" or (w, h), numbers or text)."""

    out: Optional[str] = None
    """Output folder (-o); None: the shot's folder or outputs/<scene>/."""
    frames: Optional[str] = None
    """START:END[:STEP], END exclusive; None: every frame."""
    resolution: object = None
    samples: Optional[int] = None
    supersample: object = None
    png: bool = False
    depth: object = None
    """Bits per channel of the PNGs: 8 or 16 (None: 8)."""
    exr: bool = False
    video: bool = True
    """False: --no-mp4."""
    codec: Optional[str] = None
    alpha: bool = False
    wireframe: Optional[str] = None
    motion_blur: object = None
    motion_samples: object = None
    camera_position: object = None
    """"X,Y,Z" or 3 numbers (--camera-position)."""
    camera_target: object = None
    fov: Optional[float] = None
    fit: bool = False
    verbose: bool = False
    force: bool = False
    sets: tuple = ()
    """--set KEY=VALUE overrides of the scene file."""

    @classmethod
    def from_args(cls, args) -> "RenderRequest":
        """The options of a parsed `fraytool render` command line (an argparse namespace)."""
        return cls(out=args.out, frames=args.frames, resolution=args.resolution, samples=args.samples,
                   supersample=args.supersample, png=bool(args.png), depth=args.depth, exr=bool(args.exr),
                   video=not args.no_mp4, codec=args.codec, alpha=bool(args.alpha), wireframe=args.wireframe,
                   motion_blur=args.motion_blur, motion_samples=args.motion_samples,
                   camera_position=args.camera_position, camera_target=args.camera_target, fov=args.fov,
                   fit=bool(args.fit), verbose=bool(args.verbose), force=bool(args.force),
                   sets=tuple(args.sets or ()))


@dataclass(frozen=True)
class FrameRange:
    start: int
    end: int
    """Exclusive."""
    step: int = 1

    def frames(self) -> range:
        return range(self.start, self.end, self.step)

    def __len__(self) -> int:
        return len(self.frames())

    def label(self) -> str:
        """File-name suffix of a partial render, e.g. "000010-000020" or "000010-000020_step2"."""
        text = f"{self.start:06d}-{self.end:06d}"
        return text + (f"_step{self.step}" if self.step != 1 else "")


def parse_frame_range(text: str, scene_frames: int, shot_folder: bool = False) -> FrameRange:
    """START:END[:STEP], END exclusive; START defaults to 0 and END to the scene's frame count (`shot_folder`:
    the frames are a simulated shot's, whose scene --set cannot change: the hint for more says so)."""
    allowed = (f"expected START:END[:STEP] with 0 <= START < END <= {scene_frames} (the scene's "
               f"[time] frames; END is exclusive) and STEP >= 1, e.g. 0:{scene_frames} or 10:20:2")
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise InputError(f"--frames {text!r}: {allowed}")
    try:
        start = int(parts[0]) if parts[0].strip() else 0
        end = int(parts[1]) if parts[1].strip() else scene_frames
        step = int(parts[2]) if len(parts) == 3 and parts[2].strip() else 1
    except ValueError:
        raise InputError(f"--frames {text!r}: {allowed}") from None
    if not (0 <= start < end <= scene_frames) or step < 1:
        more = (f"simulate its scene file again with --set time.frames={end}" if shot_folder
                else f"add --set time.frames={end}")
        longer = (f"; the {'shot' if shot_folder else 'scene'} has {scene_frames} frames: for more, {more}"
                  if end > scene_frames and 0 <= start < end and step >= 1 else "")
        raise InputError(f"--frames {text!r}: {allowed}{longer}")
    return FrameRange(start, end, step)


def parse_resolution(text: str, need_even: bool, no_mp4_hint: bool = True) -> tuple[int, int]:
    """WxH with both sides in [2, MAX_SIDE]; even sides when an MP4 is written (`no_mp4_hint`: the
    command has --no-mp4 to offer)."""
    m = re.fullmatch(r"\s*(\d{1,9})\s*[xX]\s*(\d{1,9})\s*", text)
    allowed = f"expected WIDTHxHEIGHT with whole numbers from 2 to {MAX_SIDE}, e.g. 1280x720"
    if not m:
        raise InputError(f"--resolution {text!r}: {allowed}")
    w, h = int(m.group(1)), int(m.group(2))
    if not (2 <= w <= MAX_SIDE and 2 <= h <= MAX_SIDE):
        raise InputError(f"--resolution {text!r}: {allowed}")
    if need_even and (w % 2 or h % 2):
        raise InputError(f"--resolution {text!r}: the MP4 (H.264, yuv420p) needs an even width and height; "
                         f"use e.g. {w + w % 2}x{h + h % 2}" + (", or --no-mp4 for PNGs only, or --codec prores" if no_mp4_hint else ""))
    return w, h


def parse_vec3(flag: str, text: str) -> tuple[float, float, float]:
    """X,Y,Z of finite numbers [m]."""
    parts = text.split(",")
    try:
        v = tuple(float(p) for p in parts)
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise InputError(f"{flag} {text!r}: expected three comma-separated numbers X,Y,Z in metres, e.g. 0,0.3,0.6")
    return v  # type: ignore[return-value]


def checked_key(where: str, key: str, check, value):
    """`check(value)`, a flag's check above, for the same value given as a key of a file (a batch job's
    [render] table): one check of each range; its InputError names `where` and `key = value` instead of the
    flag."""
    try:
        return check(value)
    except InputError as exc:
        text = str(exc)
        why = text.split(": ", 1)[1] if ": " in text else text
        raise InputError(f"{where} {key} = {value!r}: {why}") from None


def check_samples(samples: Optional[int]) -> Optional[int]:
    if samples is not None and not (0 <= samples <= 64):
        raise InputError(f"--samples {samples}: expected 0 to 64 (MSAA samples; 0 or 1 turn it off; "
                         "more than the GL context supports are clamped)")
    return samples


def check_supersample(k) -> Optional[int]:
    """--supersample K: an integer from 1 to 4 (given as text by argparse, or None when not given)."""
    if k is None:
        return None
    try:
        value = int(str(k).strip())
    except ValueError:
        value = None
    if value is None or not (1 <= value <= 4):
        raise InputError(f"--supersample {k}: expected an integer from 1 to 4 (drawn pixels per output pixel along "
                         "each axis; 1 draws at the output size)")
    return value


def check_fov(fov: Optional[float]) -> Optional[float]:
    if fov is not None and (isinstance(fov, bool) or not isinstance(fov, (int, float))):
        raise InputError(f"--fov {fov!r}: expected a number of degrees from 1 to 170")
    if fov is not None and not (math.isfinite(fov) and 1.0 <= fov <= 170.0):
        raise InputError(f"--fov {fov:g}: expected a vertical field of view from 1 to 170 degrees")
    return fov
