"""A contact sheet: the variants of a wedge side by side in one MP4, each tile labelled with its
value (e.g. "seed=3") in text sized to the tile, frame by frame from their PNG sequences; and PNG stills
of its first, middle and last frame (<wedge>_contact_sheet_NNNNNN.png)."""
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


LABEL_FRACTION = 0.06
"""Height of a tile's label text as a fraction of the tile's height (at least LABEL_MIN_PX)."""
LABEL_MIN_PX = 14
SHEET_BACKGROUND = (40, 40, 44)
"""Behind a last row that does not fill the grid (centred): a neutral grey, never a black 'tile'."""


def label_font(tile_height: int):
    """A scalable font sized to the tile (Pillow's bundled one), so labels stay readable at any size."""
    size = max(LABEL_MIN_PX, int(round(LABEL_FRACTION * tile_height)))
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: the fixed bitmap font
        return ImageFont.load_default()


def compose(images: list[np.ndarray], labels: list[str], tile: tuple[int, int], grid: tuple[int, int]) -> np.ndarray:
    """The sheet (H, W, 3) uint8: images scaled to `tile`, placed row by row, labels in their corner; a
    last row with fewer tiles is centred on a grey ground (no empty tile)."""
    tw, th = tile
    cols, rows = grid
    sheet = Image.new("RGB", (cols * tw, rows * th), SHEET_BACKGROUND)
    draw = ImageDraw.Draw(sheet)
    font = label_font(th)
    pad = max(3, th // 60)
    last_row = len(images) - (rows - 1) * cols
    for k, (img, label) in enumerate(zip(images, labels)):
        row, col = k // cols, k % cols
        shift = (cols - last_row) * tw // 2 if row == rows - 1 else 0
        x, y = col * tw + shift, row * th
        sheet.paste(Image.fromarray(img).resize((tw, th), Image.Resampling.BILINEAR), (x, y))
        box = draw.textbbox((x + 2 * pad, y + pad), label, font=font)
        draw.rectangle((box[0] - pad, box[1] - pad, box[2] + pad, box[3] + pad), fill=(0, 0, 0))
        draw.text((x + 2 * pad, y + pad), label, fill=(255, 255, 255), font=font)
    return np.asarray(sheet)


def _opaque(image: np.ndarray, background_srgb) -> np.ndarray:
    """A shot's PNG as an opaque tile: with alpha (--alpha, ProRes), over its scene's background."""
    if image.shape[-1] == 4:
        from fraytool.render.color import over_background

        return over_background(image, background_srgb)
    return image


def write_contact_sheet(shots: list[Shot], job_dir: Path, name: str) -> Path:
    from fraytool.farm.tasks import render_job_for
    from fraytool.render.encode import VideoWriter, read_png, write_png
    from fraytool.render.options import FrameRange

    jobs = [render_job_for(s, job_dir / s.name, FrameRange(0, 1))[0] for s in shots]
    grid = tile_grid(len(jobs))
    w, h = jobs[0].size
    scale = min(1.0, MAX_SHEET[0] / (grid[0] * w), MAX_SHEET[1] / (grid[1] * h))  # full-size tiles up to 4K
    tile = (max(2, int(w * scale) // 2 * 2), max(2, int(h * scale) // 2 * 2))
    frames = min(len(j.frames) for j in jobs)
    path = job_dir / f"{name}_contact_sheet.mp4"
    stills = still_indices(frames)
    with VideoWriter(path, (tile[0] * grid[0], tile[1] * grid[1]), jobs[0].spec.time.fps) as writer:
        for i in range(frames):
            images = [_opaque(read_png(j.png_path(j.frames.frames()[i])), j.spec.render.background) for j in jobs]
            sheet = compose(images, [s.label for s in shots], tile, grid)
            writer.write(sheet)
            if i in stills:
                frame = jobs[0].frames.frames()[i]
                write_png(still_path(job_dir, name, frame), sheet)
    return path


def still_indices(frames: int) -> set[int]:
    """The first, middle and last of `frames` sheets, written as PNG stills too."""
    return {0, (frames - 1) // 2, frames - 1}


def still_path(job_dir: Path, name: str, frame: int) -> Path:
    return Path(job_dir) / f"{name}_contact_sheet_{frame:06d}.png"


def contact_sheet_task(shots: list[Shot], job_dir: str, name: str, _after=None) -> dict:
    """Farm task: the wedge's contact sheet, once its shots are joined (`_after`)."""
    from fraytool.farm.tasks import task_info

    t0 = time.time()
    path = write_contact_sheet(shots, Path(job_dir), name)
    return {"task": "contact sheet", "mp4": str(path), **task_info(t0)}
