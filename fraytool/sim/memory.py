"""Memory a scene will need, estimated from the scene before anything is allocated, and what the
machine has (issue 11: refuse what will not fit, with the estimate).

The per-crossing figures are peak resident memory measured with `/usr/bin/time -v fraytool simulate
SCENE --frames 3` on grids resized from the shipped scenes (this machine, numpy 2, numba 0.60):
    drape 128^2 -> 256^2 (base model only):            about 1.05 KB more per crossing
    fig7 128^2 -> 256^2 (tearing, self-collision on):  about 2.0 KB more per crossing
and about 180 MB for the interpreter, numpy, numba and the compiled kernels. The estimate adds half
again to the per-crossing figures (torn regions grow: yarn-level masses, self-collision candidates).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Optional

from fraytool.scene.spec import SceneSpec

BASE_BYTES = 250 * 2**20
"""Interpreter, numpy, numba and compiled kernels (measured about 180 MB), with margin."""
BYTES_PER_CROSSING = 1600
"""Base model: Model + State + solver scratch (measured about 1050 B), with margin."""
TEARING_BYTES_PER_CROSSING = 1400
"""Extra for tearing at yarn level and self-collision (measured about 950 B more), with margin."""


BYTES_PER_STITCH = 200
"""A stitch's spring slot in the Model and State (about a structural spring's), with margin."""
BYTES_PER_STITCH_CANDIDATE = 64
"""Placing the stitches (fraytool.sim.seam_layout.stitch_pairs) measures every stitch point against every
crossing beside its edge: three float64 (N, C, 2) temporaries and their norms, per point and candidate."""


def estimate_bytes(spec: SceneSpec) -> int:
    """Peak resident memory [bytes] a simulation of `spec` is expected to need: every panel's crossings, the
    seams' stitches (and placing them) and the mesh bodies."""
    crossings = sum(crossing_count(panel, spec.source_file) for panel in spec.all_panels)
    per = BYTES_PER_CROSSING
    if spec.cloth.tearing.enabled or spec.self_collision.enabled:
        per += TEARING_BYTES_PER_CROSSING
    return BASE_BYTES + crossings * per + mesh_bytes(spec) + sum(seam_bytes(spec).values())


def seam_bytes(spec: SceneSpec) -> dict[int, int]:
    """Memory each [[seams]] entry needs [bytes]: its stitches (the edge's length over stitch_spacing_m) and
    placing them (each stitch point against the crossings beside the edge)."""
    from fraytool.sim.seam_layout import SEAM_REACH_SPACINGS

    out = {}
    names = [p.name for p in spec.all_panels]
    for k, seam in enumerate(spec.seams):
        if seam.panel_a not in names:
            continue  # loading says so
        length_m = _edge_length_m(spec.all_panels[names.index(seam.panel_a)], seam.segment_a)
        spacing_m = spec.cloth.spacing_m
        stitches = length_m / max(seam.stitch_spacing_m, 1e-300) + 1.0
        beside = (length_m / spacing_m + 1.0) * (2.0 * SEAM_REACH_SPACINGS + 1.0)
        out[k] = int(min(stitches * (BYTES_PER_STITCH + BYTES_PER_STITCH_CANDIDATE * beside), 2.0**62))
    return out


def _edge_length_m(cloth, segment: int) -> float:
    """Length [m] of a panel's outline segment (a rectangle's corners, outline_m or the mask's rectangle)."""
    if cloth.outline_m:
        corners = [tuple(p) for p in cloth.outline_m]
    else:
        w, h = (cloth.mask_size_m if cloth.mask else
                ((cloth.warp_yarns - 1) * cloth.spacing_m, (cloth.weft_yarns - 1) * cloth.spacing_m))
        corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
    if not corners:
        return 0.0
    a, b = corners[segment % len(corners)], corners[(segment + 1) % len(corners)]
    return float(((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5)


def crossing_count(cloth, scene_file: str = "") -> int:
    """Crossings the cloth builds: warp_yarns x weft_yarns, or those inside a shaped panel (0 when its
    shape has problems, which loading reports)."""
    if not cloth.outline_m and not cloth.mask:
        return cloth.warp_yarns * cloth.weft_yarns
    from fraytool.scene.panel_shape import PanelShapeError, panel_shape

    try:
        return int(panel_shape(cloth, scene_file).present.sum())
    except PanelShapeError:
        return 0


def mesh_bytes(spec: SceneSpec) -> int:
    """Memory the mesh bodies will need [bytes], from their files' sizes (mesh_files.BYTES_PER_FILE_BYTE)."""
    from fraytool.scene.mesh_files import BYTES_PER_FILE_BYTE, file_bytes

    return sum(file_bytes(b.file, spec.source_file) * BYTES_PER_FILE_BYTE for b in spec.bodies if b.shape == "mesh")


def available_bytes() -> Optional[int]:
    """Memory this process may still use [bytes]: the smaller of /proc/meminfo's MemAvailable and a
    cgroup v2 limit's headroom; None where neither can be read."""
    found = []
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                found.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    cg = Path("/sys/fs/cgroup")
    try:
        limit = (cg / "memory.max").read_text().strip()
        if limit != "max":
            found.append(int(limit) - int((cg / "memory.current").read_text().strip()))
    except (OSError, ValueError):
        pass
    override = os.environ.get("FRAYTOOL_AVAILABLE_MEMORY_BYTES")  # for tests and for users who know better
    if override:
        try:
            found.append(int(override))
        except ValueError:
            pass
    return min(found) if found else None


def gib(n: float) -> str:
    return f"{n / 2**30:.2f} GiB" if n >= 2**30 else f"{n / 2**20:.0f} MiB"


def memory_problem(spec: SceneSpec) -> Optional[str]:
    """A one-line refusal if the estimate does not fit in the available memory, else None."""
    need, have = estimate_bytes(spec), available_bytes()
    if have is None or need <= have:
        return None
    c = spec.cloth
    meshes = mesh_bytes(spec)
    seams = seam_bytes(spec)
    if seams and max(seams.values()) > need // 2:
        k = max(seams, key=seams.get)
        return (f"{spec.source}: [seams.{k}] stitch_spacing_m = {spec.seams[k].stitch_spacing_m:g}: its stitches need "
                f"about {gib(seams[k])} and the whole simulation about {gib(need)}; this machine has {gib(have)} "
                "available; space the stitches further apart (about the yarn spacing), or pass --force to try anyway")
    if meshes > need // 2:
        return (f"{spec.source}: [bodies] mesh files: the meshes need about {gib(meshes)} and the whole simulation "
                f"about {gib(need)}; this machine has {gib(have)} available; use a coarser mesh, "
                "or pass --force to try anyway")
    if len(spec.all_panels) > 1:
        sizes = [crossing_count(p, spec.source_file) for p in spec.all_panels]
        big = max(range(len(sizes)), key=sizes.__getitem__)
        return (f"{spec.source}: [cloth.{big}] ({spec.all_panels[big].name or 'the panel'}, {sizes[big]} crossings of "
                f"{sum(sizes)} in {len(sizes)} panels): the simulation needs about {gib(need)} and this machine has "
                f"{gib(have)} available; use smaller panels, or pass --force to try anyway")
    return (f"{spec.source}: [cloth] warp_yarns x weft_yarns = {c.warp_yarns} x {c.weft_yarns}: the simulation needs "
            f"about {gib(need)} and this machine has {gib(have)} available; use a smaller grid, "
            "or pass --force to try anyway")


def admission_problems(spec: SceneSpec, force: bool) -> list[str]:
    """Why a loaded scene cannot run here, one line each: the memory estimate (unless `force`), then the
    mesh bodies' contents (read once the estimate allows it; the reading is cached for the build)."""
    if not force:
        problem = memory_problem(spec)
        if problem:
            return [problem]
    from fraytool.scene.mesh_files import asset_problems

    return asset_problems(spec)
