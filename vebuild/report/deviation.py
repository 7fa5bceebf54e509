"""The report's laser-scan section: each scan's registration, the deviation of the model from it
per face (median and 95th percentile), and a deviation map: the scan's points seen from above,
coloured by their signed distance from the nearest face (blue behind it, red in front, white on
it; grey: farther than the distance that counts as the model's). numpy and Pillow only.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from vebuild.analysis.scans import face_deviations
from vebuild.errors import VebuildError
from vebuild.project import Project
from vebuild.project.scans import dropped_words

from .page import Cell, Report, esc, fmt, table

#: Points drawn in a map at most (a regular subsample of the scan).
MAP_POINTS = 200_000
#: The map's longer side, pixels.
MAP_SIDE_PX = 900
#: The map's background (dark, so that points on a face, white, show) and each point's side, pixels.
BACKGROUND = (40, 40, 40)
POINT_PX = 2
#: The colour scale's end, at least this (metres): a model within it is white to pale.
MIN_RANGE_M = 0.005


def diverging(t: NDArray[np.float64]) -> NDArray[np.uint8]:
    """t in [−1, 1] → blue (−1), white (0), red (+1), sRGB."""
    t = np.clip(t, -1.0, 1.0)[:, None]
    blue, white, red = np.array([33, 102, 172.0]), np.array([247, 247, 247.0]), np.array([178, 24, 43.0])
    rgb = np.where(t < 0, white + (blue - white) * (-t), white + (red - white) * t)
    return np.rint(rgb).astype(np.uint8)


def deviation_map(world: NDArray[np.float64], signed: NDArray[np.float64], side_px: int = MAP_SIDE_PX
                  ) -> tuple[NDArray[np.uint8], float, float]:
    """(H, W, 3) top view of the points (x right, y up the page), each pixel the highest point's
    colour; returns the image, the colour scale's end (metres) and the scale in pixels per metre."""
    from PIL import Image, ImageDraw

    P = np.asarray(world, float)
    d = np.asarray(signed, float)
    ok = np.isfinite(d)
    span = float(np.percentile(np.abs(d[ok]), 95)) if ok.any() else MIN_RANGE_M
    span = max(span, MIN_RANGE_M)
    lo, hi = P[:, :2].min(axis=0), P[:, :2].max(axis=0)
    size = np.maximum(hi - lo, 1e-3)
    ppm = (side_px - 20) / float(size.max())
    W, H = (np.ceil(size * ppm).astype(int) + 20).tolist()
    bar = 40
    img = np.full((H + bar, W, 3), 255, np.uint8)
    img[:H] = BACKGROUND
    order = np.argsort(P[:, 2])  # the highest point last: the view from above
    col = np.where(ok[:, None], diverging(np.where(ok, d, 0.0) / span), np.uint8(170))
    u = np.clip(((P[order, 0] - lo[0]) * ppm + 10).astype(int), 0, W - 1)
    v = np.clip(((hi[1] - P[order, 1]) * ppm + 10).astype(int), 0, H - 1)
    for du in range(POINT_PX):  # each point a POINT_PX square, so that a sparse scan shows
        for dv in range(POINT_PX):
            img[np.minimum(v + dv, H - 1), np.minimum(u + du, W - 1)] = col[order]
    # The colour bar: −span … +span.
    ramp = diverging(np.linspace(-1, 1, W - 40))
    img[H + 8 : H + 20, 20 : W - 20] = ramp[None]
    pil = Image.fromarray(img)
    draw = ImageDraw.Draw(pil)
    mm = span * 1000
    draw.text((20, H + 22), f"-{mm:.1f} mm (behind the face)", fill=(0, 0, 0))
    draw.text((W // 2 - 4, H + 22), "0", fill=(0, 0, 0))
    label = f"+{mm:.1f} mm (in front)"
    draw.text((W - 20 - 6 * len(label), H + 22), label, fill=(0, 0, 0))
    return np.asarray(pil), span, ppm


def scans(project: Project, rep: Report) -> None:
    """The section "Laser scans" (nothing where the project has none)."""
    entries = project.data.get("scans") or []
    if not entries:
        return
    parts = ["<p>Each scan is registered into the project frame by a similarity (scale, rotation, translation) "
             "fitted to targets seen in the scan and in the project (Umeyama's least squares); its points are "
             "then compared with the model's faces. Median: the signed distance (positive in front of the face); "
             "p95: the 95th percentile of the distance; registration 1σ: how far the registration's own "
             "uncertainty moves that face's points along its normal.</p>"]
    for i, e in enumerate(entries):
        reg = e["registration"]
        cov = reg.get("covariance")
        sd_scale = np.sqrt(cov["matrix"][0][0]) if cov else None
        scale = reg["similarity"]["scale"]
        ppm = f", 1σ {sd_scale / scale * 1e6:.0f} ppm" if sd_scale is not None else ""
        dropped = dropped_words(e)
        parts.append(f"<h3>Scan {i}: {esc(e['file'])}</h3><p>{esc(e['format'].upper())}, {e['point_count']} points"
                     f"{' (' + esc(dropped) + ')' if dropped else ''}, "
                     f"SHA-256 <span class='hash'>{esc(e['sha256'])}</span>; "
                     f"{'used as observations in the solve' if e['use_in_solve'] else 'a check only'}"
                     f". Scale {scale:.9g} (project metres per scan unit{ppm}), rms of the targets "
                     f"{fmt(reg['rms_m'] * 1000, 1)} mm over {len(reg['targets'])} targets.</p>")
        parts.append(table(["target", "project point", "residual mm"],
                           [[t["name"], t.get("point", "—"), fmt(r["distance_m"] * 1000, 1)]
                            for t, r in zip(reg["targets"], reg["residuals"], strict=True)], {2}))
        try:
            dev = face_deviations(project, i)
        except VebuildError as err:
            parts.append(f"<p class='warn'>{esc(err)}</p>")
            rep.warnings.append(f"scan {i}: {err}")
            continue
        for w in dev["warnings"]:
            parts.append(f"<p class='warn'>{esc(w)}</p>")
            rep.warnings.append(w)
        rows = []
        for r in dev["faces"]:
            rs = r.get("registration_sigma_m")
            far = rs is not None and abs(r["median_m"]) > 3 * np.hypot(rs, 1.2533 * r["rms_m"] / np.sqrt(r["count"]))
            med = fmt(r["median_m"] * 1000, 1)
            rows.append([f"{r['node']}:{r['face']}", r["count"], Cell(med, "bad") if far else med,
                         fmt(r["p95_m"] * 1000, 1), "—" if rs is None else fmt(rs * 1000, 1)])
        shown = f"{dev['points']} points" if dev["points"] == dev["scan_points"] else \
            f"{dev['points']} of its {dev['scan_points']} points (a regular subsample)"
        parts.append(f"<p>{shown}; {dev['unassigned']} lie farther than "
                     f"{dev['max_distance_m'] * 1000:.0f} mm from every face (not the model's).</p>")
        parts.append(table(["face", "points", "median mm", "p95 mm", "registration 1σ mm"], rows, {1, 2, 3, 4}))
        step = max(1, len(dev["world"]) // MAP_POINTS)
        img, span, px_per_m = deviation_map(dev["world"][::step], dev["signed"][::step])
        src = rep.image(f"scan-{i}-deviation.png", img, {"vebuild:scan": e["file"]})
        parts.append(f"<figure><img src='{src}'><figcaption>Scan {i} seen from above ({px_per_m:.0f} px per metre), "
                     f"each point coloured by its signed distance from the nearest face, ±{span * 1000:.1f} mm "
                     "at the ends; grey: not the model's.</figcaption></figure>")
    rep.add("Laser scans", "\n".join(parts))
