"""`fraytool golden update` and `fraytool golden check` (docs/golden.md)."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Optional, TextIO

from fraytool.golden.compare import FAIL, WARN
from fraytool.golden.report import Report
from fraytool.golden.run import (check_scene, load_for_check, load_for_golden, parse_frames, update_command_line,
                                 update_scene)


def golden_command(args, stream: Optional[TextIO] = None) -> int:
    stream = stream or sys.stderr
    if args.action == "update":
        specs = [(scene, load_for_golden(scene, args.sets)) for scene in args.scenes]  # all checked before any work
        for scene, spec in specs:
            frames = parse_frames(args.frames, spec)
            out = update_scene(spec, args.dir, frames, args.sets, args.work, stream)
            print(f"fraytool: golden of {spec.name}: frames {', '.join(map(str, frames))} in {out}/", file=stream)
        return 0
    checks = [(scene, *load_for_check(scene, args.dir, args.sets)) for scene in args.scenes]
    report = Report(args.report)
    for scene, spec, sets in checks:
        frames = parse_frames(args.frames, spec) if args.frames else None
        result = check_scene(spec, args.dir, frames, update_command_line(scene, args.dir, sets), sets,
                             args.work, stream)
        report.add(spec.name, result.golden_dir, result.verdicts, result.images, result.differences,
                   spec.golden.fail)
        for v in result.verdicts:
            figures = (f" (SSIM {v.figures['ssim']:.4f}, {v.figures['fail_percent']:.3f} % over fail)"
                       if "ssim" in v.figures else "")
            print(f"fraytool: golden {spec.name} frame {v.frame}: {v.status}{figures}", file=stream)
            for reason in v.reasons:
                print(f"fraytool:   {reason}", file=stream)
        for d in result.differences:
            print(f"fraytool:   {spec.name}: differs from the golden's metadata: {d}", file=stream)
    report.write(args.junit)
    if args.report:
        print(f"fraytool: report: {Path(args.report) / 'report.html'}", file=stream)
    status = report.status
    print(f"fraytool: golden check: {status}" + (" (warnings above)" if status == WARN else ""), file=stream)
    return 1 if status == FAIL else 0
