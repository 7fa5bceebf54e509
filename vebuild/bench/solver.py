"""``vebuild bench solver``: drag-update latency and re-calibration time (paper §3.1, §3.2).

Drags: a box resting on the floor, seen by two photos, dragged as in the paper's Figure 7 (first
a bottom corner with nothing fixed, then the far top corner with one vertex fixed, then a second
bottom corner with two fixed), 60 mouse moves each toward the corner's true place. One update is
``DragSession.move``: the solve and the projected edges of every photo. The same drags again
through a wide lens (barrel distortion moving the corners by LENS_CORNER_SHARE): the pins and the
mouse in the photos' distorted pixels, every edge drawn as its curve through the lens.

Re-calibration: boxes on a floor seen by 8 photos, every camera perturbed (0.2°, 2 cm) and held
by its calibration covariance, all solved jointly with a robust loss.

The reference, run in the same process on the same problems (same residuals and Jacobian), is
scipy's ``least_squares`` (trust-region reflective): "ratio" figures divide vebuild's time by it.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from vebuild.camera import ImageCamera, Lens, distortion_displacement_px, exp_so3, project
from vebuild.console.bars import Bar
from vebuild.model.drag import DragSession
from vebuild.model.residuals import Pin
from vebuild.model.scene import model_from_dict
from vebuild.model.solver import FINAL_PRIOR_SCALE, MarkerData, Problem, ProblemOptions
from vebuild.synthetic import model_scene

GOALS = {"drag_update_ms_p95": 5.0, "recalibration_s_50": 1.0}
MOVES = 60
MARKERS = {"O": np.zeros(3)}
#: The wide lens of the distorted drags: its corners moved inward by this share of their distance
#: from the principal point (the 1–3 % of an 18–24 mm lens on APS-C).
LENS_CORNER_SHARE = 0.03


def barrel_k1(K: np.ndarray, width: int, height: int, share: float = LENS_CORNER_SHARE) -> float:
    """The division model's k1 (< 0) that moves the farthest corner inward by ``share`` of its
    distance from the principal point: x_u = x_d / (1 + k1 r²) = (1 + share) x_d there."""
    c = np.asarray(K, float)[:2, 2]
    r = max(float(np.hypot(*(np.array(p) - c))) for p in ((0, 0), (width, 0), (0, height), (width, height)))
    return float((1.0 / (1.0 + share) - 1.0) / (r / K[0, 0]) ** 2)


def _scipy_move(session: DragSession) -> None:
    """The reference: the same drag problem solved by scipy's trust-region reflective method."""
    p = session.problem
    lo, hi = p.bounds()
    sol = least_squares(p.residuals, np.clip(session.x, lo, hi), jac=lambda x: np.asarray(p.jacobian(x)),
                        bounds=(lo, hi), method="trf", x_scale="jac", xtol=1e-8, ftol=1e-8)
    session.x = sol.x


def drags(seed: int = 7, lens: bool = False) -> dict[str, Any]:
    """The drags' figures; ``lens``: through the wide lens, vebuild only (keys end in ``_lens``)."""
    rng = np.random.default_rng(seed)
    truth_nodes, start_nodes, _, photos = model_scene(rng, n_boxes=1, n_photos=2)
    truth = model_from_dict(truth_nodes["nodes"], MARKERS)
    cams = {p.id: ImageCamera(p.id, p.K, p.R, p.C, p.width, p.height,
                              lens=Lens(barrel_k1(p.K, p.width, p.height) if lens else 0.0)) for p in photos.values()}
    out: dict[str, Any] = {}
    if lens:
        out["lens_corner_displacement_px"] = max(distortion_displacement_px(c.K, c.width, c.height, c.lens)
                                                 for c in cams.values())
    for solver in ("vebuild",) if lens else ("vebuild", "reference"):
        model = model_from_dict(start_nodes["nodes"], MARKERS)
        fixed: list[Pin] = []
        for n_fixed, handle in ((0, "v0"), (1, "v6"), (2, "v1")):
            cam = cams["p1"]
            target = project(cam.K, cam.R, cam.C, truth.handle_world("box0", handle), cam.lens)
            s = DragSession(model, cams, fixed, [], "p1", "box0", handle, click_sigma_px=0.7)
            start = s.pin.uv.copy()
            times, worst = [], 0.0
            for k in range(1, MOVES + 1):
                uv = start + (target - start) * k / MOVES
                t0 = time.perf_counter()
                if solver == "vebuild":
                    r = s.move(uv)
                    worst = max(worst, r.fixed_error_px)
                else:
                    s.problem.set_pin_pixel(s._pin_index, uv)
                    _scipy_move(s)
                times.append(1000.0 * (time.perf_counter() - t0))
            fixed.append(s.release())
            key = f"{n_fixed}_fixed" + ("_lens" if lens else "")
            if solver == "vebuild":
                out[f"drag_update_ms_median_{key}"] = float(np.median(times))
                out[f"drag_update_ms_p95_{key}"] = float(np.percentile(times, 95))
                out[f"drag_fixed_vertex_error_px_max_{key}"] = worst
            else:
                out[f"reference_drag_solve_ms_median_{key}"] = float(np.median(times))
    if lens:
        out["drag_update_ms_p95_lens"] = max(out[f"drag_update_ms_p95_{k}_fixed_lens"] for k in range(3))
        return out
    out["drag_update_ms_p95"] = max(out[f"drag_update_ms_p95_{k}_fixed"] for k in range(3))
    out["drag_time_ratio_vs_reference"] = float(np.median([out[f"drag_update_ms_median_{k}_fixed"]
                                                           / out[f"reference_drag_solve_ms_median_{k}_fixed"]
                                                           for k in range(3)]))
    return out


def _recalibration_problem(n_boxes: int, seed: int) -> Problem:
    rng = np.random.default_rng(seed)
    _, start, pins, photos = model_scene(rng, n_boxes=n_boxes, n_photos=8)
    cov = np.diag([25.0, 25.0, 25.0] + [np.radians(0.2) ** 2] * 3 + [0.02**2] * 3)
    cams = {}
    for p in photos.values():
        R = exp_so3(rng.normal(0.0, np.radians(0.2), 3)) @ p.R
        cams[p.id] = ImageCamera(p.id, p.K, R, p.C + rng.normal(0.0, 0.02, 3), p.width, p.height, covariance=cov)
    model = model_from_dict(start["nodes"], MARKERS)
    return Problem(model, cams, [Pin(p["photo"], p["node"], p["handle"], np.array(p["uv"])) for p in pins],
                   options=ProblemOptions(click_sigma_px=0.7, prior_scale=FINAL_PRIOR_SCALE, recalibrate=True),
                   markers=MarkerData(MARKERS, fixed=["O"]))


def recalibration(sizes: tuple[int, ...], reference_sizes: tuple[int, ...], progress: bool) -> dict[str, Any]:
    out: dict[str, Any] = {"recalibration_photos": 8}
    for n in Bar(sizes, desc="bench solver: re-calibration", unit="size", disable=not progress):
        problem = _recalibration_problem(n, seed=n)
        t0 = time.perf_counter()
        res = problem.solve(robust=True)
        out[f"recalibration_s_{n}"] = time.perf_counter() - t0
        out[f"recalibration_iterations_{n}"] = res.iterations
        out[f"recalibration_parameters_{n}"] = problem.n
        if n in reference_sizes:
            problem = _recalibration_problem(n, seed=n)
            lo, hi = problem.bounds()
            t0 = time.perf_counter()
            least_squares(problem.residuals, np.clip(problem.x0(), lo, hi), jac=problem.jacobian, bounds=(lo, hi),
                          method="trf", tr_solver="lsmr", x_scale="jac", loss="soft_l1", f_scale=3.0)
            out[f"reference_recalibration_s_{n}"] = time.perf_counter() - t0
            out[f"recalibration_time_ratio_vs_reference_{n}"] = (out[f"recalibration_s_{n}"]
                                                                 / out[f"reference_recalibration_s_{n}"])
    if len(sizes) >= 2:
        a, b = sizes[0], sizes[-1]
        out["recalibration_growth_exponent"] = float(np.log(out[f"recalibration_s_{b}"] / out[f"recalibration_s_{a}"])
                                                     / np.log(b / a))
    return out


def run(quick: bool = False, progress: bool = True) -> dict[str, Any]:
    fig = drags()
    fig.update(drags(lens=True))
    fig.update(recalibration((10, 50) if quick else (10, 50, 200), (10,), progress))
    fig["goals_met"] = bool(fig["drag_update_ms_p95"] <= GOALS["drag_update_ms_p95"]
                            and fig["drag_update_ms_p95_lens"] <= GOALS["drag_update_ms_p95"]
                            and fig["recalibration_s_50"] <= GOALS["recalibration_s_50"]
                            and fig.get("recalibration_growth_exponent", 1.0) <= 1.15)
    return fig


def table(fig: dict[str, Any]) -> str:
    lines = ["solver benchmark", "", f"{'drag update (ms)':<28}{'median':>10}{'p95':>10}{'scipy trf median':>18}"
             f"{'fixed vertex max (px)':>24}"]
    for k in range(3):
        lines.append(f"{f'{k} vertices fixed':<28}{fig[f'drag_update_ms_median_{k}_fixed']:>10.2f}"
                     f"{fig[f'drag_update_ms_p95_{k}_fixed']:>10.2f}{fig[f'reference_drag_solve_ms_median_{k}_fixed']:>18.2f}"
                     f"{fig[f'drag_fixed_vertex_error_px_max_{k}_fixed']:>24.3f}")
    if "drag_update_ms_p95_lens" in fig:
        lines.append(f"through a wide lens (corners moved {fig['lens_corner_displacement_px']:.0f} px):")
        for k in range(3):
            lines.append(f"{f'{k} vertices fixed':<28}{fig[f'drag_update_ms_median_{k}_fixed_lens']:>10.2f}"
                         f"{fig[f'drag_update_ms_p95_{k}_fixed_lens']:>10.2f}{'':>18}"
                         f"{fig[f'drag_fixed_vertex_error_px_max_{k}_fixed_lens']:>24.3f}")
    lines += ["", f"{'re-calibration, 8 photos':<28}{'time (s)':>10}{'unknowns':>10}{'iterations':>12}"
              f"{'scipy trf (s)':>16}"]
    for n in (10, 50, 200):
        if f"recalibration_s_{n}" in fig:
            ref = fig.get(f"reference_recalibration_s_{n}")
            lines.append(f"{f'{n} primitives':<28}{fig[f'recalibration_s_{n}']:>10.3f}"
                         f"{fig[f'recalibration_parameters_{n}']:>10d}{fig[f'recalibration_iterations_{n}']:>12d}"
                         f"{(f'{ref:.3f}' if ref else '—'):>16}")
    if "recalibration_growth_exponent" in fig:
        lines.append(f"time grows as (primitives)^{fig['recalibration_growth_exponent']:.2f}")
    lines.append(f"goals (drag p95 ≤ 5 ms, 50 primitives ≤ 1 s, growth no worse than linear): "
                 f"{'met' if fig['goals_met'] else 'NOT met'}")
    return "\n".join(lines)
