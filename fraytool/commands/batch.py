"""`fraytool batch SCENE_OR_JOB... [-o DIR] [--workers N | --scheduler ADDR] [--connect-timeout S] [--set K=V]
[--wedge K=V1,V2]`: many shots on Dask distributed (fraytool.farm, docs/farm.md). Exit 0 when every shot
is done, 1 when any failed or was invalid (job.json says which and why) or no worker connected within
--connect-timeout, 2 for bad flags or job files, or when no shot can run at all (checked before a
cluster starts)."""
from __future__ import annotations

import os
import re
import sys
from pathlib import Path

from fraytool.errors import InputError, RunError


def batch_command(args) -> int:
    from fraytool.farm.runner import local_client, remote_client, run_job
    from fraytool.farm.watch import FarmWatch
    from fraytool.farm.shots import Job, RenderOptions, check_job_name, check_render_options, expand, load_job, parse_wedge, unique_names
    from fraytool.render.motion_blur import parse_samples, parse_shutter
    from fraytool.render.options import check_supersample, parse_resolution
    from fraytool.scene.overrides import parse_assignment

    stream = sys.stderr
    sets = [parse_assignment(a) for a in args.sets]
    wedges = [parse_wedge(w) for w in args.wedges]
    render = RenderOptions(resolution=parse_resolution(args.resolution, need_even=True, no_mp4_hint=False)
                           if args.resolution else None,
                           samples=args.samples, wireframe=args.wireframe, frames=args.frames,
                           alpha=True if args.alpha else None, depth=args.depth, exr=True if args.exr else None,
                           codec=args.codec, fit=True if args.fit else None,
                           motion_blur=parse_shutter(args.motion_blur) if args.motion_blur is not None else None,
                           motion_samples=(parse_samples(args.motion_samples) if args.motion_samples is not None
                                           else None),
                           supersample=check_supersample(args.supersample))
    check_render_options(render, "batch", flags=True)
    if args.scheduler and args.workers:
        raise InputError("--workers starts a local cluster; with --scheduler the cluster's own workers run the job")
    job = None
    shots = []
    for item in args.inputs:
        path = Path(item)
        if path.suffix == ".toml" and path.is_file() and _is_job_file(path, item):
            loaded = load_job(path, sets, wedges, render, args.chunk_frames)
            job = job or loaded
            shots += loaded.shots
        else:
            shots += expand(item, sets, wedges, render)
    if not shots:
        raise InputError("batch: give scene files, shipped scene names or job files")
    name = job.name if job is not None and len(args.inputs) == 1 else "batch"
    check_job_name(name, "job name")
    job = Job(name=name, shots=shots, chunk_frames=args.chunk_frames or (job.chunk_frames if job else 24))
    unique_names(job.shots)
    job_dir = (Path(args.out) if args.out else Path("outputs") / name).absolute()  # workers may run elsewhere
    job = _checked(job, job_dir, stream)
    if args.scheduler:
        if not re.fullmatch(r"(tcp|tls|inproc|ucx)://[^\s:/]+(:\d{1,5})?", args.scheduler):
            raise InputError(f"--scheduler {args.scheduler[:200]!r}: expected an address like tcp://HOST:8786")
        try:
            client, cluster = remote_client(args.scheduler)
        except (OSError, ValueError) as exc:
            raise RunError(f"--scheduler {args.scheduler}: cannot reach the Dask scheduler ({exc}); start one "
                           "with `dask scheduler` and workers with `dask worker ADDRESS`") from None
    else:
        workers = args.workers or max(1, os.cpu_count() or 1)
        client, cluster = local_client(workers, stream)
    watch = None
    try:
        print(f"fraytool: batch: {len(job.shots)} shot(s) on {len(client.scheduler_info()['workers'])} worker(s); "
              f"Dask dashboard: {client.dashboard_link}", file=stream)
        watch = FarmWatch(client, stream, connect_timeout_s=args.connect_timeout, local=cluster is not None)
        if args.golden_check or args.golden_update:
            return _golden_batch(job, job_dir, client, args, stream, watch)
        data = run_job(job, job_dir, client, stream, contact_sheets=not args.no_contact_sheet, watch=watch)
    finally:
        if watch is not None:
            watch.close()
        client.close()
        if cluster is not None:
            cluster.close()
    bad = {n: e for n, e in data["shots"].items() if e.get("status") != "done" and n in {s.name for s in job.shots}}
    for n, e in bad.items():
        print(f"fraytool: batch: {n}: {e.get('status')}: {str(e.get('error', '')).splitlines()[0] if e.get('error') else ''}",
              file=stream)
    print(f"fraytool: batch: {len(job.shots) - len(bad)} of {len(job.shots)} shot(s) done; {job_dir / 'job.json'}",
          file=stream)
    return 0 if not bad else 1


def _golden_batch(job, job_dir: Path, client, args, stream, watch) -> int:
    """--golden-check DIR / --golden-update DIR: every valid shot checked (or its golden made) as a task on the
    cluster, in parallel; one report for all (job_dir/golden-report/: report.html, summary.json; --junit).
    `watch` (farm.watch.FarmWatch) says lost workers, retries and a cluster without workers."""
    from fraytool.farm.tasks import run_attempt
    from fraytool.golden.compare import FAIL, WARN
    from fraytool.golden.report import Report
    from fraytool.golden.run import farm_task

    update = bool(args.golden_update)
    golden_dir = str(Path(args.golden_update or args.golden_check).absolute())
    report = Report(None if update else job_dir / "golden-report")
    work = str(job_dir / "golden-work")
    futures = {client.submit(run_attempt, f"golden-{shot.name}", farm_task, shot.scene, shot.sets, golden_dir, work,
                             str(job_dir / "golden-report"), update, key=f"golden-{shot.name}", pure=False): shot
               for shot in job.shots if shot.error is None}
    watch.labels.update({f"golden-{s.name}": f"{s.name} golden {'update' if update else 'check'}" for s in job.shots})
    errors = [f"{s.name}: {_reason(s)}" for s in job.shots if s.error is not None]
    for fut in watch.completed(futures):
        entry = fut.result()
        watch.finished(fut.key, result=entry)  # takes out run_attempt's "attempt" entry
        shot = futures[fut]
        if "error" in entry:
            errors.append(f"{shot.name}: {entry['error']}")
            continue
        if update:
            print(f"fraytool: batch: golden of {entry['scene']} made in {golden_dir}/{entry['scene']}/", file=stream)
            continue
        report.scenes.append(entry)
        states = [f["status"] for f in entry["frames"]]
        print(f"fraytool: batch: golden {entry['scene']}: " + ", ".join(f"frame {f['frame']} {f['status']}"
                                                                       for f in entry["frames"]), file=stream)
        for f in entry["frames"]:
            for reason in f["reasons"]:
                if ": fail: " in reason or FAIL not in states:
                    print(f"fraytool:   {entry['scene']}: {reason}", file=stream)
    for e in errors:
        print(f"fraytool: batch: {e}", file=stream)
    if update:
        return 1 if errors else 0
    report.scenes.sort(key=lambda e: e["scene"])
    report.write(args.junit)
    status = report.status
    print(f"fraytool: batch: golden check of {len(report.scenes)} shot(s): {status}; report: "
          f"{job_dir / 'golden-report' / 'report.html'}" + (" (warnings above)" if status == WARN else ""), file=stream)
    return 1 if status == FAIL or errors else 0


def _checked(job, job_dir: Path, stream):
    """The job with every shot's scene, overrides and frame range checked here, before a cluster
    starts: a bad shot is marked invalid (reported in job.json, the others run); when no shot can
    run at all (a bad --set, --frames or --wedge applies to every shot, or no scene exists) this is
    bad input: each reason on one line (one shot: that line alone), then exit 2 without starting a
    cluster or writing anything."""
    from dataclasses import replace

    from fraytool.errors import FraytoolError
    from fraytool.farm import tasks

    from fraytool.render.options import FrameRange
    from fraytool.render.renderer import check_drawn_size_early

    limit = None  # the GL context's widest side, probed once
    shots = []
    for shot in job.shots:
        if shot.error is None:
            try:
                render_job, _ = tasks.render_job_for(shot, job_dir / shot.name, FrameRange(0, 1))
                limit = check_drawn_size_early(render_job.size, render_job.spec.render.supersample,
                                               render_job.wireframe, render_job.spec.source, limit)
            except FraytoolError as exc:
                shot = replace(shot, error=str(exc))
        shots.append(shot)
    if all(s.error for s in shots):
        reasons = [_reason(s) for s in shots]
        if len(reasons) == 1:
            raise InputError(f"batch: {reasons[0]}")
        for reason in reasons:
            print(f"fraytool: batch: {reason}", file=stream)
        raise InputError(f"batch: none of the {len(shots)} shot(s) can run (the reasons are above)")
    return replace(job, shots=shots)


def _reason(shot) -> str:
    """Why a shot cannot run, on one line, naming the shot unless the message already starts with it."""
    first = str(shot.error).splitlines()[0]
    return first if first.startswith((shot.name, shot.scene)) else f"{shot.name}: {first}"


def _is_job_file(path: Path, item: str) -> bool:
    """A job file has [job] or [[shots]]; a TOML file that does not parse is neither (exit 2)."""
    import tomllib

    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{item}: cannot read: {exc}") from None
    except (ValueError, RecursionError) as exc:
        raise InputError(f"{item}: not valid TOML (neither a scene nor a job file): {str(exc).splitlines()[0][:200]}") from None
    if "shot" in doc or "shots" in doc and not isinstance(doc["shots"], list):
        raise InputError(f"{item}: a job file lists its shots as [[shots]] tables")
    return "shots" in doc or "job" in doc
