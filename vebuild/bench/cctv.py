"""How well a CCTV still measures: ``vebuild bench cctv``.

Generated CCTV cameras (:mod:`vebuild.synthetic.cctv`: a street or a shop, a camera 2.5–4 m high
looking down 15–45°, TRUE lenses that are not vebuild's model: equidistant and equisolid
fisheyes 110–150° across the diagonal and a rectilinear 90–110° lens with a little barrel
distortion; frames 1280 × 720, 704 × 576, 1920 × 1080, the principal point a few pixels off
centre; a person-sized figure, 1.50–1.95 m, at 3–4 places). Per case
(:mod:`vebuild.bench.cctv_cases`):

- **the video** (every :data:`~vebuild.bench.cctv_cases.VIDEO_EVERY`-th case, every lens and
  size among them, half of them interlaced): the clip of the figure walking is rendered, encoded
  lossless (libx264rgb, qp 0) and lossy (libx264, crf 23), cached, decoded, and compared with the
  generator's frames: ``frames_decoded_exact`` the share of stills that vebuild takes one at a time
  (``vebuild add clip.mp4@frame=N``'s decoder; the first, the last and each place's frame of each
  lossless clip) identical bit for bit, ``frames_stream_decoded_exact`` the same for every frame
  decoded in sequence;
  the lossy frames' PSNR (dB) and largest error (grey levels). The still (the figure at its first
  place) is taken from the lossy clip as ``vebuild add`` takes it, with its provenance;
- **the calibration**: a one-photo project as a user makes it: 4–6 edges per axis marked as
  polylines along their images (2 ends and 3–5 middle points each, clicked 0.5–1 px off, 1σ drawn
  per case: a user marking a bending line, not ``detect``, which does not follow curves), the
  origin marker O on the ground, a run along x on the ground taped (whole kerb slabs or floor
  tiles, 3 mm 1σ); ``vebuild calibrate`` run on it through the API. The lens it finds is compared
  with the truth by how far it moves the photo's farthest corner (px, and relative):
  ``fisheye_corner_px_error_median`` over the fisheye cases, ``rectilinear_...`` over the others;
- **the heights**: the figure's height at each place, from its head-top and foot points clicked
  1 px off (1σ), measured on the calibrated still: ``person_height_rel_error_median`` (a
  fraction), ``person_height_coverage_95`` (the share of the 95 % intervals, value ± 1.96σ,
  holding the truth; the goal 93–97 % over at least 200 cases).

The reference run, in the same process: the same cameras and scenes seen through vebuild's own
lens model (the division model with the true lens's K-equivalent and corner displacement), the
marks made through it; ``*_ratio`` = true lens / reference. What the true lens costs is then what
the model's mismatch costs, apart from everything else. ``--quick``: 24 cases (6 with video),
the full run 200 (50 with video).
"""

from __future__ import annotations

import re
import tempfile
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.console.bars import Bar
from vebuild.synthetic.cctv_lens import TrueLens

from . import cctv_cases as cc

CASES, QUICK_CASES = 200, 24
#: The 95 % interval's half-width in σ (two-sided).
Z95 = 1.959963984540054
GOALS = {"frames_decoded_exact": 1.0, "fisheye_corner_rel_error_median_at_most": 0.10,
         "person_height_coverage_95_low": 0.93, "person_height_coverage_95_high": 0.97,
         "cases_at_least": 200, "person_height_rel_error_median_at_most": 0.015}
FISHEYES = ("equidistant", "equisolid")


def _reason(message: str) -> str:
    """A refusal without its file, numbers and quoted names, so that alike ones count together."""
    text = re.sub(r"'[^']*'", "'…'", re.sub(r"^\S*\.vebuild\.json: ", "", message))
    return re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", text)


def run_case(i: int, tmp: Path) -> dict[str, Any]:
    """Case i measured through its true lens and through the reference lens."""
    case = cc.make_case(i)
    setting, _, _, video, _ = cc.case_plan(i)
    kind = case.lens.kind if isinstance(case.lens, TrueLens) else ""
    out: dict[str, Any] = {"case": i, "setting": setting, "lens": kind, "size": f"{case.width}x{case.height}",
                           "interlaced": case.interlaced,
                           "corner_true_px": case.lens.corner_displacement_px(case.width, case.height)}
    still = None
    if video:
        clip = cc.cached_clip(i, case)
        out["video"], lossy = cc.round_trip(clip)
        still = cc.Still(clip.lossy, clip.place_frames[0]) if clip.place_frames[0] < len(lossy) else None
    for name, seen in (("true", case), ("reference", cc.reference_case(case))):
        marks = cc.user_marks(seen, np.random.default_rng([cc.SEED, i, 1]))
        if marks is None:
            out[name] = {"refused": "the still shows no origin point or no known length"}
            continue
        got = cc.measure_case(tmp / f"c{i}-{name}", seen, marks, still if name == "true" else None)
        got["corner_true_px"] = seen.lens.corner_displacement_px(seen.width, seen.height)
        out[name] = got
    return out


def _heights(cases: list[dict[str, Any]], run: str) -> list[dict[str, Any]]:
    return [h for c in cases for h in c[run].get("heights", []) if "value_m" in h]


def _height_stats(rows: list[dict[str, Any]]) -> dict[str, Any]:
    if not rows:
        return {"n": 0, "coverage_95": None, "rel_error_median": None, "rel_error_p95": None, "z_rms": None}
    err = np.array([r["value_m"] - r["truth_m"] for r in rows])
    sig = np.array([np.inf if r["sigma_m"] is None else r["sigma_m"] for r in rows])
    rel = np.abs(err) / np.array([r["truth_m"] for r in rows])
    z = err / sig
    fin = np.isfinite(sig)
    return {"n": len(rows), "coverage_95": float(np.mean(np.abs(z) <= Z95)),
            "rel_error_median": float(np.median(rel)), "rel_error_p95": float(np.percentile(rel, 95)),
            "z_rms": float(np.sqrt(np.mean(z[fin] ** 2))) if fin.any() else None}


def _corner_stats(cases: list[dict[str, Any]], run: str, kinds: tuple[str, ...]) -> dict[str, Any]:
    rows = [c for c in cases if c["lens"] in kinds and "lens" in c[run]]
    if not rows:
        return {"n": 0, "px_error_median": None, "rel_error_median": None, "within_10pct_share": None}
    est = np.array([c[run]["lens"]["corner_displacement_px"] for c in rows])
    true = np.array([c[run]["corner_true_px"] for c in rows])
    rel = np.abs(est - true) / true
    return {"n": len(rows), "px_error_median": float(np.median(np.abs(est - true))),
            "rel_error_median": float(np.median(rel)), "within_10pct_share": float(np.mean(rel <= 0.10)),
            "true_px_median": float(np.median(true))}


def _sigma_by_case(cases: list[dict[str, Any]]) -> float | None:
    """The 1σ of the heights' coverage with the cases, not the heights, as the independent draws:
    the heights of one case share its calibration's errors, so they miss or hit together (each
    case's misses less its expected share, 5 %, summed in quadrature)."""
    per_case = []
    for c in cases:
        rows = _heights([c], "true")
        z = [abs(r["value_m"] - r["truth_m"]) / (np.inf if r["sigma_m"] is None else r["sigma_m"]) for r in rows]
        per_case.append(sum(float(v <= Z95) - 0.95 for v in z))
    n = sum(len(_heights([c], "true")) for c in cases)
    return float(np.sqrt(sum(v**2 for v in per_case)) / n) if n else None


def _ratio(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None or b == 0 else a / b


def summarise(cases: list[dict[str, Any]]) -> dict[str, Any]:
    """The figures (module docstring) of measured cases."""
    fig: dict[str, Any] = {"cases": len(cases), "height_click_sigma_px": cc.HEIGHT_CLICK_PX,
                           "segment_click_sigma_px": list(cc.SEGMENT_CLICK_PX)}
    vids = [c["video"] for c in cases if "video" in c]
    n_frames = sum(v["frames"] for v in vids)
    fig["video_cases"] = len(vids)
    fig["video_cases_interlaced"] = sum(c["interlaced"] for c in cases if "video" in c)
    fig["frames_lossless"] = n_frames
    n_stills = sum(v["stills_checked"] for v in vids)
    fig["stills_checked"] = n_stills
    fig["frames_decoded_exact"] = sum(v["stills_exact"] for v in vids) / n_stills if n_stills else None
    fig["frames_stream_decoded_exact"] = sum(v["exact"] for v in vids) / n_frames if n_frames else None
    psnr = [p for v in vids for p in v["psnr_db"]]
    err = [e for v in vids for e in v["max_error_grey"]]
    fig["lossy_frames_compared"] = len(psnr)
    fig["lossy_psnr_db_median"] = float(np.median(psnr)) if psnr else None
    fig["lossy_psnr_db_min"] = float(np.min(psnr)) if psnr else None
    fig["lossy_max_error_grey_median"] = float(np.median(err)) if err else None
    fig["lossy_max_error_grey_max"] = float(np.max(err)) if err else None
    for run, prefix in (("true", ""), ("reference", "reference_")):
        refused = [c[run]["refused"] for c in cases if "refused" in c[run]]
        fig[f"{prefix}cases_refused"] = len(refused)
        fig[f"{prefix}cases_refused_reasons"] = dict(Counter(_reason(m) for m in refused).most_common())
        for name, kinds in (("fisheye", FISHEYES), ("rectilinear", ("rectilinear",))):
            st = _corner_stats(cases, run, kinds)
            fig[f"{prefix}{name}_cases_calibrated"] = st["n"]
            fig[f"{prefix}{name}_corner_px_error_median"] = st["px_error_median"]
            fig[f"{prefix}{name}_corner_rel_error_median"] = st["rel_error_median"]
            fig[f"{prefix}{name}_corner_within_10pct_share"] = st["within_10pct_share"]
            fig[f"{prefix}{name}_corner_true_px_median"] = st.get("true_px_median")
        rows = _heights(cases, run)
        every = _height_stats(rows)
        fig[f"{prefix}person_heights_measured"] = every["n"]
        fig[f"{prefix}person_heights_refused"] = sum("refused" in h for c in cases for h in c[run].get("heights", []))
        fig[f"{prefix}person_height_coverage_95"] = every["coverage_95"]
        fig[f"{prefix}person_height_rel_error_median"] = every["rel_error_median"]
        fig[f"{prefix}person_height_rel_error_p95"] = every["rel_error_p95"]
        fig[f"{prefix}person_height_z_rms"] = every["z_rms"]
        fig[f"{prefix}person_height_cases"] = sum(bool(_heights([c], run)) for c in cases)
        for kind in ("rectilinear", *FISHEYES):
            st = _height_stats(_heights([c for c in cases if c["lens"] == kind], run))
            fig[f"{prefix}{kind}_person_height_coverage_95"] = st["coverage_95"]
            fig[f"{prefix}{kind}_person_height_rel_error_median"] = st["rel_error_median"]
        for setting in ("street", "shop"):
            st = _height_stats(_heights([c for c in cases if c["setting"] == setting], run))
            fig[f"{prefix}{setting}_person_height_coverage_95"] = st["coverage_95"]
            fig[f"{prefix}{setting}_person_height_rel_error_median"] = st["rel_error_median"]
    fig["coverage_95_binomial_sigma"] = float(np.sqrt(0.95 * 0.05 / max(fig["person_heights_measured"], 1)))
    fig["coverage_95_sigma_by_case"] = _sigma_by_case(cases)
    for k in ("fisheye_corner_px_error_median", "fisheye_corner_rel_error_median", "person_height_rel_error_median",
              "person_height_z_rms"):
        fig[f"{k}_ratio"] = _ratio(fig[k], fig[f"reference_{k}"])
    fig["goals"] = dict(GOALS)
    g = GOALS
    cov = fig["person_height_coverage_95"]
    fig["goals_met"] = bool(
        (fig["frames_decoded_exact"] is None or fig["frames_decoded_exact"] >= g["frames_decoded_exact"])
        and fig["fisheye_corner_rel_error_median"] is not None
        and fig["fisheye_corner_rel_error_median"] <= g["fisheye_corner_rel_error_median_at_most"]
        and cov is not None and g["person_height_coverage_95_low"] <= cov <= g["person_height_coverage_95_high"]
        and fig["person_height_cases"] >= g["cases_at_least"]
        and (fig["person_height_rel_error_median"] or 1.0) <= g["person_height_rel_error_median_at_most"])
    return fig


def run(quick: bool = False, progress: bool = True) -> dict[str, Any]:
    n = QUICK_CASES if quick else CASES
    cases = []
    with tempfile.TemporaryDirectory(prefix="vebuild-bench-cctv-") as tmp:
        for i in Bar(range(n), desc="bench cctv", unit="case", disable=not progress):
            cases.append(run_case(i, Path(tmp)))
    return summarise(cases)


def _pct(x: float | None) -> str:
    return "—" if x is None else f"{100 * x:.1f} %"


def _num(x: float | None, fmt: str = ".1f") -> str:
    return "—" if x is None else format(x, fmt)


def table(fig: dict[str, Any]) -> str:
    lines = [f"CCTV stills measured: {fig['cases']} generated cameras ({fig['cases_refused']} refused by calibration; "
             f"reference {fig['reference_cases_refused']}), heights clicked 1σ {fig['height_click_sigma_px']:g} px, "
             f"edges {fig['segment_click_sigma_px'][0]:g}–{fig['segment_click_sigma_px'][1]:g} px", "",
             f"video: {fig['video_cases']} clips ({fig['video_cases_interlaced']} interlaced), "
             f"{fig['frames_lossless']} frames: lossless decoded bit-exact {_pct(fig['frames_stream_decoded_exact'])} "
             f"in sequence, {_pct(fig['frames_decoded_exact'])} of {fig['stills_checked']} stills taken one by "
             "one as `vebuild add` takes them; "
             "lossy (crf 23) PSNR median "
             f"{_num(fig['lossy_psnr_db_median'])} dB, least {_num(fig['lossy_psnr_db_min'])} dB, largest error "
             f"median {_num(fig['lossy_max_error_grey_median'], '.0f')}, most "
             f"{_num(fig['lossy_max_error_grey_max'], '.0f')} grey levels", "",
             f"{'':<34}{'true lens':>12}{'reference':>12}"]
    rows = [("fisheye corner error median (px)", "fisheye_corner_px_error_median", _num),
            ("fisheye corner error median", "fisheye_corner_rel_error_median", _pct),
            ("fisheye corners within 10 %", "fisheye_corner_within_10pct_share", _pct),
            ("fisheye corner shift median (px)", "fisheye_corner_true_px_median", _num),
            ("wide-lens corner error median (px)", "rectilinear_corner_px_error_median", _num),
            ("wide-lens corner error median", "rectilinear_corner_rel_error_median", _pct),
            ("heights measured", "person_heights_measured", lambda x: str(x)),
            ("heights in their 95 % interval", "person_height_coverage_95", _pct),
            ("height error median", "person_height_rel_error_median", _pct),
            ("height error 95th percentile", "person_height_rel_error_p95", _pct),
            ("height RMS error / σ", "person_height_z_rms", lambda x: _num(x, ".2f")),
            *[(f"  {k} in 95 % / median error", f"{k}_person_height_coverage_95", _pct)
              for k in ("rectilinear", *FISHEYES, "street", "shop")]]
    for label, key, f in rows:
        extra = ""
        if key.endswith("_person_height_coverage_95") and not key.startswith("person"):
            med = key.replace("coverage_95", "rel_error_median")
            extra = f"   error {_pct(fig[med])} / ref {_pct(fig['reference_' + med])}"
        lines.append(f"{label:<34}{f(fig[key]):>12}{f(fig['reference_' + key]):>12}{extra}")
    for what in ("cases_refused_reasons", "reference_cases_refused_reasons"):
        if fig[what]:
            lines += ["", what.replace("_", " ").replace("reasons", "(why)") + ":"]
            lines += [f"  {n:>4} × {reason}" for reason, n in fig[what].items()]
    g = fig["goals"]
    lines += ["", f"goals: lossless frames bit-exact; fisheye corner error median ≤ "
              f"{100 * g['fisheye_corner_rel_error_median_at_most']:.0f} %; heights in their 95 % interval "
              f"{100 * g['person_height_coverage_95_low']:.0f}–{100 * g['person_height_coverage_95_high']:.0f} % over "
              f"≥ {g['cases_at_least']} cases; median height error ≤ "
              f"{100 * g['person_height_rel_error_median_at_most']:g} %: {'met' if fig['goals_met'] else 'NOT met'} "
              f"(1σ of the coverage at this count {_pct(fig['coverage_95_binomial_sigma'])} binomial, "
              f"{_pct(fig['coverage_95_sigma_by_case'])} with the cases as the draws)"]
    return "\n".join(lines)
