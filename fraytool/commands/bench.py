"""`fraytool bench`: median milliseconds per frame and the split by stage.

An empty run first (build, first frame, export) pays numba compilation (or loading it from the
cache); it is timed apart as compile_s, and the memory figures are taken over the resident size
after it (bench_simulation). Frames are exported to a temporary folder so the export
stage is measured as a real run pays it.
"""
from __future__ import annotations

import gc
import json
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from fraytool._numba_cache import kernels_compiled
from fraytool.io.frame_store import FrameStore
from fraytool.resident_memory import peak_rss_bytes, release_freed_memory, reset_peak, rss_bytes
from fraytool.scene import load_scene, scene_hash
from fraytool.sim.simulation import Simulation

DEFAULT_FRAMES = 48


def empty_run(spec, out_dir: Path) -> float:
    """Build the scene, simulate and write its first frame, and drop it all: every module and numba
    kernel the run uses is then loaded (compiled or read from the cache). Returns the seconds taken."""
    t0 = time.perf_counter()
    sim = Simulation(spec)
    store = FrameStore(out_dir)
    store.start(sim.model.arrays(), scene_hash(spec), {"scene": spec.name})
    record = sim.advance_frame()
    store.write_frame(record, sim.checkpoint_arrays())
    return time.perf_counter() - t0


def _threads() -> int:
    """Threads the parallel kernels may use in this run (--threads or numba's default)."""
    import numba

    return int(numba.get_num_threads())


def bench_simulation(spec, frames: int = DEFAULT_FRAMES, out_dir: Path | None = None) -> dict:
    """An empty run, then `frames` frames simulated and written; returns the bench figures.

    compile_s: the empty run (build, first frame and its export), where numba compiles or loads
    every kernel the scene uses. bytes_per_crossing: (peak RSS of the measured run - RSS after the
    empty run) / crossings, i.e. what the model, the state, the solver's scratch, the stages, the
    temporaries of building and stepping, and the frame export add over a process that has every
    kernel loaded (the empty run's freed memory goes back to the system first: malloc_trim). Where
    the peak cannot be reset (no /proc/self/clear_refs), the baseline is the peak before the empty
    run, kernels included (memory_baseline says which).

    Kernels first used after the first frame (a split, a cut, a re-attachment) are compiled during
    the timed frames when numba's cache is cold (after a change): their compilation would then be in
    the stage means and the memory peak. So when that happened (kernels_compiled_in_timed_frames > 0)
    the frames are timed a second time, every kernel loaded by then, and the second run is reported
    (timed_runs = 2)."""
    rss_start = peak_rss_bytes()
    with tempfile.TemporaryDirectory() as tmp:
        compile_s = empty_run(spec, Path(tmp) / "empty")
    compiled_before = kernels_compiled()
    run = _timed_run(spec, frames, out_dir, rss_start)
    compiled = kernels_compiled() - compiled_before
    runs = 1
    if compiled:
        run = _timed_run(spec, frames, out_dir, rss_start)
        runs = 2
    sim, per_frame, export_s, peak, rss_before, baseline = run
    stages = {k: 1e3 * v / frames for k, v in sim.solver.stage_s.items() if v > 0.0}
    return {
        "scene": spec.name,
        "masses": int(sim.state.particle_active.sum()),
        "springs": int(sim.state.spring_alive.sum()),
        "frames": frames,
        "steps_per_frame": spec.time.steps_per_frame,
        "threads": _threads(),
        "ms_per_frame": 1e3 * statistics.median(per_frame),
        "stages_ms_per_frame": stages,
        "export_ms_per_frame": 1e3 * statistics.median(export_s),
        "compile_s": compile_s,
        "kernels_compiled_in_timed_frames": compiled,
        "timed_runs": runs,
        "strain_iterations_max": sim.solver.strain_iterations_max,
        "peak_rss_bytes": peak,
        "bytes_per_crossing": (peak - rss_before) / max(1, sim.model.crossing_count),
        "memory_baseline": baseline,
        "summary": sim.summary(),
    }


def _timed_run(spec, frames: int, out_dir: Path | None, rss_start: int):
    """One timed run of `frames` frames, simulated and written (bench_simulation): (the Simulation,
    seconds per frame, export seconds per frame, peak RSS, the RSS baseline, what the baseline is)."""
    gc.collect()
    release_freed_memory()
    if reset_peak():
        rss_before, baseline = rss_bytes(), "after an empty run"
    else:
        rss_before, baseline = rss_start, "before an empty run (kernels included)"
    sim = Simulation(spec)
    with tempfile.TemporaryDirectory() as tmp:
        store = FrameStore(Path(out_dir or tmp))
        store.start(sim.model.arrays(), scene_hash(spec), {"scene": spec.name})
        per_frame, export_s = [], []
        for _ in range(frames):
            t = time.perf_counter()
            record = sim.advance_frame()
            t_sim = time.perf_counter()
            store.write_frame(record, sim.checkpoint_arrays())
            t_end = time.perf_counter()
            per_frame.append(t_sim - t)
            export_s.append(t_end - t_sim)
    return sim, per_frame, export_s, peak_rss_bytes(), rss_before, baseline


def bench_command(args) -> int:
    from fraytool.scene.overrides import parse_assignment

    spec = load_scene(args.scene, [parse_assignment(a) for a in getattr(args, "sets", None) or ()])
    _refuse_what_will_not_fit(spec)
    if getattr(args, "self_collision", None):
        spec = replace(spec, self_collision=replace(spec.self_collision, enabled=args.self_collision == "on"))
    frames = args.frames or DEFAULT_FRAMES
    result = bench_simulation(spec, frames)
    if args.render:
        from fraytool.commands.render_bench import render_stage_timings  # GL only when asked

        parts: dict[str, float] = {}
        video: dict[str, float] = {}
        result["render_stages_ms_per_frame"] = render_stage_timings(spec, frames=min(frames, 10), parts=parts,
                                                                    video=video)
        result["render_video_start_finish_ms"] = video["start_finish_ms"]
        result["render_encode_estimate"] = video["encode_estimate"]
        result["render_ms_per_frame"] = sum(result["render_stages_ms_per_frame"].values())
        result["render_draw_parts_ms_per_frame"] = parts
        result["render_resolution"] = list(spec.render.resolution)
        result["render_samples"] = spec.render.samples
        result["render_supersample"] = spec.render.supersample
    if args.json:
        print(json.dumps({k: v for k, v in result.items() if k != "summary"}))
        return 0
    out = sys.stdout
    print(f"scene {result['scene']}: {result['masses']} masses, {result['springs']} live springs (cut ones left out), "
          f"{frames} frames x {spec.time.steps_per_frame} steps", file=out)
    print(f"simulation: {result['ms_per_frame']:.2f} ms per frame (median); "
          f"compile/cache load {result['compile_s']:.2f} s (empty run: build and first frame, not in the median)", file=out)
    for name, ms in result["stages_ms_per_frame"].items():
        print(f"  {name:20s} {ms:8.2f} ms/frame (mean)", file=out)
    if result["kernels_compiled_in_timed_frames"]:
        print(f"  note: numba compiled {result['kernels_compiled_in_timed_frames']} kernel(s) during the first timed "
              "run (kernels first used after the first frame, numba's cache cold after a change), so the frames were "
              "timed again: these are the second run's figures", file=out)
    print(f"export: {result['export_ms_per_frame']:.2f} ms per frame (median; writing the frame record and "
          "checkpoint, not in the simulation figure)", file=out)
    print(f"memory: peak RSS {result['peak_rss_bytes'] / 2**20:.0f} MiB; "
          f"{result['bytes_per_crossing']:.0f} bytes per crossing over the RSS {result['memory_baseline']}", file=out)
    if "render_stages_ms_per_frame" in result:
        W, H = result["render_resolution"]
        print(f"render: {result['render_ms_per_frame']:.2f} ms per frame at {W}x{H}, "
              f"{result['render_samples']} MSAA samples" + (f", supersampled {result['render_supersample']}x"
                                                            if result.get("render_supersample", 1) > 1 else "")
              + " ([render] resolution, samples, supersample)", file=out)
        for name, ms in result["render_stages_ms_per_frame"].items():
            print(f"  {name:18s} {ms:8.2f} ms/frame", file=out)
            if name == "draw":
                for part, part_ms in result["render_draw_parts_ms_per_frame"].items():
                    print(f"    {part:16s} {part_ms:8.2f} ms/frame (timed apart, the queue finished around each)",
                          file=out)
        print(f"  once per video: {result['render_video_start_finish_ms']:.0f} ms (starting ffmpeg, flushing and "
              "closing the MP4; not in the per-frame figure)", file=out)
        if result["render_encode_estimate"] != "marginal":
            print("  note: encode is the whole video's average per frame (the timing noise exceeded the extra "
                  "frames' cost)", file=out)
    return 0


def _refuse_what_will_not_fit(spec) -> None:
    """As simulate: exit 2 with the estimate when the scene will not fit in the available memory."""
    from fraytool.errors import SceneError
    from fraytool.sim.memory import memory_problem

    problem = memory_problem(spec)
    if problem:
        raise SceneError([problem.replace(", or pass --force to try anyway", "")])
