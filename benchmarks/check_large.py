"""Benchmark: `fraytool check` and the memory estimate on large grids (issue 11, "size").

For drape resized to N x N (default 256, 1024; 4096 is refused on a machine with less than about
25 GiB available), prints the wall time of `fraytool check` in a fresh process, its exit code, and
the memory estimate next to the available memory. With --measure it also runs `fraytool simulate
--frames 3` under `/usr/bin/time -v` and prints the peak resident memory beside the estimate (the
estimate should stay above it).

Run: ``python benchmarks/check_large.py [N ...] [--measure]``
"""
from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def resized_drape(n: int, folder: Path) -> Path:
    text = (ROOT / "scenes" / "drape.toml").read_text()
    text = text.replace("warp_yarns = 30", f"warp_yarns = {n}").replace("weft_yarns = 30", f"weft_yarns = {n}")
    text = text.replace('name = "drape"', f'name = "drape_{n}"')
    path = folder / f"drape_{n}.toml"
    path.write_text(text)
    return path


def main(argv: list[str]) -> int:
    measure = "--measure" in argv
    sizes = [int(a) for a in argv if a.isdigit()] or [256, 1024]
    sys.path.insert(0, str(ROOT))
    from fraytool.scene import load_scene
    from fraytool.sim.memory import available_bytes, estimate_bytes, gib

    print(f"{'grid':>11s} {'check_s':>8s} {'exit':>4s} {'estimate':>10s} {'available':>10s} {'peak_rss':>10s}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            scene = resized_drape(n, Path(tmp))
            t = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "fraytool", "check", str(scene)], capture_output=True, text=True)
            check_s = time.perf_counter() - t
            peak = "-"
            if measure and r.returncode == 0:
                m = subprocess.run(["/usr/bin/time", "-v", sys.executable, "-m", "fraytool", "simulate", str(scene),
                                    "-o", str(Path(tmp) / f"out{n}"), "--frames", "3"], capture_output=True, text=True)
                found = re.search(r"Maximum resident set size \(kbytes\): (\d+)", m.stderr)
                peak = gib(int(found.group(1)) * 1024) if found else "?"
            spec = load_scene(str(scene))
            print(f"{n:>5d}x{n:<5d} {check_s:8.2f} {r.returncode:4d} {gib(estimate_bytes(spec)):>10s} "
                  f"{gib(available_bytes() or 0):>10s} {peak:>10s}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
