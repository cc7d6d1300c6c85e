"""The figures of one golden frame against its new render, and their verdict (docs/golden.md).

Images, in the manner of OpenImageIO's idiff, over the per-channel absolute difference of the 16-bit
sRGB values scaled to [0, 1]: the share of pixels with a channel over `fail` (over `failpercent` %
fails the frame), any pixel over `hardfail` fails it, `warn` / `warnpercent` likewise warn; also the
mean, RMS and largest difference (with the pixel) and PSNR. Perceptually, SSIM (Wang, Bovik, Sheikh and
Simoncelli 2004) of the luma, over 7 x 7 windows with the usual constants K1 = 0.01, K2 = 0.03; below
`ssim_min` fails. Geometry: the largest distance between matching yarn points in yarn thicknesses
(pieces must match one to one: a yarn cut elsewhere is a different tear), and the torn-spring count.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

PASS, WARN, FAIL = "pass", "warn", "fail"


@dataclass
class FrameVerdict:
    frame: int
    status: str = PASS
    figures: dict = field(default_factory=dict)
    reasons: list[str] = field(default_factory=list)
    """One line per threshold crossed: "frame 35: image: 3.2 % of pixels over fail 0.05 (failpercent 0.5)"."""

    def flag(self, status: str, text: str) -> None:
        if status == FAIL or self.status == PASS:
            self.status = status
        self.reasons.append(f"frame {self.frame}: {status}: {text}")


def _box_mean(x: np.ndarray, r: int) -> np.ndarray:
    """Mean over (2r + 1)^2 windows, valid region only (summed-area table)."""
    c = np.pad(x, ((1, 0), (1, 0))).cumsum(0).cumsum(1)
    k = 2 * r + 1
    return (c[k:, k:] - c[:-k, k:] - c[k:, :-k] + c[:-k, :-k]) / (k * k)


def ssim(a: np.ndarray, b: np.ndarray, window: int = 7) -> float:
    """Mean SSIM of two luma images in [0, 1] (Wang et al. 2004), uniform windows of `window` pixels."""
    r = window // 2
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    a, b = a.astype(np.float64), b.astype(np.float64)
    ma, mb = _box_mean(a, r), _box_mean(b, r)
    va = _box_mean(a * a, r) - ma * ma
    vb = _box_mean(b * b, r) - mb * mb
    cov = _box_mean(a * b, r) - ma * mb
    s = ((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2))
    return float(s.mean())


def luma(image01: np.ndarray) -> np.ndarray:
    """Rec. 709 luma of an sRGB image in [0, 1]."""
    return image01[..., :3] @ np.array([0.2126, 0.7152, 0.0722])


def image_figures(golden: np.ndarray, new: np.ndarray, fail: float, warn: float) -> dict:
    """The image figures of a frame (uint16 images of the same shape)."""
    g, n = golden.astype(np.float64) / 65535.0, new.astype(np.float64) / 65535.0
    d = np.abs(g - n)
    per_pixel = d.max(axis=-1)
    worst = np.unravel_index(int(per_pixel.argmax()), per_pixel.shape)
    mse = float((d ** 2).mean())
    return {
        "mean_error": float(d.mean()),
        "rms_error": mse ** 0.5,
        "psnr_db": float("inf") if mse == 0 else float(10 * np.log10(1.0 / mse)),
        "max_error": float(per_pixel.max()),
        "max_error_pixel": [int(worst[1]), int(worst[0])],
        "fail_percent": 100.0 * float((per_pixel > fail).mean()),
        "warn_percent": 100.0 * float((per_pixel > warn).mean()),
        "ssim": ssim(luma(g), luma(n)),
    }


def geometry_figures(golden_points: np.ndarray, golden_offsets: np.ndarray, points: np.ndarray,
                     offsets: np.ndarray, thickness_m: float) -> dict:
    """Largest yarn-point distance in thicknesses, or the piece counts when the yarns are cut differently."""
    same = golden_offsets.shape == offsets.shape and np.array_equal(golden_offsets, offsets)
    out = {"yarn_pieces": int(len(offsets) - 1), "golden_yarn_pieces": int(len(golden_offsets) - 1),
           "same_yarn_pieces": bool(same)}
    if same:
        d = np.linalg.norm(points.astype(np.float64) - golden_points.astype(np.float64), axis=1)
        out["max_yarn_distance_thickness"] = float(d.max(initial=0.0) / thickness_m)
        if d.size and d.max() > 0.0:  # where it moved most (the report marks it on the image)
            out["moved_most_point_m"] = [float(x) for x in points[int(d.argmax())]]
    return out


@dataclass(frozen=True)
class ImageTolerance:
    """Image thresholds, as the [golden] table's (GoldenSpec has the same names), plus two a test suite may
    want: `rms_max` (fail above this RMS) and `warn_fails` (the warn level fails too: a second, finer
    fail level)."""

    fail: float = 0.05
    failpercent: float = 0.1
    hardfail: float = 1.0
    warn: float = 0.01
    warnpercent: float = 0.05
    ssim_min: float = 0.98
    rms_max: float = 1.0
    warn_fails: bool = False


def judge_image(v: FrameVerdict, golden: np.ndarray, new: np.ndarray, tol) -> None:
    """Add the image figures of golden against new (uint16, (H, W, 3)) to `v`, flagging what `tol` (an
    ImageTolerance or the scene's GoldenSpec) does not allow."""
    if golden.shape != new.shape:
        v.figures["image_size"] = [list(golden.shape[1::-1]), list(new.shape[1::-1])]
        v.flag(FAIL, f"image: size {golden.shape[1]} x {golden.shape[0]} in the golden, {new.shape[1]} x "
                     f"{new.shape[0]} now")
        return
    f = image_figures(golden, new, tol.fail, tol.warn)
    v.figures.update(f)
    px = f"at pixel ({f['max_error_pixel'][0]}, {f['max_error_pixel'][1]})"
    if f["fail_percent"] > tol.failpercent:
        v.flag(FAIL, f"image: {f['fail_percent']:.3f} % of pixels differ by more than fail = {tol.fail:g} "
                     f"(failpercent = {tol.failpercent:g}); largest {f['max_error']:.4f} {px}")
    if f["max_error"] > tol.hardfail:
        v.flag(FAIL, f"image: largest difference {f['max_error']:.4f} {px} over hardfail = {tol.hardfail:g}")
    if f["ssim"] < tol.ssim_min:
        v.flag(FAIL, f"image: SSIM {f['ssim']:.5f} below ssim_min = {tol.ssim_min:g}")
    if f["rms_error"] > getattr(tol, "rms_max", 1.0):
        v.flag(FAIL, f"image: RMS {f['rms_error']:.5f} over rms_max = {tol.rms_max:g}")
    if f["warn_percent"] > tol.warnpercent:
        v.flag(FAIL if getattr(tol, "warn_fails", False) else WARN,
               f"image: {f['warn_percent']:.3f} % of pixels differ by more than warn = {tol.warn:g} "
               f"(warnpercent = {tol.warnpercent:g})")


def judge(frame: int, golden: dict, new: dict, tol, thickness_m: float) -> FrameVerdict:
    """Compare one frame: `golden` and `new` hold image (uint16), points, offsets, torn_springs; `tol` is
    the scene's [golden] table (GoldenSpec)."""
    v = FrameVerdict(frame)
    judge_image(v, golden["image"], new["image"], tol)
    g = geometry_figures(golden["points"], golden["offsets"], new["points"], new["offsets"], thickness_m)
    v.figures.update(g)
    if not g["same_yarn_pieces"]:
        v.flag(FAIL, f"geometry: {g['yarn_pieces']} yarn pieces, the golden has {g['golden_yarn_pieces']} "
                     "(the yarns are cut differently)")
    elif g["max_yarn_distance_thickness"] > tol.geometry_thickness:
        v.flag(FAIL, f"geometry: a yarn point moved {g['max_yarn_distance_thickness']:.3f} thicknesses "
                     f"(geometry_thickness = {tol.geometry_thickness:g})")
    v.figures["torn_springs"] = int(new["torn_springs"])
    v.figures["golden_torn_springs"] = int(golden["torn_springs"])
    if abs(int(new["torn_springs"]) - int(golden["torn_springs"])) > tol.torn_springs:
        v.flag(FAIL, f"geometry: {new['torn_springs']} torn springs, the golden has {golden['torn_springs']} "
                     f"(torn_springs = {tol.torn_springs})")
    return v
