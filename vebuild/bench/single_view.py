"""How well one photo measures: ``vebuild bench single-view``.

Generated single photos of rooms and streets (:mod:`vebuild.bench.single_view_scenes`: wide to
long lenses, EXIF present and absent, principal points off centre, barrel distortion on some,
hand-held and CCTV heights, near-frontal and oblique views), each handled as a user would: a
one-photo project written (its vanishing segments, its origin marker and one known length in
view, with the tape's 1σ), ``vebuild calibrate`` run on it (:func:`calibrate_project`), the
project saved and read back, and each measurement made by the words `vebuild analyse` takes
(:func:`vebuild.analysis.single_view.single_view_command`, parsed and run as a project's saved
analysis: the command line's own path), the clicks :data:`CLICK_SIGMA_PX` off their true pixels.

The figures: per kind of measurement (:data:`KINDS`), how often the truth lies inside the
reported 95 % interval (value ± 1.96σ, two-sided; the goal 93–97 % over at least 300
measurements), the median and 95th percentile of the relative error (the goal for heights: a
median of at most 1 % with a known length in view), and the RMS of the errors over their σ (1
where the σ is honest); the same split by each condition (EXIF, lens, view, mount, setting,
distortion), so a failure is found where it lives; and the photos calibration refused, with
why. ``--quick``: 60 photos (some 300 measurements), the full run 400.
"""

from __future__ import annotations

import re
import tempfile
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.console.bars import Bar
from vebuild.errors import VebuildError

from .single_view_scenes import CLICK_SIGMA_PX, Scene, click, scene

#: The measurements made, each a `vebuild analyse` kind → the figures' name for it. The kinds of
#: :data:`vebuild.analysis.single_view.SINGLE_VIEW_CLICKS` not here are generated but not measured:
#: add ``"wall-length": "wall_length"``, ``"raised-height": "raised_height"``, ``"plane-length":
#: "plane_length"`` where `vebuild analyse` takes them.
KINDS: dict[str, str] = {"photo-height": "height", "floor-distance": "distance", "wall-length": "wall_length",
                         "raised-height": "raised_height", "plane-length": "plane_length"}
#: The 95 % interval's half-width in σ (two-sided).
Z95 = 1.959963984540054
#: The goals: the intervals' coverage (two-sided), over at least this many measurements; the
#: median relative error of a height with a known length in view.
GOALS = {"coverage_95_low": 0.93, "coverage_95_high": 0.97, "measurements_at_least": 300,
         "height_rel_error_median_at_most": 0.01}
#: Whether every other pair of photos goes without the origin marker (calibration then puts the
#: world's origin on the floor below the camera); False: every photo has one.
WITHOUT_ORIGIN_MARKER = True
PHOTOS, QUICK_PHOTOS = 400, 60
SEED = 20261207
SETTINGS = ("room", "street")
#: The conditions the figures are split by, and each one's values (Scene.conditions).
CONDITIONS = {"exif": ("exif_present", "exif_absent"), "lens": ("lens_wide", "lens_normal", "lens_long"),
              "view": ("frontal", "oblique"), "mount": ("hand_held", "cctv"), "setting": ("room", "street"),
              "lens_distortion": ("undistorted", "distorted"),
              "principal_point": ("principal_point_near", "principal_point_off"),
              **({"origin": ("origin_marker", "origin_below_camera")} if WITHOUT_ORIGIN_MARKER else {})}


def _reason(message: str) -> str:
    """A refusal's message without the project file it begins with, its numbers and quoted names, so
    that alike refusals count together."""
    text = re.sub(r"'[^']*'", "'…'", re.sub(r"^\S*\.vebuild\.json: ", "", message.splitlines()[0]))
    return re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", text)


def write_scene(folder: Path, s: Scene, rng: np.random.Generator) -> Path:
    """The one-photo project a user makes of scene ``s``: its segments, the origin marker O on the
    floor (where ``s.origin_marker``), its EXIF and the known length (the tape's reading off the
    truth by its 1σ)."""
    from vebuild.project import load_project, save_project
    from vebuild.synthetic import write_project

    path = write_project(folder, [s.photo], {"O": s.origin, "O2": s.origin + [1.0, 0.0, 0.0]})
    project = load_project(path)
    d = project.data
    d["settings"]["click_sigma_px"] = CLICK_SIGMA_PX
    photo = d["photos"][0]
    photo["marker_observations"] = {"O": click(s, s.origin, rng)} if s.origin_marker else {}
    if s.exif:
        photo["exif"] = dict(s.exif)
    d["markers"] = [{"name": "O", "on_floor": True}] if s.origin_marker else []
    if s.origin_marker:
        d["origin_marker"] = "O"
    else:
        d.pop("origin_marker", None)
    d["reference_distances"] = []
    sc = s.scale
    length = round(sc["length"] + rng.normal(0.0, sc["sigma"]), 4)
    known: dict[str, Any] = {"photo": s.photo.id, "axis": sc["axis"], "length": length, "sigma": sc["sigma"],
                             "ends": [click(s, X, rng) for X in sc["ends"]]}
    if sc["axis"] == "z":
        known["floor_end"] = 0
    d["known_lengths"] = [known]
    save_project(project)
    return path


def measure_scene(folder: Path, s: Scene, index: int) -> dict[str, Any]:
    """Calibrate scene ``s``'s project and make its measurements: ``{"refused": reason}`` where
    calibration refused the photo, else ``{"rows": [...]}``, one row per measurement (its kind,
    truth, value and σ in metres, or its refusal)."""
    from vebuild.actions.calibrate import calibrate_project
    from vebuild.analysis.recorded import parse_recorded
    from vebuild.analysis.single_view import single_view_command
    from vebuild.project import load_project, save_project

    path = write_scene(folder, s, np.random.default_rng([SEED, index, 0]))
    try:
        project = load_project(path)
        calibrate_project(project)
        save_project(project)
        project = load_project(path)
    except VebuildError as e:
        return {"refused": str(e)}
    rows = []
    for j, item in enumerate(s.items):
        if item.kind not in KINDS:
            continue
        rng = np.random.default_rng([SEED, index, 1 + j])  # the same clicks whatever else is measured
        row: dict[str, Any] = {"kind": item.kind, "what": item.what, "truth_m": item.truth}
        try:
            words = single_view_command(item.kind, s.photo.id, [click(s, X, rng) for X in item.points])
            (m,) = parse_recorded(words).run(project).figures["measurements"]
        except VebuildError as e:
            row["refused"] = str(e)
        else:
            if "value_m" not in m:
                row["refused"] = "lengths relative: the known length did not scale the photo"
            else:
                row["value_m"], row["sigma_m"] = m["value_m"], m["sigma_m"]
        rows.append(row)
    return {"rows": rows}


def _stats(rows: list[dict[str, Any]]) -> dict[str, float]:
    """Coverage of the 95 % intervals, relative errors and the errors' RMS in σ of measured rows."""
    if not rows:
        return {"n": 0}
    err = np.array([r["value_m"] - r["truth_m"] for r in rows])
    sig = np.array([np.inf if r["sigma_m"] is None else r["sigma_m"] for r in rows])
    rel = np.abs(err) / np.array([r["truth_m"] for r in rows])
    z = err / sig
    return {"n": len(rows), "coverage_95": float(np.mean(np.abs(z) <= Z95)),
            "rel_error_median": float(np.median(rel)), "rel_error_p95": float(np.percentile(rel, 95)),
            "z_rms": float(np.sqrt(np.mean(z[np.isfinite(sig)] ** 2))) if np.isfinite(sig).any() else float("nan"),
            "rel_sigma_median": float(np.median(sig / np.array([r["truth_m"] for r in rows])))}


def _sigma_by_photo(done: list[tuple[Scene, dict[str, Any]]]) -> float | None:
    """The 1σ of the coverage with the photos, not the measurements, as the independent draws: the
    measurements of one photo share its camera's errors, so they miss or hit together more often
    than the binomial count assumes (each photo's misses less its expected share, 5 %, summed in
    quadrature)."""
    if not done:
        return None
    by_photo: dict[int, list[float]] = {}
    for s, row in done:
        z = (row["value_m"] - row["truth_m"]) / (np.inf if row["sigma_m"] is None else row["sigma_m"])
        by_photo.setdefault(id(s), []).append(float(abs(z) <= Z95) - 0.95)
    return float(np.sqrt(sum(sum(v) ** 2 for v in by_photo.values())) / len(done))


def summarise(results: list[tuple[Scene, dict[str, Any]]]) -> dict[str, Any]:
    """The figures (module docstring) of measured scenes."""
    fig: dict[str, Any] = {"photos": len(results), "click_sigma_px": CLICK_SIGMA_PX}
    refused = [(s, r["refused"]) for s, r in results if "refused" in r]
    fig["photos_refused"] = len(refused)
    fig["photos_refused_reasons"] = dict(Counter(_reason(m) for _, m in refused).most_common())
    rows = [(s, row) for s, r in results for row in r.get("rows", [])]
    done = [(s, row) for s, row in rows if "value_m" in row]
    fig["measurements"] = len(done)
    fig["measurements_refused"] = len(rows) - len(done)
    fig["measurements_refused_reasons"] = dict(Counter(_reason(row["refused"]) for _, row in rows
                                                       if "refused" in row).most_common())
    every = _stats([row for _, row in done])
    fig["coverage_95"] = every.get("coverage_95")
    fig["coverage_95_binomial_sigma"] = float(np.sqrt(0.95 * 0.05 / max(len(done), 1)))
    fig["coverage_95_sigma_by_photo"] = _sigma_by_photo(done)
    for kind, name in KINDS.items():
        st = _stats([row for _, row in done if row["kind"] == kind])
        fig[f"{name}s_measured"] = st["n"]
        for k in ("coverage_95", "rel_error_median", "rel_error_p95", "z_rms", "rel_sigma_median"):
            fig[f"{name}_{k}"] = st.get(k)
    for cond, values in CONDITIONS.items():
        for value in values:
            mine = [row for s, row in done if s.conditions()[cond] == value]
            fig[f"{value}_photos"] = sum(s.conditions()[cond] == value for s, _ in results)
            fig[f"{value}_photos_refused"] = sum(s.conditions()[cond] == value for s, _ in refused)
            fig[f"{value}_measurements"] = len(mine)
            fig[f"{value}_coverage_95"] = _stats(mine).get("coverage_95")
            for kind, name in KINDS.items():
                st = _stats([row for row in mine if row["kind"] == kind])
                fig[f"{value}_{name}_coverage_95"] = st.get("coverage_95")
                fig[f"{value}_{name}_rel_error_median"] = st.get("rel_error_median")
    fig["goals"] = dict(GOALS)
    cov = [fig[f"{name}_coverage_95"] for name in KINDS.values()]
    fig["goals_met"] = bool(len(done) >= GOALS["measurements_at_least"]
                            and all(c is not None and GOALS["coverage_95_low"] <= c <= GOALS["coverage_95_high"]
                                    for c in cov)
                            and (fig["height_rel_error_median"] or 1.0) <= GOALS["height_rel_error_median_at_most"])
    return fig


def run(quick: bool = False, progress: bool = True) -> dict[str, Any]:
    n = QUICK_PHOTOS if quick else PHOTOS
    results: list[tuple[Scene, dict[str, Any]]] = []
    with tempfile.TemporaryDirectory(prefix="vebuild-bench-single-view-") as tmp:
        for i in Bar(range(n), desc="bench single-view", unit="photo", disable=not progress):
            s = scene(np.random.default_rng([SEED, i]), SETTINGS[i % len(SETTINGS)])
            s.origin_marker = not (WITHOUT_ORIGIN_MARKER and (i // 2) % 2)
            folder = Path(tmp) / f"photo{i}"
            results.append((s, measure_scene(folder, s, i)))
    return summarise(results)


def _label(name: str) -> str:
    """A kind's figures' name as a column's heading: "wall_length" → "wall lengths"."""
    return name.replace("_", " ") + "s"


def _width(name: str) -> int:
    return max(11, len(_label(name)) + 2)


def _pct(x: float | None) -> str:
    return "—" if x is None else f"{100 * x:.1f} %"


def table(fig: dict[str, Any]) -> str:
    lines = [f"one photo measured: {fig['photos']} generated photos ({fig['photos_refused']} refused by calibration), "
             f"{fig['measurements']} measurements ({fig['measurements_refused']} refused), clicks 1σ "
             f"{fig['click_sigma_px']:g} px", "",
             f"{'':<24}{'n':>6}{'in 95 %':>10}{'median err':>12}{'95th pct':>10}{'RMS err/σ':>11}"
             f"{'median σ':>10}"]
    for name in KINDS.values():
        lines.append(f"{_label(name):<24}{fig[f'{name}s_measured']:>6}{_pct(fig[f'{name}_coverage_95']):>10}"
                     f"{_pct(fig[f'{name}_rel_error_median']):>12}{_pct(fig[f'{name}_rel_error_p95']):>10}"
                     + ("" if fig[f"{name}_z_rms"] is None else f"{fig[f'{name}_z_rms']:>11.2f}")
                     + f"{_pct(fig[f'{name}_rel_sigma_median']):>10}")
    lines += ["", "by condition (share inside the 95 % intervals; median height error)",
              f"{'':<24}{'photos':>7}{'refused':>8}{'n':>6}{'all':>9}"
              + "".join(f"{_label(name):>{_width(name)}}" for name in KINDS.values()) + f"{'height err':>12}"]
    for values in CONDITIONS.values():
        for v in values:
            lines.append(f"{v.replace('_', ' '):<24}{fig[f'{v}_photos']:>7}{fig[f'{v}_photos_refused']:>8}"
                         f"{fig[f'{v}_measurements']:>6}{_pct(fig[f'{v}_coverage_95']):>9}"
                         + "".join(f"{_pct(fig[f'{v}_{name}_coverage_95']):>{_width(name)}}" for name in KINDS.values())
                         + f"{_pct(fig[f'{v}_height_rel_error_median']):>12}")
    for what in ("photos_refused_reasons", "measurements_refused_reasons"):
        if fig[what]:
            lines += ["", what.replace("_", " ").replace("reasons", "(why)") + ":"]
            lines += [f"  {n:>4} × {reason}" for reason, n in fig[what].items()]
    g = fig["goals"]
    lines += ["", f"goals: the 95 % intervals hold the truth {100 * g['coverage_95_low']:.0f}–"
              f"{100 * g['coverage_95_high']:.0f} % of the time over ≥ {g['measurements_at_least']} measurements, "
              f"median height error ≤ {100 * g['height_rel_error_median_at_most']:g} %: "
              f"{'met' if fig['goals_met'] else 'NOT met'} (binomial 1σ of the coverage at this count "
              f"{_pct(fig['coverage_95_binomial_sigma'])}, {_pct(fig['coverage_95_sigma_by_photo'])} with the "
              "photos as the draws)"]
    return "\n".join(lines)
