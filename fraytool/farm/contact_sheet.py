"""A contact sheet: the variants of a wedge side by side in one MP4, each tile labelled with its
value (e.g. "seed=3"), frame by frame from their PNG sequences."""
from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from fraytool.farm.shots import Shot

MAX_SHEET = (3840, 2160)
"""Largest contact sheet [px]; tiles keep the shots' own size below it."""


def tile_grid(count: int) -> tuple[int, int]:
    """(columns, rows) for `count` tiles, as square as possible, wider than tall."""
    cols = math.ceil(math.sqrt(count))
    return cols, math.ceil(count / cols)


def compose(images: list[np.ndarray], labels: list[str], tile: tuple[int, int], grid: tuple[int, int]) -> np.ndarray:
    """The sheet (H, W, 3) uint8: images scaled to `tile`, placed row by row, labels in their corner."""
    tw, th = tile
    cols, rows = grid
    sheet = Image.new("RGB", (cols * tw, rows * th), (0, 0, 0))
    draw = ImageDraw.Draw(sheet)
    font = ImageFont.load_default()
    for k, (img, label) in enumerate(zip(images, labels)):
        x, y = (k % cols) * tw, (k // cols) * th
        sheet.paste(Image.fromarray(img).resize((tw, th), Image.Resampling.BILINEAR), (x, y))
        box = draw.textbbox((x + 4, y + 3), label, font=font)
        draw.rectangle((box[0] - 3, box[1] - 2, box[2] + 3, box[3] + 2), fill=(0, 0, 0))
        draw.text((x + 4, y + 3), label, fill=(255, 255, 255), font=font)
    return np.asarray(sheet)


def _opaque(image: np.ndarray, background_srgb) -> np.ndarray:
    """A shot's PNG as an opaque tile: with alpha (--alpha, ProRes), over its scene's background."""
    if image.shape[-1] == 4:
        from fraytool.render.color import over_background

        return over_background(image, background_srgb)
    return image


def write_contact_sheet(shots: list[Shot], job_dir: Path, name: str) -> Path:
    from fraytool.farm.tasks import render_job_for
    from fraytool.render.encode import VideoWriter, read_png
    from fraytool.render.options import FrameRange

    jobs = [render_job_for(s, job_dir / s.name, FrameRange(0, 1))[0] for s in shots]
    grid = tile_grid(len(jobs))
    w, h = jobs[0].size
    scale = min(1.0, MAX_SHEET[0] / (grid[0] * w), MAX_SHEET[1] / (grid[1] * h))  # full-size tiles up to 4K
    tile = (max(2, int(w * scale) // 2 * 2), max(2, int(h * scale) // 2 * 2))
    frames = min(len(j.frames) for j in jobs)
    path = job_dir / f"{name}_contact_sheet.mp4"
    with VideoWriter(path, (tile[0] * grid[0], tile[1] * grid[1]), jobs[0].spec.time.fps) as writer:
        for i in range(frames):
            images = [_opaque(read_png(j.png_path(j.frames.frames()[i])), j.spec.render.background) for j in jobs]
            writer.write(compose(images, [s.label for s in shots], tile, grid))
    return path


def contact_sheet_task(shots: list[Shot], job_dir: str, name: str, _after=None) -> dict:
    """Farm task: the wedge's contact sheet, once its shots are joined (`_after`)."""
    from fraytool.farm.tasks import task_info

    t0 = time.time()
    path = write_contact_sheet(shots, Path(job_dir), name)
    return {"task": "contact sheet", "mp4": str(path), **task_info(t0)}
