"""`fraytool render SCENE`: simulate (or reuse frames of the same scene hash) and render PNG / MP4.

Order of work, so that mistakes fail fast: check every flag (InputError, exit 2) -> create the GL
context (RunError, exit 1, before any long simulation) -> make sure the frame records exist ->
render. See docs/rendering.md.
"""
from __future__ import annotations

import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Optional, Sequence, TextIO

from fraytool.commands.target import load_target
from fraytool.errors import FraytoolError, RunError
from fraytool.io.frame_store import FrameStore
from fraytool.io.lock import OutputLock
from fraytool.render.job import build_job
from fraytool.render.motion_blur import frames_needed
from fraytool.render.options import RenderRequest
from fraytool.scene import SceneSpec
from fraytool.sim.model import Model


def ensure_frames(spec: SceneSpec, out_dir: Path, needed: int, stream: TextIO = sys.stderr,
                  model: Optional[Model] = None, digest: Optional[str] = None,
                  sources: Sequence[Path] = ()) -> FrameStore:
    """Frame records 0..needed-1: reuse out_dir/frames if the manifest's digest matches and frames
    0..needed-1 verify (checksums); else reuse those of another folder of `sources` that holds them (the shot
    folder rendered with `-o OTHER`, the scene's default folder: a change of the picture only simulates
    nothing, and says so); else continue or repair a matching run in out_dir (resume: the damaged files are
    named on `stream`), else simulate afresh, naming the scene keys that differ from the frames it replaces.
    `model`: a Model built or edited in Python to simulate instead of the scene's
    (fraytool.sim.run.simulate_to_disk); `digest`: the frames' hash of a shot read back from its folder
    (default: shot_hash(spec, model))."""
    from fraytool.sim.run import shot_hash, simulate_to_disk

    store = FrameStore(out_dir)
    digest = digest or shot_hash(spec, model)
    if _holds(store, digest, needed):
        return store
    for source in sources:
        other = FrameStore(Path(source))
        if other.dir.resolve() != store.dir.resolve() and _holds(other, digest, needed):
            print(f"fraytool: reusing the frames simulated in {other.dir} (the settings change only the picture: "
                  "nothing is simulated)", file=stream)
            return other
    if store.matches(digest) or (store.manifest() is None and store.dir.is_dir()):
        done = store.frames_complete()
        survey = store.survey(digest, frames=min(done, needed) if store.manifest() else None)
        if survey.clean and done >= needed:
            return store
        if survey.good_frames > 0:
            if survey.clean:
                print(f"fraytool: continuing the simulation in {store.dir} from frame {done} to {needed}",
                      file=stream)
            simulate_to_disk(spec, out_dir, frames=needed, resume=True, stream=stream, model=model, digest=digest)
            return store
    print(f"fraytool: simulating {needed} frames into {store.dir}", file=stream)
    for line in _why_again(spec, digest, needed, [store] + [FrameStore(Path(s)) for s in sources]):
        print(f"fraytool: {line}", file=stream)
    simulate_to_disk(spec, out_dir, frames=needed, stream=stream, model=model, digest=digest)
    return store


def _holds(store: FrameStore, digest: str, needed: int) -> bool:
    """True when `store` holds intact frames 0..needed-1 of the shot `digest`."""
    if not store.matches(digest) or store.frames_complete() < needed:
        return False
    return store.survey(digest, frames=needed).clean


def _why_again(spec: SceneSpec, digest: str, needed: int, stores: list) -> list[str]:
    import dataclasses

    """Why frames already on disk for this scene cannot be reused: the simulation keys that differ from the
    first of `stores` that holds a shot of the same name, or that it holds too few frames (none: nothing to
    say)."""
    from fraytool.scene.load import key_changes, simulation_keys
    from fraytool.sim.run import is_shot_folder, load_shot

    for store in stores:
        if not is_shot_folder(store.out_dir):
            continue
        try:
            old_spec, _, _ = load_shot(store.out_dir)
        except FraytoolError:
            continue
        if old_spec.name != spec.name:
            continue
        if store.matches(digest):
            good = store.survey(digest, frames=needed).good_frames
            return [f"not reusing the frames in {store.dir}: {good} of the {needed} frames needed are intact"]
        # a saved scene has no file of its own: its meshes, masks and tear maps are the scene file's
        old_spec = dataclasses.replace(old_spec, source_file=old_spec.source_file or spec.source_file)
        changed = key_changes(simulation_keys(old_spec), simulation_keys(spec))
        if not changed:
            changed = ["no scene key: the Model (built or edited in Python), a file the scene reads, or the "
                       "solver's revision changed"]
        return [f"not reusing the frames in {store.dir}: they were simulated with other settings: "
                + "; ".join(changed)]
    return []


@contextmanager
def _reading(store: FrameStore, out_dir: Path, digest: str, needed: int, stream: TextIO):
    """While frames of another folder are read (look-dev into -o OTHER), hold that folder's lock too, so that
    no simulation replaces them half way through; they must still be the shot's once it is held."""
    if store.out_dir.resolve() == Path(out_dir).resolve():
        yield
        return
    with OutputLock(store.out_dir, "render", wait_stream=stream):
        if not _holds(store, digest, needed):
            raise RunError(f"{store.dir}: its frames changed while this render waited for the folder; render again "
                           "(it simulates what it needs)")
        yield


def fitted_line(cam) -> str:
    """Where a fitted camera is, for the --fit message: its pose at frame 0, and its keys if it moves."""
    moving = f" on frame 0, moving on {len(cam.position_keys_m)} keys" if cam.position_keys_m else ""
    return f"camera at {_fmt(cam.position_m)} looking at {_fmt(cam.target_m)}{moving}"


def _fmt(v) -> str:
    return "(" + ", ".join(f"{x:.4f}" for x in v) + ")"


class _Terminated(SystemExit):
    """SIGTERM (a farm scheduler pre-empting the job) turned into an exception, so the same clean-up
    as for Ctrl-C runs: ffmpeg stopped, the partial video deleted, the GL context released."""


def _on_sigterm(signum, frame):  # pragma: no cover - exercised through a subprocess
    raise _Terminated(128 + signum)


def render_command(args, stream: Optional[TextIO] = None) -> int:
    """`fraytool render` from its parsed command line."""
    return render(args.scene, RenderRequest.from_args(args), stream)


def render(scene: str, request: RenderRequest, stream: Optional[TextIO] = None) -> int:
    """Render `scene` (a scene file, a shipped scene's name or a shot's folder) as `request` asks; 0 on
    success (InputError, RunError otherwise). SIGTERM cleans up as Ctrl-C does (in the main thread)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return _render(scene, request, stream)
    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return _render(scene, request, stream)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _render(scene: str, args: RenderRequest, stream: Optional[TextIO]) -> int:
    stream = stream or sys.stderr
    target = load_target(scene, args.sets, force=args.force)
    spec = target.spec
    job = build_job(spec, args, target.output_dir(args.out), shot_folder=target.out_dir is not None)
    if job.exr:
        try:
            import OpenEXR  # noqa: F401  (a dependency of fraytool; missing only in a broken installation)
        except ImportError:
            raise RunError('--exr needs the OpenEXR package, which is not installed: pip install "openexr>=3.2" '
                           '(or reinstall fraytool)') from None
    if job.codec == "prores" and not args.alpha:
        print("fraytool: --codec prores: ProRes 4444 carries alpha, so the background is transparent (as with "
              "--alpha, for the PNGs and EXRs too)", file=stream)
    from fraytool.render.context import create_context, describe
    from fraytool.render.renderer import check_drawn_size, clamp_samples

    ctx = create_context()
    try:
        if args.verbose:
            print(describe(ctx), file=stream)
            print(f"MSAA samples: {clamp_samples(ctx, job.samples)} (asked {job.samples})"
                  + (f"; supersampled {job.spec.render.supersample} x {job.spec.render.supersample}"
                     if job.spec.render.supersample > 1 else ""), file=stream)
        check_drawn_size(ctx, job.size, job.spec.render.supersample, job.wireframe, where=job.spec.source)  # before simulating
        if job.samples > 1 and clamp_samples(ctx, job.samples) < job.samples:
            print(f"fraytool: warning: [render] samples = {job.samples}: this OpenGL driver "
                  f"({ctx.info.get('GL_RENDERER', '?')}) draws at most {int(ctx.max_samples)} MSAA samples a "
                  f"pixel; drawing with {clamp_samples(ctx, job.samples)}", file=stream)
        from fraytool.render.sequence import render_job

        with OutputLock(job.out_dir, "render", wait_stream=stream):
            # the fit covers the whole shot, so farm shards of one scene agree on the camera
            from fraytool.sim.run import shot_hash

            needed = job.spec.time.frames if job.spec.camera.fit else frames_needed(job)
            digest = target.digest or shot_hash(spec, target.model)
            store = ensure_frames(spec, job.out_dir, needed, stream, target.model, digest, target.frame_sources())
            with _reading(store, job.out_dir, digest, needed, stream):
                if job.spec.camera.fit:
                    from fraytool.render.fit import fitted_job

                    job = fitted_job(job, store)
                    cam = job.spec.camera
                    print(f"fraytool: --fit: {fitted_line(job.spec.camera)}", file=stream)
                result = render_job(job, ctx, store, stream=stream)
    finally:
        ctx.release()
    if result.png_dir:
        from fraytool.commands.check_outputs import mixed_png_sets

        for line in mixed_png_sets(Path(result.png_dir)):
            print(f"fraytool: warning: {line}", file=stream)
    wrote = [result.video] if result.video else []
    folders = [f"{d}/" for d in (result.png_dir, result.exr_dir) if d]
    if folders:
        wrote.append(f"{', '.join(folders)} ({result.rendered} rendered, {result.reused} kept from an earlier run)")
    verb = "rendered" if result.rendered else "finished"  # every frame kept: nothing drawn, the video rebuilt
    print(f"fraytool: {verb} {result.frames} frame{'' if result.frames == 1 else 's'}: " + "; ".join(wrote),
          file=stream)
    return 0
