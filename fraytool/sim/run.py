"""Running a scene to disk: the driver behind `fraytool simulate` (and `render`, `bench`).

Frames go to a FrameStore; `resume=True` continues from the last complete frame's checkpoint and
gives the same frames, bit for bit, as an uninterrupted run.
"""
from __future__ import annotations

import hashlib
import json
import sys
import time
from pathlib import Path
from typing import Optional

import numpy as np
from fraytool.errors import OutputError, SceneError
from fraytool.io.frame_store import FrameStore
from fraytool.io.lock import OutputLock
from fraytool.progress import Progress
from fraytool.scene.load import scene_hash
from fraytool.scene.spec_io import spec_to_json
from fraytool.scene.spec import SceneSpec
from fraytool.sim.builder import build_model
from fraytool.io.failure import write_failure
from fraytool.sim.diagnostic import unstable_message
from fraytool.sim.guard import explain_failure, record_is_finite
from fraytool.sim.model import Model
from fraytool.sim.simulation import Simulation
from fraytool.sim.solver import SimulationUnstable
from fraytool.sim.state import State
from fraytool.sim.stability import stable_step_bound_s


def default_out_dir(spec: SceneSpec) -> Path:
    return Path("outputs") / spec.name


def check_step(spec: SceneSpec, model: Model, stream=None) -> float:
    """Compare the step with the explicit stability bound: warn, or refuse (SceneError) when the
    scene says [time] stability = "refuse"; print what the builder noticed (Model.build_warnings: a mesh
    in the wrong unit, an open mesh, a seam whose stitches start torn, an attachment that holds nothing).
    Returns the bound [s]."""
    bound = stable_step_bound_s(model)
    if spec.time.step_s > bound:
        msg = (f"{spec.source}: [time] step_s = {spec.time.step_s:g}: above the explicit stability bound "
               f"{bound:.6g} s (2 / omega_max, Gershgorin, from the stiffest springs and lightest mass); "
               f"use step_s <= {bound:.6g} or lower the stiffness")
        if spec.time.stability == "refuse":
            raise SceneError([msg])
        print(f"fraytool: warning: {msg}", file=stream or sys.stderr)
    for line in model.build_warnings:
        print(f"fraytool: warning: {line}", file=stream or sys.stderr)
    return bound


SCENE_RECORD = "scene_json"
"""Topology entry holding the SceneSpec as JSON (fraytool.scene.spec_io): a frames folder renders, exports
and resumes without its scene file."""


def shot_hash(spec: SceneSpec, model: Optional[Model] = None) -> str:
    """The digest naming a shot's frames: the scene's (scene_hash), or with a Model built or edited in
    Python, the scene's and the Model's arrays' together (an edited break strain is another shot)."""
    digest = scene_hash(spec)
    if model is None:
        return digest
    return hashlib.sha256(f"{digest}:{model.digest()}".encode()).hexdigest()[:16]


def shot_topology(spec: SceneSpec, model: Model) -> dict:
    """What a frames folder's topology.npz holds: the Model's arrays and the scene as JSON."""
    return {**model.arrays(), SCENE_RECORD: np.asarray(spec_to_json(spec))}


def simulate_to_disk(spec: SceneSpec, out_dir: Path, frames: Optional[int] = None, resume: bool = False,
                     progress: Optional[bool] = None, stream=None, model: Optional[Model] = None,
                     digest: Optional[str] = None) -> dict:
    """Simulate `frames` frames (default: the scene's) into out_dir/frames; returns the summary.

    `model`: a Model built or edited in Python (ModelBuilder, or build_model then an edit) to simulate
    instead of the scene's own; `spec` still gives the time step, frames, camera and render settings. Its
    arrays are saved with the frames (topology.npz, with the scene), so `fraytool render OUT` and
    `fraytool export OUT` (or fraytool.api) render and export it, and a resume continues it, without a
    scene file. `digest`: the frames' hash when continuing a shot read back from its folder (load_shot);
    default shot_hash(spec, model).

    The output folder is held (OutputLock) for the whole run, and temp files of dead writers in it
    are swept. With `resume`, the store is surveyed first: missing, truncated, corrupted or foreign
    files are reported on `stream`, and the run continues from the checkpoint when it follows the
    last good frame, else from frame 0 (deterministic: frames that verify are not rewritten)."""
    stream = stream or sys.stderr
    built = build_model(spec) if model is None else model
    check_step(spec, built, stream)  # bad input (SceneError) before anything is written
    with OutputLock(out_dir, "simulate"):
        store = FrameStore(out_dir)
        for p in store.sweep_temp_files():
            print(f"fraytool: removed {p} (a temp file of a write that was killed)", file=stream)
        return _simulate_locked(spec, store, frames, resume, progress, stream, model, digest, built)


def _store_info(spec: SceneSpec, model: Model, total: int) -> dict:
    return {"scene": spec.name, "seed": spec.scene.seed, "frames_planned": total,
            "step_s": spec.time.step_s, "steps_per_frame": spec.time.steps_per_frame, "fps": spec.time.fps,
            "particle_count": model.particle_count, "spring_count": model.spring_count}


def _resume_point(spec: SceneSpec, model: Model, store: FrameStore, digest: str, total: int,
                  stream, topology: dict) -> Optional[tuple[Simulation, int]]:
    """(simulation to continue, first frame whose record must be written) after surveying the store,
    or None when nothing there can be reused (a fresh start)."""
    m = store.manifest()
    if m is not None and m.get("scene_hash") != digest:
        raise OutputError(f"{store.dir}: frames were made from a different scene or version "
                          f"(scene hash {m.get('scene_hash')} != {digest}): they cannot be continued; run "
                          "without --resume to replace them, or choose another output folder with -o")
    survey = store.survey(digest)
    if survey.manifest is None and survey.good_frames == 0:
        if store.dir.exists() and any(store.dir.iterdir()):
            for line in survey.problems:
                print(f"fraytool: {line}", file=stream)
            print(f"fraytool: nothing in {store.dir} can be reused; simulating afresh", file=stream)
        return None
    for line in survey.problems:
        print(f"fraytool: {line}", file=stream)
    good = survey.good_frames
    store.reopen(digest, _store_info(spec, model, total), good, topology, not survey.topology_ok)
    if good > 0 and survey.resumable_from_checkpoint():
        frame, arrays = store.load_checkpoint()
        sim = Simulation(spec, model=model, state=State.from_arrays(arrays, model.body_rotation),
                         frame=frame)
        sim.restore_shot(arrays)
        return sim, frame + 1
    if survey.problems:
        print(f"fraytool: no checkpoint at frame {good - 1}: re-simulating from frame 0 "
              f"(frames 0-{good - 1} verify and are kept)" if good else
              "fraytool: re-simulating from frame 0", file=stream)
    return Simulation(spec, model=model), good


def _simulate_locked(spec: SceneSpec, store: FrameStore, frames: Optional[int], resume: bool,
                     progress: Optional[bool], stream, given: Optional[Model] = None,
                     digest: Optional[str] = None, built: Optional[Model] = None) -> dict:
    total = spec.time.frames if frames is None else frames
    model = built if built is not None else (build_model(spec) if given is None else given)
    digest = digest or shot_hash(spec, given)
    topology = shot_topology(spec, model)
    point = _resume_point(spec, model, store, digest, total, stream, topology) if resume else None
    if point is not None:
        sim, first_write = point
        store.clear_failure()  # a failure recorded by an earlier attempt no longer describes this run
        if sim.frame == 0 and first_write == 0:
            store.write_frame(sim.record(), sim.checkpoint_arrays())
    else:
        store.start(topology, digest, _store_info(spec, model, total))
        sim, first_write = Simulation(spec, model=model), 1
        try:
            store.write_frame(sim.record(), sim.checkpoint_arrays())
        except OSError:
            store.restore_previous()
            raise
    try:
        summary = _advance(spec, sim, store, total, first_write, progress, stream)
        # with --resume: the first frame this run wrote (the frames before it verified and were kept)
        summary["resumed_at_frame"] = first_write if point is not None else None
        return summary
    except OSError:
        if point is None and store.restore_previous():  # a fresh run failed on I/O: the old frames are back
            print(f"fraytool: {store.dir}: the previous frames are back in place", file=stream)
        raise


def _advance(spec: SceneSpec, sim: Simulation, store: FrameStore, total: int, first_write: int,
             progress, stream) -> dict:
    from fraytool._numba_cache import cold_start_note, first_compile_notice

    note = cold_start_note()
    if note and sim.frame < total:
        print(note, file=stream)
    bar = Progress(total, spec.name, stream=stream, enabled=progress, stage="simulate")
    try:
        with first_compile_notice(bar.message if not note else (lambda text: None)):
            _frames(sim, store, total, first_write, bar)
    except SimulationUnstable as exc:
        bar.close()
        raise _unstable_run(sim, store, exc) from None
    bar.close()
    store.update_manifest(frames_planned=max(total, store.manifest().get("frames_planned", 0)))
    store.drop_previous()
    warning = sim.woven_strain_warning()
    if warning:
        print(f"fraytool: warning: {warning}", file=stream)
    return sim.summary()


def _frames(sim: Simulation, store: FrameStore, total: int, first_write: int, bar: Progress) -> None:
    """Advance and write frame by frame up to `total` (the frames before first_write only advance)."""
    t_last = time.perf_counter()
    while sim.frame + 1 < total:
        record = sim.advance_frame()
        if not record_is_finite(record):  # the guard checks active masses; never write a NaN frame
            raise SimulationUnstable("frame record holds a non-finite value",
                                     {"step": sim.state.step_index, "time_s": sim.state.time_s,
                                      "stage": "frame record", "stage_located": True,
                                      "kernel": "frame_record"})
        if sim.frame >= first_write:
            store.write_frame(record, sim.checkpoint_arrays())
        elif sim.frame == first_write - 1:  # the last kept frame: its checkpoint, for a later resume
            store.write_frame(record, sim.checkpoint_arrays(), write_record=False)
        now = time.perf_counter()
        bar.update(sim.frame + 1, f"{1e3 * (now - t_last):6.1f} ms/frame")
        t_last = now


def _unstable_run(sim: Simulation, store: FrameStore, exc: SimulationUnstable) -> SimulationUnstable:
    """After the guard stopped a run: replay the failed step from the last complete frame's checkpoint
    to find the stage, write <out>/frames/unstable.json and the last good state, note it in the
    manifest, and return the error to raise (one line for the user; exit code 1). The frames on disk
    stay those of the complete, finite frames before the failure."""
    try:
        start = State.from_arrays(store.load_checkpoint()[1], sim.model.body_rotation)
    except (OSError, KeyError, ValueError, OutputError):
        start = None
    diag, last_good = explain_failure(sim.solver, start, sim.dt_s, exc.diagnostic)
    diag["last_good_frame"] = store.frames_complete() - 1
    path = write_failure(store.dir, diag, last_good.arrays() if last_good is not None else None)
    store.update_manifest(unstable=json.loads(path.read_text()))
    return SimulationUnstable(unstable_message(diag, str(path)), diag)


def is_shot_folder(path: str | Path) -> bool:
    """True when `path` is an output folder holding simulated frames (OUT/frames/topology.npz)."""
    p = Path(path)
    return p.is_dir() and (p / "frames" / "topology.npz").is_file()


def load_shot(out_dir: str | Path) -> tuple[SceneSpec, Model, str]:
    """(scene, model, digest) of a simulated shot from its frames folder alone: the scene and the Model
    the frames were simulated from (a scene's own, or one built or edited in Python), and the frames'
    hash, to continue them with. Raises OutputError naming what is missing or damaged."""
    from fraytool.scene.spec_io import spec_from_json

    store = FrameStore(Path(out_dir))
    manifest = store.manifest()
    if manifest is None:
        raise OutputError(f"{store.dir}: no intact manifest.json: not a frames folder fraytool wrote "
                          f"({store.manifest_problem()})")
    topology = store.load_topology()
    where = store.dir / "topology.npz"
    if SCENE_RECORD not in topology:
        raise OutputError(f"{where}: holds no scene record (simulated by an older fraytool): "
                          "render or export it from its scene file instead")
    try:
        spec = spec_from_json(str(topology.pop(SCENE_RECORD)), source=str(where))
    except ValueError as exc:
        raise OutputError(f"{where}: its scene record does not read back: {exc}") from None
    try:
        model = Model.from_arrays(topology)
    except (ValueError, KeyError, TypeError) as exc:
        raise OutputError(f"{where}: the saved model does not read back: {exc}") from None
    return spec, model, manifest["scene_hash"]
