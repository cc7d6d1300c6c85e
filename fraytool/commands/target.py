"""What `render`, `export` and `bench --render` act on: a scene file (or a shipped scene's name), or the
output folder of a simulated shot, which holds its scene and Model (fraytool.sim.run.load_shot), as a shot
simulated from a Model built in Python does."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

from fraytool.errors import InputError, SceneError
from fraytool.scene import SceneSpec
from fraytool.sim.model import Model


@dataclass(frozen=True)
class Target:
    spec: SceneSpec
    model: Optional[Model] = None
    """The Model to simulate instead of the scene's (a saved shot's); None: the scene file's own."""
    out_dir: Optional[Path] = None
    """The shot's folder when the target is one (the default output folder)."""
    digest: Optional[str] = None
    """The frames' digest when the target is a shot folder."""

    def output_dir(self, out: Optional[str | Path]) -> Path:
        """Where the command writes: `-o OUT` if given, else the shot's own folder, else outputs/<name>/."""
        from fraytool.sim.run import default_out_dir

        return Path(out) if out else self.out_dir or default_out_dir(self.spec)

    def frame_sources(self) -> list[Path]:
        """Folders whose frames of this shot a command writing elsewhere (`-o OTHER`) reuses: the shot's own
        folder, then the scene's default one (fraytool.commands.render.ensure_frames checks the digest)."""
        from fraytool.sim.run import default_out_dir

        return [d for d in (self.out_dir, default_out_dir(self.spec)) if d is not None]


def load_target(name: str, sets: Sequence[str] = (), force: bool = False) -> Target:
    """The scene file `name` with its --set overrides (refused, exit 2, when the machine lacks the memory
    unless `force`), or the shot in the output folder `name`."""
    from fraytool.resources import scenes_dir, shipped_scene
    from fraytool.sim.run import is_shot_folder, load_shot

    shipped = shipped_scene(name)
    if is_shot_folder(name):
        if sets:
            also = (f" (`{name}` is also a shipped scene's name: give "
                    f"scenes/{shipped.relative_to(scenes_dir()).as_posix()} to render that one with --set)"
                    if shipped is not None else "")
            raise InputError(f"{name}: --set changes a scene file's keys; this is a simulated shot's folder, whose "
                             f"scene is fixed: render its scene file with --set instead, or re-simulate in Python{also}")
        spec, model, digest = load_shot(name)
        return Target(spec, model, Path(name), digest)
    if Path(name).is_dir() and shipped is None:
        raise InputError(f"{name}: a folder without simulated frames (no frames/topology.npz): give a scene file, "
                         "a shipped scene's name, or the output folder of a simulated shot")
    # a folder here that holds no shot does not hide the shipped scene of that name (as for `simulate`)
    from fraytool.scene import load_scene
    from fraytool.scene.overrides import parse_assignment
    from fraytool.sim.memory import admission_problems

    spec = load_scene(name, [parse_assignment(a) for a in sets])
    problems = admission_problems(spec, force=force)
    if problems:
        raise SceneError(problems)
    return Target(spec)
