"""Reports of a golden check (docs/golden.md): per frame the reference, the new image and their difference
(8-bit PNGs for the browser), report.html (a summary first, the failures at the top, the scene keys that
differ from the golden's by key and value, the images side by side and full size on a click, a ring where the
yarns moved most, a hover or click swap, the figures, pass / warn / fail per frame), summary.json and JUnit
XML."""
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
                row["image_size"] = [int(n.shape[1]), int(n.shape[0])]
            entry["frames"].append(row)
        self.scenes.append(entry)

    @property
    def status(self) -> str:
        states = [f["status"] for s in self.scenes for f in s["frames"]]
        return FAIL if FAIL in states else WARN if WARN in states else PASS

    def summary(self) -> dict:
        return {"status": self.status, "scenes": self.scenes,
                "overview": [scene_overview(s) for s in _by_severity(self.scenes)]}

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
        """The page a reviewer scans: a summary first (per scene its frames, verdict and the worst figure of each
        kind), then the failing and warning frames linked, then every scene with its failing frames first: the
        scene keys that differ from the golden's by key and value, the images large and full size on a click,
        and where the yarns moved most marked on the new image and the difference."""
        e = html.escape
        scenes = _by_severity(self.scenes)
        parts = [PAGE_HEAD.replace("{status}", e(self.status)), _summary_table(scenes), _problem_list(scenes)]
        for s in scenes:
            parts.append(f"<h2 id='{_anchor(s['scene'])}'>{e(s['scene'])}</h2><p class='where'>golden: {e(s['golden'])}</p>")
            if s["settings_differ"]:
                parts.append("<details open><summary>what differs from the golden (golden -> now)</summary><ul "
                             "class='differ'>" + "".join(f"<li>{e(d)}</li>" for d in s["settings_differ"])
                             + "</ul></details>")
            for f in _frames_by_severity(s["frames"]):
                parts.append(_frame_section(s["scene"], f))
        parts.append(PAGE_TAIL)
        return "\n".join(parts)


WORST = {"max_error": max, "fail_percent": max, "warn_percent": max, "rms_error": max, "mean_error": max,
         "max_yarn_distance_thickness": max, "ssim": min, "psnr_db": min}
"""The worst of each figure over a scene's frames: the largest error, the smallest similarity."""
SEVERITY = {FAIL: 0, WARN: 1, PASS: 2}


def scene_overview(scene: dict) -> dict:
    """A scene's line of the summary: frames, how many of each verdict, its verdict, the worst figures."""
    frames = scene.get("frames", [])
    counts = {k: sum(f["status"] == k for f in frames) for k in (FAIL, WARN, PASS)}
    status = FAIL if counts[FAIL] or "error" in scene else WARN if counts[WARN] else PASS
    worst = {}
    for name, pick in WORST.items():
        values = [f["figures"][name] for f in frames if isinstance(f["figures"].get(name), (int, float))]
        if values:
            worst[name] = pick(values)
    torn = [abs(f["figures"]["torn_springs"] - f["figures"]["golden_torn_springs"]) for f in frames
            if "torn_springs" in f["figures"] and "golden_torn_springs" in f["figures"]]
    if torn:
        worst["torn_springs_difference"] = max(torn)
    return {"scene": scene["scene"], "status": status, "frames": len(frames), "counts": counts, "worst": worst}


def _by_severity(scenes: list[dict]) -> list[dict]:
    return sorted(scenes, key=lambda s: SEVERITY[scene_overview(s)["status"]])  # stable: the given order within


def _frames_by_severity(frames: list[dict]) -> list[dict]:
    return sorted(frames, key=lambda f: (SEVERITY.get(f["status"], 0), f["frame"]))


def _anchor(scene: str, frame: Optional[int] = None) -> str:
    safe = "".join(c if c.isalnum() else "-" for c in scene)
    return f"s-{safe}" if frame is None else f"s-{safe}-f{frame}"


def _summary_table(scenes: list[dict]) -> str:
    e = html.escape
    rows = []
    for s in scenes:
        o = scene_overview(s)
        worst = ", ".join(f"{k} {_fmt(v)}" for k, v in o["worst"].items())
        c = o["counts"]
        rows.append(f"<tr class='{o['status']}'><td><a href='#{_anchor(s['scene'])}'>{e(s['scene'])}</a></td>"
                    f"<td class='badge'>{o['status']}</td><td>{o['frames']}</td><td>{c[FAIL]} fail, {c[WARN]} warn, "
                    f"{c[PASS]} pass</td><td class='worst'>{e(worst)}</td></tr>")
    return ("<table id='summary'><tr><th>scene</th><th>verdict</th><th>frames</th><th>by frame</th>"
            "<th>worst figures (largest error, smallest SSIM / PSNR)</th></tr>" + "".join(rows) + "</table>")


def _problem_list(scenes: list[dict]) -> str:
    e = html.escape
    items = [f"<li class='{f['status']}'><a href='#{_anchor(s['scene'], f['frame'])}'>{e(s['scene'])} frame "
             f"{f['frame']}</a> ({len(f['reasons'])} reason{'' if len(f['reasons']) == 1 else 's'}): "
             f"{e(f['reasons'][0] if f['reasons'] else f['status'])}</li>"
             for s in scenes for f in _frames_by_severity(s["frames"]) if f["status"] != PASS]
    if not items:
        return "<p id='problems'>Every frame passes.</p>"
    return "<h2>Failures and warnings</h2><ul id='problems'>" + "".join(items) + "</ul>"


def _marked(src: str, alt: str, caption: str, pixel, size) -> str:
    """A figure: the image at a readable size, full size on a click (a link), with a ring where the yarns
    moved most (`pixel` of an image of `size` (W, H)) when given."""
    e = html.escape
    ring = ""
    if pixel is not None and size:
        x, y = 100.0 * (pixel[0] + 0.5) / size[0], 100.0 * (pixel[1] + 0.5) / size[1]
        ring = (f"<span class='ring' data-moved-most='{pixel[0]},{pixel[1]}' style='left:{x:.3f}%;top:{y:.3f}%' "
                "title='where the yarns moved most'></span>")
    return (f"<figure><a href='{e(src)}' target='_blank'><span class='pic'><img src='{e(src)}' alt='{alt}'>{ring}"
            f"</span></a><figcaption>{caption}</figcaption></figure>")


def _frame_section(scene: str, f: dict) -> str:
    e = html.escape
    figs = "".join(f"<tr><td>{e(k)}</td><td>{e(_fmt(v))}</td></tr>" for k, v in f["figures"].items())
    reasons = "".join(f"<li>{e(r)}</li>" for r in f["reasons"])
    imgs = ""
    if "images" in f:
        ref, new, diff = (f["images"][k] for k in ("reference", "new", "diff"))
        pixel, size = f["figures"].get("moved_most_pixel"), f.get("image_size")
        imgs = ("<div class='row'>" + _marked(ref, "reference", "reference", None, size)
                + _marked(new, "new", "new" + (" (ring: where the yarns moved most)" if pixel else ""), pixel, size)
                + _marked(diff, "difference", "difference (white: fail threshold)", pixel, size)
                + f"<figure class='swap'><span class='pic'><img class='swap' src='{e(ref)}' data-reference='{e(ref)}' "
                f"data-new='{e(new)}' alt='swap'></span><figcaption>hover or click: reference / new</figcaption>"
                "</figure></div>")
    return (f"<section id='{_anchor(scene, f['frame'])}' class='frame {f['status']}' data-status='{f['status']}'>"
            f"<h3>frame {f['frame']} <span class='badge'>{f['status']}</span></h3><ul>{reasons}</ul>{imgs}"
            f"<table>{figs}</table></section>")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    return json.dumps(v) if isinstance(v, (list, dict)) else str(v)


PAGE_HEAD = """<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>fraytool golden check: {status}</title>
<style>
body { font: 14px sans-serif; margin: 1em 2em; background: #fafafa; }
.row { display: flex; gap: 8px; flex-wrap: wrap; }
figure { margin: 0; flex: 1 1 46%; min-width: 320px; max-width: 960px; }
.pic { position: relative; display: block; }
.pic img { width: 100%; border: 1px solid #ccc; display: block; image-rendering: pixelated; }
.ring { position: absolute; width: 28px; height: 28px; margin: -16px 0 0 -16px; border: 3px solid #f0f;
        border-radius: 50%; box-shadow: 0 0 0 2px #fff; pointer-events: none; }
#summary { border-collapse: collapse; margin: 8px 0 16px; } #summary td, #summary th { border: 1px solid #ccc; padding: 2px 8px; }
#summary tr.fail td.badge { color: #d22; font-weight: bold; } #summary tr.warn td.badge { color: #d90; }
#problems li.fail a { color: #d22; } ul.differ { font-family: monospace; }
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
  const sections = [...document.querySelectorAll('section.frame')];
  document.body.dataset.firstFrameStatus = sections.length ? sections[0].dataset.status : '';
  const shown = document.querySelector('figure .pic img');
  document.body.dataset.shownWidth = shown ? Math.round(shown.getBoundingClientRect().width) : 0;
  document.body.dataset.rings = document.querySelectorAll('.ring').length;
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
