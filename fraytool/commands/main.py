"""The `fraytool` command: simulate, render, export, check, bench, study, batch.

Exit codes: 0 success, 1 failed run (unstable simulation, no GL context, I/O), 2 bad input
(scene file or flags). Errors print one clear message, never a traceback.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Optional, Sequence

from fraytool import __version__
from fraytool.errors import FraytoolError, InputError, os_error_message
from fraytool.io.failure import finite_json


class _Parser(argparse.ArgumentParser):
    """argparse that exits 2 through our error path (usage errors are bad input)."""

    def error(self, message: str):  # noqa: D102
        """One line: what was wrong, a guess at a misspelled flag, and where the options are listed."""
        hint = ""
        if message.startswith("unrecognized arguments:"):
            import difflib

            options = sorted(self._every_option())
            for word in message.split(":", 1)[1].split():
                close = difflib.get_close_matches(word.split("=")[0], options, n=1, cutoff=0.6)
                if word.startswith("-") and close:
                    hint += f"; did you mean {close[0]}?"
        print(f"{self.prog}: error: {_cut(message)}{hint} (`{self.prog} --help` lists what is allowed)",
              file=sys.stderr)
        raise SystemExit(2)

    def _every_option(self) -> set[str]:
        """Option strings of this parser and of its subcommands' parsers."""
        found: set[str] = set()
        for action in self._actions:
            found.update(o for o in action.option_strings if o.startswith("--"))
            for sub in getattr(action, "choices", None) or ():
                parser = action.choices[sub] if isinstance(action.choices, dict) else None
                if isinstance(parser, _Parser):
                    found |= parser._every_option()
        return found


MAX_LINE_CHARS = 1000


def _cut(line: str) -> str:
    """A message line of at most MAX_LINE_CHARS characters (a flag's value is quoted whole otherwise)."""
    return line if len(line) <= MAX_LINE_CHARS else f"{line[:MAX_LINE_CHARS]}... ({len(line)} characters)"


MAX_FRAMES = 1_000_000
"""Largest --frames, the same as the largest [time] frames of a scene file."""


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    if v > MAX_FRAMES:
        raise argparse.ArgumentTypeError(f"expected at most {MAX_FRAMES} (as [time] frames), got {text!r}")
    return v


MAX_WAIT_S = 7 * 24 * 3600.0
"""Largest --connect-timeout: a week (a longer wait is better said as no timeout)."""


def _positive_seconds(text: str) -> float:
    """A positive, finite number of seconds, at most MAX_WAIT_S."""
    import math

    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    if v > MAX_WAIT_S:
        raise argparse.ArgumentTypeError(f"expected at most {MAX_WAIT_S:.0f} seconds (a week; leave the option out "
                                         f"to wait for workers as long as it takes), got {text!r}")
    return v


def _set_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene key, validated like the file: e.g. --set scene.seed=3, "
                        "--set cloth.tearing.break_strain=0.3, --set bodies.0.radius_m=0.02 or bodies.ball.radius_m=0.02 "
                        "(repeatable)")


def _progress_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--progress", choices=("auto", "bar", "log", "none"), default="auto",
                   help="progress on stderr: a bar on a terminal, a line every few seconds (log), or none; "
                        "auto (default): bar on a terminal, log otherwise")


def _threads_flag(p: argparse.ArgumentParser) -> None:
    p.add_argument("--threads", type=int, metavar="N", help="threads for the parallel simulation kernels (default 1, "
                   "or NUMBA_NUM_THREADS if set; at most the machine's cores); the frames are the same on any number")


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="fraytool", description="Woven cloth tearing with frayed edges: simulate and render.")
    p.add_argument("--version", action="version", version=f"fraytool {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    s = sub.add_parser("simulate", help="simulate a scene and write frame records (.npz)")
    s.add_argument("scene", help="scene file (TOML), or the name of a shipped scene")
    s.add_argument("-o", "--out", type=Path, help="output folder (default outputs/<scene name>/)")
    s.add_argument("--frames", type=_positive_int, help="number of frames (default: the scene's)")
    s.add_argument("--resume", action="store_true", help="continue from the last complete frame")
    s.add_argument("--json", action="store_true", help="print a JSON summary on stdout at the end")
    s.add_argument("--force", action="store_true", help="run even if the memory estimate exceeds what is available")
    _progress_flag(s)
    _set_flag(s)
    _threads_flag(s)

    c = sub.add_parser("check", help="validate a scene and print derived figures; or check an output folder")
    c.add_argument("scene", nargs="?", help="scene file or shipped scene name (optional with --outputs)")
    c.add_argument("--outputs", type=Path, metavar="DIR", help="check the frames (checksums, scene) and PNGs in an "
                   "output folder instead; exit 1 if any file is damaged")
    c.add_argument("--run", action="store_true", help="also run the scene's own [checks]")
    c.add_argument("--json", action="store_true", help="print the report as JSON on stdout")
    c.add_argument("--force", action="store_true", help="build the model even if the memory estimate exceeds "
                   "what is available")
    _set_flag(c)

    pv = sub.add_parser("preview", help="draw a scene's rest pose (panels, grain, seams, attachments, bodies) from "
                        "its camera, the front and the side, before a run")
    pv.add_argument("scene", help="scene file or shipped scene name")
    pv.add_argument("-o", "--out", type=Path, metavar="OUT.png", help="the picture to write")
    pv.add_argument("--json", action="store_true", help="print each panel's world bounds as JSON on stdout")
    _set_flag(pv)

    b = sub.add_parser("bench", help="time the simulation (and rendering) per stage")
    b.add_argument("scene", help="scene file (TOML), or the name of a shipped scene (e.g. fig7_square_grab)")
    b.add_argument("--frames", type=_positive_int, default=None, help="frames to time (default 20)")
    b.add_argument("--render", action="store_true", help="also time the render stages")
    b.add_argument("--self-collision", choices=("on", "off"), help="override the scene's [self_collision] enabled")
    b.add_argument("--json", action="store_true", help="print the figures as JSON on stdout")
    _set_flag(b)
    _threads_flag(b)

    r = sub.add_parser("render", help="simulate (or reuse frames) and render PNG / EXR / MP4 / ProRes")
    r.add_argument("scene", help="scene file (TOML), the name of a shipped scene (e.g. fig7_square_grab), or "
                   "the output folder of a simulated shot (its scene and Model are saved there)")
    r.add_argument("-o", "--out", type=Path, help="output folder (default outputs/<scene name>/)")
    r.add_argument("--frames", metavar="START:END[:STEP]", help="frame range to render (END exclusive)")
    r.add_argument("--resolution", metavar="WxH", help="image size, e.g. 1280x720 (even numbers for H.264)")
    r.add_argument("--samples", type=int, metavar="N", help="MSAA samples, 0-64 (default: the scene's [render] "
                   "samples); more than the GL context draws are clamped, with a warning")
    r.add_argument("--supersample", metavar="K", help="draw K x K pixels per output pixel and average "
                   "them in linear light, 1-4 (default: the scene's [render] supersample, 1): finer, about K^2 "
                   "times the draw")
    r.add_argument("--png", action="store_true", help="also write a numbered PNG sequence in <out>/png/")
    r.add_argument("--depth", metavar="BITS", default="8",
                   help="bits per channel of the PNGs: 8 (default) or 16 (drawn in float; RGB, or RGBA with --alpha)")
    r.add_argument("--exr", action="store_true", help="also write an OpenEXR sequence in <out>/exr/: half-float "
                   "R, G, B, A in linear light, premultiplied by alpha, and Z, the distance from the camera along "
                   "its view axis in metres (+inf where nothing is drawn)")
    r.add_argument("--no-mp4", action="store_true", help="do not write the video (the MP4, or the .mov of --codec prores)")
    r.add_argument("--codec", choices=("h264", "prores"), default="h264",
                   help="video codec: h264 (default; <scene>.mp4, no alpha) or prores (ProRes 4444 with alpha, "
                        "10-bit, <scene>.mov, for compositing; implies --alpha)")
    r.add_argument("--alpha", action="store_true", help="transparent background: RGBA PNGs with straight alpha "
                   "in sRGB (the fading yarn ends as partial alpha), EXR alpha; the H.264 MP4 is composited over "
                   "the background, ProRes keeps the alpha")
    r.add_argument("--wireframe", choices=("off", "only", "beside"), nargs="?", const="beside", default="off",
                   help="springs as lines, base model purple, yarn level blue (Fig. 8); default 'beside'")
    r.add_argument("--motion-blur", metavar="SHUTTER",
                   help="motion blur: the fraction of a frame the shutter is open, from 0 (off, the default) to 1, "
                        "e.g. 0.5; yarns and bodies are drawn at --motion-samples times from the frame to the "
                        "shutter's close, interpolated between frame records, and averaged in linear light")
    r.add_argument("--motion-samples", metavar="N",
                   help="sub-frames drawn per frame with --motion-blur, 2 to 64 (default 8); each costs a draw")
    r.add_argument("--camera-position", metavar="X,Y,Z", help="override [camera] position_m")
    r.add_argument("--camera-target", metavar="X,Y,Z", help="override [camera] target_m")
    r.add_argument("--fov", type=float, help="override [camera] fov_deg")
    r.add_argument("--fit", action="store_true",
                   help="frame the cloth (as [camera] fit = true): keep the view direction and fov, aim at the centre "
                        "of every yarn point and body over the whole shot and move the camera along its view axis "
                        "until they all fit, with [camera] fit_margin free; simulates the whole shot first")
    r.add_argument("-v", "--verbose", action="store_true", help="print the GL renderer and version")
    r.add_argument("--force", action="store_true", help="run even if the memory estimate exceeds what is available")
    _progress_flag(r)
    _set_flag(r)
    _threads_flag(r)

    e = sub.add_parser("export", help="simulate (or reuse frames) and write the yarns and bodies as USD")
    e.add_argument("scene", help="scene file (TOML), the name of a shipped scene (e.g. fig7_square_grab), or "
                   "the output folder of a simulated shot (its scene and Model are saved there)")
    e.add_argument("--usd", required=True, type=Path, metavar="OUT.usd",
                   help="USD file to write (.usd or .usdc binary, .usda text): yarns as BasisCurves (cubic "
                        "Catmull-Rom through the yarn centre lines, widths, weft/warp displayColor, the fade of "
                        "broken ends as displayOpacity), bodies as Sphere / Cube / Plane, a time sample per "
                        "frame; needs the usd extra: pip install \"fraytool[usd]\"")
    e.add_argument("-o", "--out", type=Path, help="folder of the frame records (default outputs/<scene name>/)")
    e.add_argument("--frames", metavar="START:END[:STEP]", help="frame range to export (END exclusive)")
    e.add_argument("--force", action="store_true", help="run even if the memory estimate exceeds what is available")
    _progress_flag(e)
    _set_flag(e)
    _threads_flag(e)

    g = sub.add_parser("golden", help="golden-image regression tests of your own scenes: update or check")
    g.add_argument("action", choices=("update", "check"),
                   help="update: render the frames and store them as the golden; check: render them again and "
                        "compare (exit 0 pass, 1 a regression, 2 bad input or a missing golden)")
    g.add_argument("scenes", nargs="+", metavar="SCENE", help="scene files or shipped scene names")
    g.add_argument("--dir", required=True, type=Path, help="the golden folder (one sub-folder per scene)")
    g.add_argument("--frames", metavar="LIST", help="frames, e.g. 0,35,71 (default: the scene's [golden] frames, "
                   "else the first, middle and last)")
    g.add_argument("--report", type=Path, metavar="OUT", help="check: write report.html, summary.json and the "
                   "reference / new / difference images into OUT")
    g.add_argument("--junit", type=Path, metavar="FILE", help="check: write JUnit XML for CI systems")
    g.add_argument("--work", type=Path, help="folder for the simulated frames (default outputs/golden/)")
    _progress_flag(g)
    _set_flag(g)
    _threads_flag(g)

    ba = sub.add_parser("batch", help="render many shots (scenes, job files, wedges) on Dask distributed")
    ba.add_argument("inputs", nargs="+", metavar="SCENE_OR_JOB", help="scene files, shipped scene names or job files (TOML)")
    ba.add_argument("-o", "--out", type=Path, help="job folder (default outputs/<job name>/)")
    ba.add_argument("--workers", type=_positive_int, help="local worker processes (default: one per core)")
    ba.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="use a running Dask scheduler instead")
    ba.add_argument("--connect-timeout", type=_positive_seconds, metavar="SECONDS",
                    help="while no worker is connected (none yet, or all lost), give up after SECONDS: exit 1, "
                         "job.json and the outputs so far kept (default: wait as long as it takes, saying so "
                         "every 30 s)")
    ba.add_argument("--wedge", dest="wedges", action="append", default=[], metavar="KEY=V1,V2,...",
                    help="one shot per value (ranges: A..B, A..B:STEP), plus a contact sheet (repeatable)")
    ba.add_argument("--frames", metavar="START:END[:STEP]", help="frame range of every shot")
    ba.add_argument("--resolution", metavar="WxH", help="image size of every shot, e.g. 1280x720 (even numbers)")
    ba.add_argument("--samples", type=int, help="MSAA samples of every shot")
    ba.add_argument("--supersample", metavar="K", help="drawn pixels per output pixel along each axis, "
                    "1-4, for every shot (as in render)")
    ba.add_argument("--wireframe", choices=("off", "only", "beside"), help="wireframe pass of every shot (as in render)")
    ba.add_argument("--alpha", action="store_true", help="transparent background for every shot (as in render)")
    ba.add_argument("--depth", type=int, choices=(8, 16), help="PNG bits per channel of every shot (as in render)")
    ba.add_argument("--exr", action="store_true", help="also an EXR sequence per shot (as in render)")
    ba.add_argument("--codec", choices=("h264", "prores"),
                    help="video codec of every shot (as in render): h264 (default) or prores (ProRes 4444 with "
                         "alpha in <shot>.mov; the PNGs are then 16-bit RGBA, which the join encodes)")
    ba.add_argument("--fit", action="store_true",
                    help="frame every shot's cloth over its whole shot (as in render; the shot is simulated "
                         "before any frame is rendered)")
    ba.add_argument("--motion-blur", metavar="SHUTTER", help="motion blur of every shot (as in render): the "
                    "shutter, a fraction of a frame from 0 (off) to 1")
    ba.add_argument("--motion-samples", metavar="N", help="sub-frames per blurred frame of every shot (as in "
                    "render), 2 to 64 (default 8)")
    ba.add_argument("--chunk-frames", type=_positive_int, help="frames per render task (default 24)")
    ba.add_argument("--no-contact-sheet", action="store_true", help="no contact sheet for wedges")
    ba.add_argument("--golden-check", type=Path, metavar="DIR", help="instead of rendering: check every shot "
                    "against its golden in DIR (fraytool golden check, docs/golden.md) in parallel, one report for "
                    "all in <job folder>/golden-report/; exit 1 on a regression")
    ba.add_argument("--golden-update", type=Path, metavar="DIR", help="instead of rendering: make every shot's "
                    "golden in DIR (fraytool golden update), in parallel")
    ba.add_argument("--junit", type=Path, metavar="FILE", help="with --golden-check: JUnit XML for CI systems")
    _progress_flag(ba)
    _set_flag(ba)

    st = sub.add_parser("study", help="error against run time, or stability sweeps")
    st.add_argument("scene", help="scene file (TOML), or the name of a shipped scene (e.g. fig7_square_grab)")
    st.add_argument("-o", "--out", type=Path, help="output folder (default outputs/<scene name>/)")
    st.add_argument("--stability", action="store_true", help="sweep stiff and extreme cases instead")
    st.add_argument("--quick", action="store_true", help="fewer settings, for a fast look")
    st.add_argument("--duration", type=float, metavar="S", help="simulated seconds to study (default: a tearing "
                    "scene's shot; at most 48 frames for trajectories)")
    st.add_argument("--trajectories", action="store_true", help="tearing scene: also compare trajectories with "
                    "tearing off")
    _threads_flag(st)
    st.add_argument("--seeds", metavar="LIST", help="tearing scene: seeds every step runs at, compared by their means, "
                    "e.g. 1-4 or 1,3,7 (default: 4 seeds from the scene's; one with --quick)")
    st.add_argument("--multires", action="store_true", help="compare [cloth.multires] factors k against k = 1: "
                    "untorn shape, tear figures and run time (docs/multires.md)")
    st.add_argument("--factors", metavar="LIST", help="with --multires: the factors, e.g. 1,2,4 (default; 1 is always "
                    "run, as the reference)")
    _set_flag(st)
    return p


def _load(path: str, force: Optional[bool] = None, sets: Sequence[str] = ()):
    """The scene with --set overrides; unless `force` is True (None: no memory check), refuse (exit 2)
    a scene whose memory estimate exceeds what the machine has available."""
    from fraytool.scene import load_scene
    from fraytool.errors import SceneError
    from fraytool.scene.overrides import parse_assignment

    spec = load_scene(path, [parse_assignment(a) for a in sets])
    from fraytool.sim.memory import admission_problems

    problems = admission_problems(spec, force=force is not False)
    if problems:
        raise SceneError(problems)
    return spec


def cmd_simulate(args) -> int:
    from fraytool.sim.run import default_out_dir, simulate_to_disk

    spec = _load(args.scene, force=args.force, sets=args.sets)
    out = args.out or default_out_dir(spec)
    summary = simulate_to_disk(spec, out, frames=args.frames, resume=args.resume)
    if args.json:
        print(json.dumps(finite_json(summary)))
    else:
        at = summary.get("resumed_at_frame")
        kept = "" if not at else f" (resumed at frame {at}: frames 0-{at - 1} verified and kept)"
        print(f"wrote {summary['frames']} frames to {out / 'frames'}{kept}", file=sys.stderr)
    return 0


def cmd_check(args) -> int:
    if args.outputs is not None:
        from fraytool.commands.check_outputs import check_outputs

        return check_outputs(args.outputs, _load(args.scene) if args.scene else None, as_json=args.json)
    if args.scene is None:
        raise InputError("check: give a scene (or --outputs DIR to check an output folder)")
    from fraytool.sim.run import check_step
    from fraytool.sim.builder import build_model
    from fraytool.kinds import SPRING_KIND_NAMES
    from fraytool.sim.memory import available_bytes, estimate_bytes
    from fraytool.sim.mesh_report import describe_lines, describe_mesh_bodies
    from fraytool.sim.stability import stability_report

    spec = _load(args.scene, force=args.force, sets=args.sets)
    model = build_model(spec)
    bound = check_step(spec, model)
    if spec.render.supersample > 1:  # the drawn frame against the GL context, as `render` checks it
        from fraytool.render.renderer import check_drawn_size_early

        check_drawn_size_early(tuple(spec.render.resolution), spec.render.supersample, where=spec.source)
    slots = {name: int((model.spring_kind == k).sum()) for k, name in enumerate(SPRING_KIND_NAMES)}
    # shear twins are reserved slots, born only when a crossing splits (docs/tearing.md): not springs yet
    kinds = {name: (0 if name == "shear_twin" else n) for name, n in slots.items()}
    info = {
        "scene": spec.name,
        "masses": model.crossing_count,
        "particle_slots": model.particle_count,
        "springs": sum(kinds.values()),
        "springs_by_kind": kinds,
        "spring_slots": model.spring_count,
        "shear_twin_slots": slots["shear_twin"],
        "step_s": spec.time.step_s,
        "stability_bound_s": bound,
        "step_over_bound": spec.time.step_s / bound,
        **{k: v for k, v in stability_report(model, spec.time.step_s).items() if k != "step_s"},
        "bodies": len(spec.bodies),
        "mesh_bodies": describe_mesh_bodies(spec, model),
        "attached_masses": model.attachment_count,
        "simulated_s_per_frame": spec.time.step_s * spec.time.steps_per_frame,
        "memory_estimate_bytes": estimate_bytes(spec),
        "memory_available_bytes": available_bytes(),
    }
    if model.coarse_factor > 1:
        from fraytool.sim import multires

        layout = multires.coarse_layout(model)
        refined = model.state().coarse_cell_refined
        info.update({"coarse_factor": model.coarse_factor, "coarse_cells": layout.cell_count,
                     "coarse_whole_cells": int(layout.cell_whole.sum()),
                     "coarse_nodes": int(layout.crossing_is_node.sum()),
                     "cells_refined_at_start": int(refined.sum()),
                     "free_crossings_at_start": int(multires.free_crossings(layout, refined).sum()),
                     "refine_strain": model.refine_strain, "refine_band_cells": model.refine_band_cells})
    from fraytool.sim.tear_control_figures import figure_lines, tear_control_figures

    info.update(tear_control_figures(model, spec=spec))  # stitches and weakened springs; broken after --run
    if args.run:
        from fraytool.sim.checks import run_scene_checks

        info["checks"] = run_scene_checks(spec)
        for table in ("seams", "weak_lines"):
            info[table] = info["checks"]["summary"].get(table, info[table])
    if args.json:
        print(json.dumps(finite_json(info)))
    else:
        checks = info.pop("checks", None)
        listed = {k: info.pop(k) for k in ("mesh_bodies", "seams", "weak_lines")}
        for k, v in info.items():
            print(f"{k:28s} {_rounded(v)}")
        for line in describe_lines(listed["mesh_bodies"]) + figure_lines(listed):
            print(line)
        info.update(listed)
        if not info["power_converged"]:
            print(f"note: power iteration stopped after {info['power_iterations']} sweeps (cap "
                  f"{info['power_sweep_cap']}, about a second of work) before converging: omega_max_power_rad_s "
                  "is a lower bound, so stability_bound_power_s may be too large; the step is judged by "
                  "Gershgorin's bound, which is safe")
        if checks is not None:
            print(f"checks after {checks['frames']} frames: {'passed' if checks['passed'] else 'FAILED'}")
            for name, r in checks["results"].items():
                print(f"  {'ok  ' if r['passed'] else 'FAIL'} {name}: {r['value']} (wanted {r['wanted']})")
        info["checks"] = checks
    if args.run and not info["checks"]["passed"]:
        return 1
    return 0


def _rounded(v):
    """Figures for people: floats to 6 significant digits, dicts as "key value" pairs."""
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, dict):
        return ", ".join(f"{k} {_rounded(x)}" for k, x in v.items())
    return v


def cmd_bench(args) -> int:
    from fraytool.commands.bench import bench_command

    return bench_command(args)


def cmd_render(args) -> int:
    from fraytool.commands.render import render_command

    return render_command(args)


def cmd_study(args) -> int:
    from fraytool.commands.study import study_command

    return study_command(args)


def cmd_batch(args) -> int:
    from fraytool.commands.batch import batch_command

    return batch_command(args)


def cmd_export(args) -> int:
    from fraytool.commands.export import export_command

    return export_command(args)


def cmd_preview(args) -> int:
    from fraytool.commands.preview import preview_command

    return preview_command(args, _load)


def cmd_golden(args) -> int:
    from fraytool.commands.golden import golden_command

    return golden_command(args)


COMMANDS = {"golden": cmd_golden, "batch": cmd_batch, "simulate": cmd_simulate, "check": cmd_check, "bench": cmd_bench, "render": cmd_render,
            "study": cmd_study, "export": cmd_export, "preview": cmd_preview}


VECTOR_FLAGS = ("--camera-position", "--camera-target")
"""Flags whose value may start with a minus sign (argparse would take "-0.02,0.26,0.16" for a flag)."""


def _join_negative_vectors(argv: Sequence[str]) -> list[str]:
    """`--camera-position -0.02,0.26,0.16` -> `--camera-position=-0.02,0.26,0.16`."""
    out, i = [], 0
    while i < len(argv):
        tok = argv[i]
        if tok in VECTOR_FLAGS and i + 1 < len(argv) and argv[i + 1][:2].lstrip("-")[:1] in "0123456789." \
                and argv[i + 1].startswith("-"):
            out.append(f"{tok}={argv[i + 1]}")
            i += 2
            continue
        out.append(tok)
        i += 1
    return out


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = _join_negative_vectors(sys.argv[1:] if argv is None else list(argv))
    args = build_parser().parse_args(argv)
    from fraytool.progress import set_default_mode

    set_default_mode(getattr(args, "progress", "auto"))
    try:
        from fraytool.resident_memory import map_large_blocks
        from fraytool.threads import set_up_threads

        map_large_blocks()
        set_up_threads(getattr(args, "threads", None))
        return COMMANDS[args.command](args)
    except FraytoolError as exc:
        kind = "error" if isinstance(exc, InputError) else "run failed"
        for line in str(exc).splitlines() or [repr(exc)]:
            print(f"fraytool: {kind}: {_cut(line)}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("fraytool: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 1
    except OSError as exc:  # a write or read of an output failed: one line, path, cause, what to do
        print(f"fraytool: run failed: {os_error_message(exc)}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    raise SystemExit(main())
