"""The demo's last words: why a check distance falls outside its interval, where the example's
truth says, and a five-line summary (what was rebuilt, how close to the truth, the checks, where
the outputs are, what to open next).

The example's truth is exact (its markers' positions, its cameras), and its clicks are the true
projections plus the generator's noise (N(0, σ) per coordinate, σ the project's
``click_sigma_px``). A check distance outside its 95 % interval is then either one of those noisy
clicks drawn far out, which the interval allows one time in twenty, or a fault: the line says which,
from the click of the check's ends that lies farthest from its true projection.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from vebuild.camera import Lens, log_so3
from vebuild.camera import project as project_points

#: A click at least this many σ from its true place (its 2-D distance over σ; a χ₂ draw beyond it
#: happens about once in 7 clicks) can explain a check outside its interval; where every end's click
#: lies closer, the line says the clicks do not explain it.
FAR_CLICK_SIGMAS = 2.0


def _farthest_click(project: Any, name: str, truth: dict) -> tuple[str, float, float] | None:
    """The click of marker ``name`` farthest from its true projection: (photo, px, in σ)."""
    sigma = float(project.settings["click_sigma_px"])
    best = None
    for photo in project.data["photos"]:
        t = (truth.get("photos") or {}).get(photo["id"])
        obs = photo.get("marker_observations") or {}
        if t is None or name not in obs or name not in (truth.get("markers") or {}):
            continue
        k1 = float((t.get("distortion") or {}).get("k1", 0.0))
        uv = project_points(t["K"], t["R"], t["C"], np.asarray(truth["markers"][name], float),
                            Lens(k1, float((t.get("distortion") or {}).get("k2", 0.0))))
        d = float(np.linalg.norm(np.asarray(obs[name], float) - uv))
        if best is None or d > best[1]:
            best = (photo["id"], d, d / sigma)
    return best


def _most_off(project: Any, names: tuple[str, str], truth: dict) -> tuple[str, float, float] | None:
    """Of the check's two markers, the one placed farthest from its true place in its own σ (the
    final model's markers, else the calibration's): (marker, metres off, in σ)."""
    data = project.data
    placed = (data.get("model_solution") or {}).get("markers") or (data.get("calibration") or {}).get("markers") or {}
    best = None
    for n in names:
        if n not in placed or n not in (truth.get("markers") or {}):
            continue
        err = np.asarray(placed[n]["position"], float) - np.asarray(truth["markers"][n], float)
        sig = np.asarray(placed[n]["sigma"], float)
        z = float(np.max(np.abs(err) / np.where(sig > 0, sig, np.inf)))
        if best is None or z > best[2]:
            best = (n, float(np.linalg.norm(err)), z)
    return best


def check_explanations(project: Any, checks: list[dict], truth: dict) -> list[str]:
    """One plain line for each check the final model puts outside its 95 % interval."""
    out = []
    for c in checks:
        if c.get("within_ci95", True):
            continue
        known = truth.get("markers") or {}
        head = f"  why {c['a']}–{c['b']} is outside: "
        if c["a"] in known and c["b"] in known:
            tape = float(np.linalg.norm(np.asarray(known[c["a"]]) - np.asarray(known[c["b"]])))
            if abs(tape - c["known_m"]) >= 1e-4:
                out.append(head + f"the example's truth is {tape:.4f} m but its tape says {c['known_m']:.4f} m: the "
                           "example's known distance is wrong")
                continue
        off = _most_off(project, (c["a"], c["b"]), truth)
        far = _farthest_click(project, off[0], truth) if off is not None else None
        if off is None or far is None:
            out.append(head + "its ends cannot be compared with the example's truth (no true marker or camera)")
            continue
        n, metres, z_pos = off
        pid, px, z = far
        marked = sum(1 for p in project.data["photos"] if n in (p.get("marker_observations") or {}))
        chance = math.exp(-z * z / 2.0)  # P(χ²₂ > z²): a click at least this far off
        said = (f"the example's truth is the known {c['known_m']:.4f} m; {n} comes out {1000 * metres:.0f} mm from "
                f"its true place ({z_pos:.1f}σ), marked in {marked} photos, and its click in {pid} lies {px:.1f} px "
                f"from its true place ({z:.1f}σ of the example's click noise; about 1 click in {1 / chance:.0f} "
                "lies as far out)")
        if z >= FAR_CLICK_SIGMAS:
            out.append(head + said + ": the solve follows the clicks, and a check lies outside its 95 % interval "
                       "about one time in 20")
        else:
            out.append(head + said + ": no click lies far out, so the clicks' noise does not explain it")
    return out


def summary(project: Any, model: dict, truth: dict | None, out: Any, textured_faces: int) -> str:
    """Five lines: rebuilt, against the truth, the checks, the outputs, what to open next."""
    nodes = model.get("nodes") or {}
    cams = (project.data.get("model_solution") or {}).get("cameras") or \
        (project.data.get("calibration") or {}).get("cameras") or {}
    lines = ["summary:",
             f"  rebuilt: the example room from its {len(project.data['photos'])} photos: {len(cams)} cameras, "
             f"{len(nodes)} parts of the model, textures on {textured_faces} faces"]
    if truth and "model" in truth:
        true_nodes = {n["name"]: n for n in truth["model"]["nodes"]}
        true_params = {name: (n.get("primitive") or {}).get("params") or {} for name, n in true_nodes.items()}
        errs = [abs(v["value"] - true_params[name][k]) for name, node in nodes.items()
                for k, v in node["params"].items() if v.get("sigma") and k in true_params.get(name, {})]
        f_err, rot, pos = [], [], []
        for pid, cam in cams.items():
            t = truth["photos"][pid]
            f_err.append(abs(cam["focal_px"]["value"] / t["K"][0][0] - 1.0))
            rot.append(float(np.degrees(np.linalg.norm(log_so3(np.asarray(t["R"]) @ np.asarray(cam["R"]).T)))))
            pos.append(float(np.linalg.norm(np.asarray(cam["position"]["value"]) - np.asarray(t["C"]))))
        errs = errs or [0.0]
        lines.append(f"  against the truth: dimensions {1000 * float(np.median(errs)):.1f} mm off in the median "
                     f"(at most {1000 * max(errs):.1f} mm); cameras within {100 * max(f_err):.2f} % in focal "
                     f"length, {max(rot):.2f}° and {100 * max(pos):.1f} cm")
    checks = model.get("check_distances") or []
    outside = [f"{c['a']}–{c['b']}" for c in checks if not c.get("within_ci95", True)]
    lines.append(f"  check distances: {len(checks) - len(outside)} of {len(checks)} within their 95 % interval"
                 + (f"; outside: {', '.join(outside)} (why: above)" if outside else ""))
    lines.append(f"  outputs: {out / 'room.vebuild.json'}, its textures in {out / 'textures'}, renders in "
                 f"{out / 'renders'}")
    lines.append(f"  next: `vebuild view {out / 'room.vebuild.json'}` to walk through it; `vebuild report "
                 f"{out / 'room.vebuild.json'} --out {out / 'report'}` for the report")
    return "\n".join(lines)
