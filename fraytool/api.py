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
from typing import Optional, Sequence

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
           motion_samples: Optional[int] = None, options: Sequence[str] = ()) -> Path:
    """Render a shot folder (or a scene file or shipped scene's name) as `fraytool render` does; returns the
    output folder. `frames` is a range "START:END[:STEP]"; `motion_blur` and `motion_samples` are
    --motion-blur and --motion-samples (0: no blur); `options` are more of the command's flags, e.g.
    ("--resolution", "640x360", "--alpha")."""
    from fraytool.commands.render import render_command

    argv = ["render", str(target)] + _common(out_dir, frames) + (["--png"] if png else []) \
        + ([] if video else ["--no-mp4"]) + (["--exr"] if exr else []) \
        + (["--motion-blur", str(motion_blur)] if motion_blur else []) \
        + (["--motion-samples", str(motion_samples)] if motion_samples is not None else []) + list(options)
    args = _parse(argv)
    render_command(args)
    return _out_dir(args)


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


def _out_dir(args) -> Path:
    from fraytool.commands.target import load_target

    return load_target(args.scene, args.sets or ()).output_dir(args.out)
