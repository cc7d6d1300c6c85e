"""Reports of a golden check (docs/golden.md): per frame the reference, the new image and their difference
(8-bit PNGs for the browser), report.html (side by side, a hover or click swap, the figures, pass / warn
/ fail per frame, the settings that differ from the golden's metadata), summary.json and JUnit XML."""
from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Optional
from xml.etree import ElementTree as ET

import numpy as np

from fraytool.golden.compare import FAIL, PASS, WARN

DIFF_GAIN_OF_FAIL = 1.0
"""The difference image maps a channel difference of `fail` (the scene's threshold) to full white."""


def to8(image16: np.ndarray) -> np.ndarray:
    return np.round(image16.astype(np.float64) / 257.0).astype(np.uint8)


def diff_image(golden16: np.ndarray, new16: np.ndarray, fail: float) -> np.ndarray:
    """|golden - new| (largest channel), scaled so that `fail` is white: grey 8-bit, shape (H, W)."""
    if golden16.shape != new16.shape:
        return np.full((8, 8), 255, np.uint8)
    d = np.abs(golden16.astype(np.float64) - new16.astype(np.float64)).max(axis=-1) / 65535.0
    return np.clip(d / max(fail, 1e-6) * 255.0 * DIFF_GAIN_OF_FAIL, 0, 255).astype(np.uint8)


class Report:
    """Collects the verdicts of every scene and frame of one check and writes the reports."""

    def __init__(self, out: Optional[Path]):
        self.out = Path(out) if out else None
        self.scenes: list[dict] = []

    def add(self, scene: str, golden_dir: Path, verdicts: list, images: dict, differences: list[str],
            fail: float) -> None:
        """`images`: frame -> (golden uint16, new uint16)."""
        entry = {"scene": scene, "golden": str(golden_dir), "settings_differ": differences, "frames": []}
        for v in verdicts:
            row = {"frame": v.frame, "status": v.status, "figures": v.figures, "reasons": v.reasons}
            if self.out is not None:
                from PIL import Image

                folder = self.out / scene
                folder.mkdir(parents=True, exist_ok=True)
                g, n = images[v.frame]
                names = {k: f"{k}_{v.frame:06d}.png" for k in ("reference", "new", "diff")}
                Image.fromarray(to8(g)).save(folder / names["reference"])
                Image.fromarray(to8(n)).save(folder / names["new"])
                Image.fromarray(diff_image(g, n, fail)).save(folder / names["diff"])
                row["images"] = {k: f"{scene}/{name}" for k, name in names.items()}
            entry["frames"].append(row)
        self.scenes.append(entry)

    @property
    def status(self) -> str:
        states = [f["status"] for s in self.scenes for f in s["frames"]]
        return FAIL if FAIL in states else WARN if WARN in states else PASS

    def summary(self) -> dict:
        return {"status": self.status, "scenes": self.scenes}

    def write(self, junit: Optional[Path] = None) -> None:
        if self.out is not None:
            self.out.mkdir(parents=True, exist_ok=True)
            (self.out / "summary.json").write_text(json.dumps(self.summary(), indent=2, default=float) + "\n")
            (self.out / "report.html").write_text(self.html())
        if junit is not None:
            Path(junit).parent.mkdir(parents=True, exist_ok=True)
            Path(junit).write_text(self.junit())

    def junit(self) -> str:
        """JUnit XML: one testsuite, a testcase per scene frame; a failure for FAIL, system-out for warnings."""
        cases = [(s, f) for s in self.scenes for f in s["frames"]]
        suite = ET.Element("testsuite", name="fraytool golden", tests=str(len(cases)),
                           failures=str(sum(f["status"] == FAIL for _, f in cases)), errors="0", skipped="0")
        for s, f in cases:
            case = ET.SubElement(suite, "testcase", classname=f"golden.{s['scene']}", name=f"frame_{f['frame']:06d}")
            if f["status"] == FAIL:
                failure = ET.SubElement(case, "failure", message=f["reasons"][0] if f["reasons"] else "failed")
                failure.text = "\n".join(f["reasons"])
            elif f["status"] == WARN:
                ET.SubElement(case, "system-out").text = "\n".join(f["reasons"])
        return ET.tostring(ET.ElementTree(suite).getroot(), encoding="unicode", xml_declaration=True) + "\n"

    def html(self) -> str:
        e = html.escape
        parts = [PAGE_HEAD.replace("{status}", e(self.status))]
        for s in self.scenes:
            parts.append(f"<h2>{e(s['scene'])}</h2><p class='where'>golden: {e(s['golden'])}</p>")
            if s["settings_differ"]:
                parts.append("<details open><summary>settings that differ from the golden's</summary><ul>"
                             + "".join(f"<li>{e(d)}</li>" for d in s["settings_differ"]) + "</ul></details>")
            for f in s["frames"]:
                figs = "".join(f"<tr><td>{e(k)}</td><td>{e(_fmt(v))}</td></tr>" for k, v in f["figures"].items())
                reasons = "".join(f"<li>{e(r)}</li>" for r in f["reasons"])
                imgs = ""
                if "images" in f:
                    ref, new, diff = (e(f["images"][k]) for k in ("reference", "new", "diff"))
                    imgs = (f"<div class='row'><figure><img src='{ref}' alt='reference'><figcaption>reference</figcaption>"
                            f"</figure><figure><img src='{new}' alt='new'><figcaption>new</figcaption></figure>"
                            f"<figure><img src='{diff}' alt='difference'><figcaption>difference (white: fail "
                            f"threshold)</figcaption></figure><figure class='swap'><img class='swap' src='{ref}' "
                            f"data-reference='{ref}' data-new='{new}' alt='swap'><figcaption>hover or click: "
                            f"reference / new</figcaption></figure></div>")
                parts.append(f"<section class='frame {f['status']}' data-status='{f['status']}'><h3>frame {f['frame']}"
                             f" <span class='badge'>{f['status']}</span></h3>{imgs}<ul>{reasons}</ul>"
                             f"<table>{figs}</table></section>")
        parts.append(PAGE_TAIL)
        return "\n".join(parts)


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return json.dumps(v) if isinstance(v, (list, dict)) else str(v)


PAGE_HEAD = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>fraytool golden check: {status}</title>
<style>
body { font: 14px sans-serif; margin: 1em 2em; background: #fafafa; }
.row { display: flex; gap: 8px; flex-wrap: wrap; }
figure { margin: 0; } figure img { max-width: 400px; border: 1px solid #ccc; display: block; }
figcaption { font-size: 12px; color: #555; }
section.frame { border-left: 6px solid #2a2; padding: 4px 12px; margin: 12px 0; background: #fff; }
section.warn { border-color: #d90; } section.fail { border-color: #d22; }
.badge { font-size: 12px; text-transform: uppercase; }
table td { padding: 0 12px 0 0; font-family: monospace; }
img.swap { cursor: pointer; }
</style></head>
<body data-status="{status}"><h1>fraytool golden check: {status}</h1>"""

PAGE_TAIL = """<script>
// Swap: a hover (or a click) shows the new image in place of the reference.
function show(img, which) { img.src = img.dataset[which]; img.dataset.showing = which; }
for (const img of document.querySelectorAll('img.swap')) {
  img.dataset.showing = 'reference';
  img.addEventListener('mouseenter', () => show(img, 'new'));
  img.addEventListener('mouseleave', () => show(img, 'reference'));
  img.addEventListener('click', () => show(img, img.dataset.showing === 'new' ? 'reference' : 'new'));
}
// Self-check for automated runs (tests load the page in a headless browser and read these back).
window.addEventListener('load', () => {
  const imgs = [...document.images];
  const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;
  document.body.dataset.imagesTotal = imgs.length;
  document.body.dataset.imagesLoaded = ok;
  const first = document.querySelector('img.swap');
  if (first) {
    const before = first.getAttribute('src');
    first.dispatchEvent(new MouseEvent('mouseenter'));
    const during = first.getAttribute('src');
    first.dispatchEvent(new MouseEvent('mouseleave'));
    const after = first.getAttribute('src');
    document.body.dataset.swapWorks = String(during === first.dataset.new && before === after && before !== during);
  }
});
</script></body></html>
"""
