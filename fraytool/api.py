"""The Python path to disk: simulate a scene, or a Model built or edited in Python, into an output folder,
then render and export that folder, with no scene file needed after the simulation.

    from fraytool import api
    from fraytool.scene import load_scene
    from fraytool.sim import build_model

    spec = load_scene("scenes/fig7_square_grab.toml")
    model = build_model(spec)
    model.spring_break_strain[weak] *= 0.6                 # any edit of the Model's arrays
    api.simulate(spec, "outputs/weak", model=model)       # frames + the Model + the scene, on disk
    api.render("outputs/weak", png=True)                  # what `fraytool render outputs/weak --png` does
    api.export_usd("outputs/weak", "outputs/weak/weak.usdc")

`render` and `export_usd` run the same code as the commands (`fraytool render FOLDER`, `fraytool export
FOLDER --usd`), with the same checks; errors are raised (fraytool.errors), not turned into exit codes.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional

from fraytool.scene import SceneSpec
from fraytool.sim.model import Model


def simulate(spec: SceneSpec, out_dir: str | Path, *, model: Optional[Model] = None, frames: Optional[int] = None,
             resume: bool = False, progress: Optional[bool] = None) -> dict:
    """Simulate `frames` frames (default: the scene's) of `spec`, or of `model` with the spec's time step,
    camera and render settings, into out_dir/frames; returns the `simulate --json` summary. The Model's
    arrays and the scene are saved with the frames (fraytool.sim.run.simulate_to_disk)."""
    from fraytool.sim.run import simulate_to_disk

    return simulate_to_disk(spec, Path(out_dir), frames=frames, resume=resume, progress=progress, model=model)


def render(target: str | Path, *, out_dir: Optional[str | Path] = None, frames: Optional[str] = None,
           png: bool = False, video: bool = True, exr: bool = False, motion_blur: float = 0.0,
           motion_samples: Optional[int] = None, **more) -> Path:
    """Render a shot folder (or a scene file or shipped scene's name) as `fraytool render` does; returns the
    output folder. `frames` is a range "START:END[:STEP]"; `motion_blur` and `motion_samples` are
    --motion-blur and --motion-samples (0: no blur); `more` are the other fields of
    fraytool.render.options.RenderRequest, e.g. resolution=(640, 360), alpha=True, samples=0, fov=30.
    The values are checked as the command line's are (InputError naming the flag)."""
    import dataclasses

    from fraytool.commands.render import render as render_shot
    from fraytool.errors import InputError
    from fraytool.render.options import RenderRequest

    known = {f.name for f in dataclasses.fields(RenderRequest)} - {"out"}
    unknown = sorted(set(more) - known)
    if unknown:
        raise InputError(f"fraytool.api.render: unknown option {', '.join(unknown)}; allowed: {', '.join(sorted(known))}")
    request = RenderRequest(out=str(out_dir) if out_dir is not None else None, frames=frames, png=png, video=video,
                            exr=exr, motion_blur=motion_blur or None, motion_samples=motion_samples, **more)
    render_shot(str(target), request)
    from fraytool.commands.target import load_target

    return load_target(str(target), request.sets).output_dir(request.out)


def export_usd(target: str | Path, usd_path: str | Path, *, out_dir: Optional[str | Path] = None,
               frames: Optional[str] = None) -> Path:
    """Write a shot folder (or a scene) as USD, as `fraytool export --usd` does; returns the USD file."""
    from fraytool.commands.export import export_command

    export_command(_parse(["export", str(target), "--usd", str(usd_path)] + _common(out_dir, frames)))
    return Path(usd_path)


def _common(out_dir, frames) -> list[str]:
    return (["-o", str(out_dir)] if out_dir is not None else []) + (["--frames", frames] if frames else [])


def _parse(argv: list[str]):
    """The command's arguments, checked by the command line's own parser (a bad value raises InputError)."""
    from fraytool.commands.main import build_parser
    from fraytool.errors import InputError

    parser = build_parser()
    try:
        return parser.parse_args(argv)
    except SystemExit:
        raise InputError(f"fraytool.api: bad arguments for `fraytool {' '.join(argv)}` (see the message above)") from None


    return load_target(args.scene, args.sets or ()).output_dir(args.out)
