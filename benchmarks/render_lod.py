"""Aliasing error against render cost of the yarn representations (docs/rendering.md, "Far field: cloth
under a few pixels", "Error against cost").

For a scene's frames, each representation is drawn at the scene's resolution (scaled by --scales: 0.5,
1 and 2 halve, keep and double the yarns' footprint in pixels) and compared with a reference of the
same frame drawn with yarns only (the far field off) at REF_FACTOR times the scene's resolution in
each axis (for a scale s, max(2, REF_FACTOR / s) times the frame's), averaged in linear light over
each block (a box filter) and encoded to sRGB.
The error is the RMS difference in 8-bit sRGB levels after a Gaussian blur of BLUR_SIGMA_PX pixels
on both images (fraytool.render.aliasing). Cost: median milliseconds per frame of geometry + draw + read-back (as `fraytool bench
--render`), over --repeat draws.

    python benchmarks/render_lod.py scenes/tablecloth_tear.toml OUT_DIR --frames 53,106
    python benchmarks/render_lod.py scenes/tablecloth_tear.toml OUT_DIR --frames 53 --scales 0.5,1,2 \\
        --modes tube,ribbon,far_field
    python benchmarks/render_lod.py scenes/tablecloth_tear.toml OUT_DIR --frames 53,106 --supersamples 1,2,3
    python benchmarks/render_lod.py scenes/tablecloth_tear.toml OUT_DIR --frames 53 --reference-spread
    python benchmarks/render_lod.py scenes/tablecloth_tear.toml OUT_DIR --frames 53 --reference-spread --ref-factor 8

OUT_DIR holds (or receives) the scene's frame records. With --save DIR the images are written there.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from fraytool.io.frame_store import FrameStore
from fraytool.render.aliasing import BLUR_SIGMA_PX, FACTOR, blurred_rms, box_downsample
from fraytool.render.context import create_context
from fraytool.render.renderer import Renderer
from fraytool.scene import load_scene, scene_hash

REF_FACTOR = FACTOR
MODES = {
    "tube": dict(yarn_shape="tube", far_field=False),
    "ribbon": dict(yarn_shape="ribbon", far_field=False),
    "far_field": dict(far_field=True),       # the scene's own yarn shape, with the far field
}


def draw(spec, topology, record, size, samples, target="srgb8", repeat=1):
    """(image, median ms of geometry + draw + read-back): 8-bit sRGB (H, W, 3), or the float target's
    linear premultiplied RGBA."""
    ctx = create_context()
    try:
        r = Renderer(ctx, size, samples, spec.render, spec.camera, topology, target=target,
                     panels_spec=spec.all_panels)
        b = r.geometry_builder(topology)
        r.draw(b.build(record))  # warm-up (numba, shaders, buffers)
        ctx.finish()
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            r.draw(b.build(record))
            image = r.read() if target == "srgb8" else r.read_linear()
            times.append(time.perf_counter() - t0)
        r.release()
    finally:
        ctx.release()
    return image, 1e3 * statistics.median(times)


FLOAT_TARGET_MAX_PX = 16_000_000
"""Above this many pixels (5120x2880 is 14.7 M) a supersampled reference is drawn into the 8-bit sRGB target
and decoded: llvmpipe refuses a multisampled float framebuffer of 8x the shipped 1280x720 (59 M pixels). The
8-bit steps average out over the factor x factor block (under 0.1 level), but the 8-bit target clips each
sample at 1 where the float one keeps a highlight's excess: a 4x (float) and an 8x (8-bit) reference
differ in that too."""


def draw_linear(spec, topology, record, size, samples) -> np.ndarray:
    """The frame as linear premultiplied RGBA (H, W, 4) float32, through the float target when it fits."""
    from fraytool.render.color import srgb_to_linear

    if size[0] * size[1] <= FLOAT_TARGET_MAX_PX:
        return draw(spec, topology, record, size, samples, target="float")[0]
    image, _ = draw(spec, topology, record, size, samples)
    rgb = srgb_to_linear(image.astype(np.float32) / 255.0).astype(np.float32)
    return np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,), np.float32)], axis=-1)


def reference(spec, topology, record, size, samples, factor: int = REF_FACTOR) -> np.ndarray:
    """The frame at `factor` x the size, yarns only, box-filtered in linear light: (H, W, 3) uint8 sRGB.
    Ribbons there are sampled as tubes are (no straight steps over 4 px, fraytool.render.lod): the
    reference does not take the shortcut it is measuring."""
    from fraytool.render import lod

    W, H = size
    f = int(factor)
    ref_spec = with_render(spec, far_field=False, supersample=1)
    ribbon_straight = lod.RIBBON_STRAIGHT_PX
    lod.RIBBON_STRAIGHT_PX = lod.STRAIGHT_PX
    try:
        linear = draw_linear(ref_spec, topology, record, (W * f, H * f), samples)
    finally:
        lod.RIBBON_STRAIGHT_PX = ribbon_straight
    return box_downsample(linear, f)


CONVERGED = {
    # spline samples every 2 px and no straight segments (ribbons); 16-sided tubes with facets of a
    # quarter pixel and samples every 4 px: the same yarns without the level of detail's shortcuts
    "ribbon": (dict(SAMPLE_PX=2.0, STRAIGHT_PX=0.0, RIBBON_STRAIGHT_PX=0.0), dict(spline_samples=8)),
    "tube": (dict(FACET_PX=0.25, SAMPLE_PX=4.0, STRAIGHT_PX=0.0, RIBBON_STRAIGHT_PX=0.0),
             dict(yarn_shape="tube", tube_sides=16, spline_samples=8)),
}


def converged_reference(spec, topology, record, size, samples, shape: str, factor: int = REF_FACTOR) -> np.ndarray:
    """As `reference`, but with the yarns drawn converged (CONVERGED[shape]): how far the reference's
    own level of detail moves it (docs/rendering.md, "The reference is not converged either")."""
    from fraytool.render import lod

    W, H = size
    f = int(factor)
    limits, render = CONVERGED[shape]
    saved = {name: getattr(lod, name) for name in limits}
    for name, value in limits.items():
        setattr(lod, name, value)
    try:
        linear = draw_linear(with_render(spec, far_field=False, supersample=1, **render), topology, record, (W * f, H * f), samples)
    finally:
        for name, value in saved.items():
            setattr(lod, name, value)
    return box_downsample(linear, f)


def reference_spread(spec, topology, record, size, samples, factor: int = REF_FACTOR) -> dict:
    """Blurred RMS [levels] between the reference and the two converged drawings (all at `factor` x), and of
    the shipped frame (the far field on) against each."""
    images = {"reference": reference(spec, topology, record, size, samples, factor),
              **{f"converged {shape}s": converged_reference(spec, topology, record, size, samples, shape, factor)
                 for shape in CONVERGED}}
    shipped, _ = draw(with_render(spec, **MODES["far_field"]), topology, record, size, samples)
    names = list(images)
    out = {f"{a} / {b}": blurred_rms(images[a], images[b]) for k, a in enumerate(names) for b in names[k + 1:]}
    out.update({f"shipped / {a}": blurred_rms(shipped, images[a]) for a in names})
    return out


def render_sets(spec, items) -> dict:
    """KEY=VALUE items as [render] changes, each value of its key's type."""
    out = {}
    for item in items:
        key, value = item.split("=", 1)
        kind = type(getattr(spec.render, key))
        out[key] = (value.lower() in ("1", "true", "on")) if kind is bool else kind(value)
    return out


def with_render(spec, **changes):
    return dataclasses.replace(spec, render=dataclasses.replace(spec.render, **changes))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("out_dir")
    ap.add_argument("--frames", default="53,106")
    ap.add_argument("--scales", default="1")
    ap.add_argument("--modes", default="ribbon,far_field")
    ap.add_argument("--supersamples", default="1",
                    help="[render] supersample values to draw each mode at, e.g. 1,2 (the reference is unchanged)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--save", default=None)
    ap.add_argument("--ref-factor", type=int, default=None,
                    help="supersampling of the reference per axis (default: REF_FACTOR times the scene's size)")
    ap.add_argument("--far-field-px", type=float, default=None,
                    help="middle of the blend band [px] (default: the scene's [render] far_field_px)")
    ap.add_argument("--render-set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a [render] key for every image, e.g. shadows=false (repeatable)")
    ap.add_argument("--image-set", action="append", default=[], metavar="KEY=VALUE",
                    help="override a [render] key for the compared images only, not the reference, e.g. samples=0")
    ap.add_argument("--reference-spread", action="store_true",
                    help="instead of the table: the reference against the same yarns drawn converged "
                         "(CONVERGED), and the shipped frame against each, at the scene's size (with "
                         "--ref-factor, all drawn at that factor)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    spec = load_scene(args.scene)
    spec = with_render(spec, **render_sets(spec, args.render_set))
    image_sets = render_sets(spec, args.image_set)
    if args.far_field_px is not None:
        spec = with_render(spec, far_field_px=args.far_field_px)
    store = FrameStore(Path(args.out_dir))
    frames = [int(f) for f in args.frames.split(",")]
    if not (store.matches(scene_hash(spec)) and store.frames_complete() > max(frames)):
        from fraytool.sim.run import simulate_to_disk
        simulate_to_disk(spec, Path(args.out_dir), frames=max(frames) + 1, progress=sys.stderr.isatty())
    topology = store.load_topology()
    if args.reference_spread:
        rows = []
        for frame in frames:
            spread = reference_spread(spec, topology, store.load_frame(frame), tuple(spec.render.resolution),
                                      spec.render.samples, args.ref_factor or REF_FACTOR)
            rows.append(dict(frame=frame, **{k: round(v, 2) for k, v in spread.items()}))
            if not args.json:
                for k, v in spread.items():
                    print(f"{spec.name} frame {frame}: {k:40s} {v:5.2f} sRGB levels RMS (blur {BLUR_SIGMA_PX:g} px)",
                          flush=True)
        if args.json:
            print(json.dumps(rows))
        return
    save = Path(args.save) if args.save else None
    if save:
        save.mkdir(parents=True, exist_ok=True)
    rows = []
    for scale in (float(s) for s in args.scales.split(",")):
        W, H = (int(round(v * scale)) for v in spec.render.resolution)
        for frame in frames:
            record = store.load_frame(frame)
            # the reference is always the 1x frame's REF_FACTOR x (5120x2880 for a 1280x720 scene):
            # 8x for the half-size frame, 2x for the double-size one
            factor = args.ref_factor or max(2, int(round(REF_FACTOR / scale)))
            ref = reference(spec, topology, record, (W, H), spec.render.samples, factor)
            if save:
                from PIL import Image
                Image.fromarray(ref).save(save / f"ref_{frame}_{scale:g}.png")
            for mode, k in ((m, int(k)) for m in args.modes.split(",") for k in args.supersamples.split(",")):
                image_spec = with_render(spec, **{**MODES[mode], "supersample": k, **image_sets})
                image, ms = draw(image_spec, topology, record, (W, H), image_spec.render.samples, repeat=args.repeat)
                err = blurred_rms(image, ref)
                rows.append(dict(scale=scale, size=[W, H], frame=frame, mode=mode, **{"supersample": k, **image_sets},
                                 rms_levels=round(err, 2), ms=round(ms, 1)))
                if save:
                    from PIL import Image
                    Image.fromarray(image).save(save / f"{mode}{'' if k == 1 else f'_ss{k}'}_{frame}_{scale:g}.png")
                if not args.json:
                    print(f"{spec.name} frame {frame} {W}x{H} (x{scale:g}) {mode:9s}{f' supersample {k}' if k > 1 else ''}"
                          f"{''.join(f' {key}={v}' for key, v in image_sets.items())}: "
                          f"error {err:5.2f} sRGB levels RMS (blur {BLUR_SIGMA_PX:g} px), {ms:7.1f} ms/frame",
                          flush=True)
    if args.json:
        print(json.dumps(rows))


if __name__ == "__main__":
    main()
