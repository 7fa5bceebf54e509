"""The stages kept apart (issue 17, "uncertainty counted once"), on the example room.

A re-calibrating solve writes its cameras and markers into ``model_solution``, never into
``calibration``, and always starts from the calibration stage's priors: re-running it gives the
same figures. A check distance on a model vertex waits for the solve, which reports every check
distance from the final model. Pins in a photo without a camera are named, not dropped silently.
"""

from __future__ import annotations

import copy
import json
import re
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from vebuild.calibration.lm import levenberg_marquardt
from vebuild.cli import main
from vebuild.constants import Z95
from vebuild.errors import ProjectError

EXAMPLE = Path(__file__).resolve().parents[1] / "scenes" / "room"

#: How far two runs of the same solve may end apart, per figure, in units of its 1σ.
#: Levenberg–Marquardt (vebuild.calibration.lm, tol = 1e-10, the solver's default) stops once a step
#: lowers the cost ½‖r‖² by less than tol × cost. Near the minimum the cost is quadratic in the
#: whitened parameters z, so the end point lies ‖δz‖ ≲ √(2 · tol · cost / (1 − ρ)) from the
#: minimum, ρ ≤ 0.9 being the linear rate of the damped steps' convergence; any figure f (a
#: linear function of the parameters near the minimum) then moves by at most σ_f · ‖δz‖. On the
#: example room the cost is about 64 (≈ 320 whitened rows at 0.63 px RMS with a 1 px click σ),
#: so each run ends within 3.6e-4 σ of the minimum and two runs within 7.2e-4 σ of each other: the
#: bound is 1e-3 σ. (Runs 2 and 3 restart from run 1's solved values in ``model.nodes``; the weak
#: pull toward the start, 1e5 × PRIOR_SIGMA, moves the end point by (σ/1e4 m)² of the restart's
#: shift, far below.) Measured: 1.8e-5 σ at most.
FIGURE_TOL_SIGMA = 1e-3
#: The same bound, relative, for a 1σ (and a covariance entry, relative to √(Cᵢᵢ Cⱼⱼ)): the
#: Jacobian at two end points 1e-3 σ apart differs by far less than that share. Measured: 8e-7.
SIGMA_TOL_REL = 1e-3
#: Below this a 1σ is zero (a coordinate fixed exactly, e.g. a hinge's foot on the floor): its
#: two runs may differ by rounding, 1e-19 m measured.
SIGMA_FLOOR = 1e-12
#: Image residuals move with the end point by at most ‖δz‖ click σ (1 px): 1e-3 px.
RESIDUAL_TOL_PX = 1e-3
#: Keys that are no figure of the solution: how many iterations it took, who wrote it, and the
#: hashes of what it read (``computed_from``, vebuild.project.provenance: each run reads the solved
#: values the run before wrote into ``model.nodes``, equal only within the tolerances above).
NOT_FIGURES = {"iterations", "software", "computed_from"}


def _sigmas(s: Any) -> np.ndarray:
    return np.atleast_1d(np.asarray([np.inf if v is None else v for v in np.atleast_1d(s)], float))


def _compare(a: Any, b: Any, path: str = "$") -> Iterator[str]:
    """Every figure of b that differs from a's by more than the tolerances above, in words."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), f"{path}: keys {sorted(a)} vs {sorted(b)}"
        if "measured_m" in a:  # a check distance: its figures within the tolerance of its 1σ
            tol = FIGURE_TOL_SIGMA * (1 + 1.96) * a["difference_sigma_m"] + SIGMA_FLOOR
            for k, v in a.items():
                if k.endswith("_m") and np.any(np.abs(np.subtract(v, b[k])) > tol):
                    yield f"{path}.{k}: {v} vs {b[k]}"
                elif not k.endswith("_m") and v != b[k]:
                    yield f"{path}.{k}: {v!r} vs {b[k]!r}"
            return
        value = "value" if "value" in a else "position" if "position" in a else None
        if value and "sigma" in a:
            va, vb = np.atleast_1d(np.asarray(a[value], float)), np.atleast_1d(np.asarray(b[value], float))
            sa, sb = _sigmas(a["sigma"]), _sigmas(b["sigma"])
            s = np.where(np.isfinite(sa), sa, 0.0)
            if np.any(np.abs(va - vb) > FIGURE_TOL_SIGMA * s + SIGMA_FLOOR):
                yield f"{path}.{value}: {va} vs {vb} (1σ {sa})"
            same_inf = np.isinf(sa) == np.isinf(sb)
            with np.errstate(invalid="ignore"):
                off = np.abs(sa - sb) > SIGMA_TOL_REL * s + SIGMA_FLOOR
            if not np.all(same_inf) or np.any(off & np.isfinite(sa)):
                yield f"{path}.sigma: {sa} vs {sb}"
            if "ci95" in a and a["ci95"] is not None:
                ca, cb = np.asarray(a["ci95"], float), np.asarray(b["ci95"], float)
                if np.any(np.abs(ca - cb) > (FIGURE_TOL_SIGMA + 1.96 * SIGMA_TOL_REL) * s + SIGMA_FLOOR):
                    yield f"{path}.ci95: {ca} vs {cb}"
            rest = set(a) - {value, "sigma", "ci95"}
        else:
            rest = set(a)
        for k in sorted(rest - NOT_FIGURES):
            yield from _compare(a[k], b[k], f"{path}.{k}")
        return
    if isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"{path}: {len(a)} vs {len(b)} entries"
        if path.endswith(("covariance", "matrix")) and a and isinstance(a[0], list):
            A, B = (np.array([[np.inf if v is None else v for v in r] for r in m], float) for m in (a, b))
            d = np.sqrt(np.abs(np.outer(np.diag(A), np.diag(A))))
            fin = np.isfinite(A)
            if not np.array_equal(fin, np.isfinite(B)) or np.any(np.abs(A - B)[fin] > SIGMA_TOL_REL * 2 * d[fin]
                                                                   + SIGMA_FLOOR**2):
                yield f"{path}: the covariance differs"
            return
        if "residual" in path:
            if np.any(np.abs(np.asarray(a, float) - np.asarray(b, float)) > RESIDUAL_TOL_PX):
                yield f"{path}: {a} vs {b}"
            return
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            yield from _compare(x, y, f"{path}[{i}]")
        return
    if path.endswith(("rms_px", "variance_factor")):
        if abs(a - b) > RESIDUAL_TOL_PX:
            yield f"{path}: {a} vs {b}"
    elif re.search(r"\.(K|R)(\[\d+\])*$", path):
        return  # the same numbers as focal_px, principal_point and ypr_deg, compared with their 1σ
    elif a != b:
        yield f"{path}: {a!r} vs {b!r}"


def test_the_tolerance_names_the_solvers_convergence_test() -> None:
    """FIGURE_TOL_SIGMA is derived from the LM's relative cost test at its default tol = 1e-10."""
    import inspect

    assert inspect.signature(levenberg_marquardt).parameters["tol"].default == 1e-10
    assert np.sqrt(2 * 1e-10 * 64 / (1 - 0.9)) * 2 < FIGURE_TOL_SIGMA


def test_the_comparison_sees_a_figure_moved_beyond_its_tolerance() -> None:
    a = {"nodes": {"box": {"params": {"width": {"value": 0.6, "sigma": 0.001, "ci95": [0.598, 0.602]}}}},
         "markers": {"T1": {"position": [1.0, 2.0, 0.7], "sigma": [0.002, 0.002, 0.001]}},
         "covariance": {"parameters": ["box.width"], "matrix": [[1e-6]]}, "iterations": 7}
    assert not list(_compare(a, copy.deepcopy(a) | {"iterations": 9}))
    for change in (lambda b: b["nodes"]["box"]["params"]["width"].update(value=0.6 + 2e-3 * 0.001),
                   lambda b: b["nodes"]["box"]["params"]["width"].update(sigma=0.00101),
                   lambda b: b["markers"]["T1"]["position"].__setitem__(2, 0.7 + 2e-6),
                   lambda b: b["covariance"]["matrix"][0].__setitem__(0, 1.01e-6)):
        b = copy.deepcopy(a)
        change(b)
        assert list(_compare(a, b)), change


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("stages") / "room"
    shutil.copytree(EXAMPLE, folder)
    path = folder / "room.vebuild.json"
    assert main(["calibrate", str(path), "--quiet"]) == 0
    return path


def _copy(path: Path, folder: Path) -> Path:
    shutil.copytree(path.parent, folder)
    return folder / path.name


def _solve(path: Path, *flags: str) -> dict[str, Any]:
    assert main(["solve", str(path), *flags]) == 0
    return json.loads(path.read_text())


def _mismatches(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    return list(_compare(a, b))


def test_recalibrating_three_times_gives_the_first_runs_figures(calibrated, tmp_path, capsys) -> None:
    path = _copy(calibrated, tmp_path / "room")
    calibration = json.loads(path.read_text())["calibration"]
    runs = [_solve(path, "--recalibrate")]
    # A re-run on unchanged inputs that reproduces the recorded figures keeps them (the next test's
    # subject); to measure the solve itself, runs 2 and 3 start without a recorded solution, from
    # the solved values run 1 wrote into model.nodes.
    for _ in range(2):
        data = json.loads(path.read_text())
        del data["model_solution"]
        path.write_text(json.dumps(data))
        runs.append(_solve(path, "--recalibrate"))
    capsys.readouterr()
    for k, doc in enumerate(runs):
        # The calibration stage is untouched: it stays the prior of every re-calibration.
        assert doc["calibration"] == calibration, f"run {k + 1} wrote into calibration"
        sol = doc["model_solution"]
        assert sol["recalibrated"] and set(sol["cameras"]) == set(calibration["cameras"])
        assert all(c["recalibrated"] for c in sol["cameras"].values())
        assert set(sol["markers"]) <= set(calibration["markers"]) and sol["markers"]
    first = runs[0]["model_solution"]
    for k in (1, 2):
        bad = _mismatches(first, runs[k]["model_solution"])
        assert not bad, f"run {k + 1} differs from run 1: " + "; ".join(bad[:8])
    # The symptom: the table's width σ shrank run after run (1.0 → 0.8 → 0.8 mm here).
    widths = [r["model_solution"]["nodes"]["table.top"]["params"]["width"]["sigma"] for r in runs]
    assert widths[2] >= widths[0] * (1 - SIGMA_TOL_REL) and widths[1] >= widths[0] * (1 - SIGMA_TOL_REL), widths


def test_a_rerun_that_reproduces_the_figures_keeps_the_recorded_solution(calibrated, tmp_path, capsys) -> None:
    """Solving again on unchanged inputs, the same way, gives the recorded figures within the solver's
    tolerance: the recorded solution and model stand, byte for byte, and nothing made from them turns
    stale. Solved another way (plain after re-calibrating) the solution is written anew."""
    path = _copy(calibrated, tmp_path / "room")
    _solve(path, "--recalibrate")
    text = path.read_text()
    _solve(path, "--recalibrate")
    assert path.read_text() == text
    assert not _solve(path)["model_solution"]["recalibrated"]
    capsys.readouterr()


def test_plain_and_recalibrating_solves_in_either_order(calibrated, tmp_path, capsys) -> None:
    """A plain solve after a re-calibrating one writes no cameras and gives a plain solve's figures;
    a re-calibrating one after a plain one gives a re-calibration's."""
    path = _copy(calibrated, tmp_path / "room")
    plain = _solve(path)["model_solution"]
    recal = _solve(path, "--recalibrate")["model_solution"]
    plain2 = _solve(path)["model_solution"]
    recal2 = _solve(path, "--recalibrate")["model_solution"]
    capsys.readouterr()
    assert "cameras" not in plain and "markers" not in plain and not plain["recalibrated"]
    assert "cameras" not in plain2 and "markers" not in plain2
    assert not (bad := _mismatches(plain, plain2)), "; ".join(bad[:8])
    assert not (bad := _mismatches(recal, recal2)), "; ".join(bad[:8])
    # The two stages do differ: re-calibration moves the cameras and the model with them.
    w0, w1 = (s["nodes"]["table.top"]["params"]["width"] for s in (plain, recal))
    assert abs(w0["value"] - w1["value"]) > FIGURE_TOL_SIGMA * w0["sigma"]


def test_later_stages_use_the_recalibrated_cameras_and_markers(calibrated, tmp_path, capsys) -> None:
    from vebuild.project import decode, load_project

    path = _copy(calibrated, tmp_path / "room")
    _solve(path, "--recalibrate")
    capsys.readouterr()
    project = load_project(path)
    final, prior = decode.cameras(project), decode.cameras_from_calibration(project)
    recal = project.data["model_solution"]["cameras"]
    for pid, cam in final.items():
        assert cam.K.tolist() == recal[pid]["K"] and cam.C.tolist() == recal[pid]["position"]["value"]
        assert prior[pid].K.tolist() == project.data["calibration"]["cameras"][pid]["K"]
        assert decode.photo_camera(project, pid).K.tolist() == recal[pid]["K"]
    markers = decode.markers(project.data, "final")
    sigmas = decode.marker_sigmas(project.data, "final")
    for name, rec in project.data["model_solution"]["markers"].items():
        assert markers[name].tolist() == rec["position"] and sigmas[name].tolist() == rec["sigma"]
        assert decode.known_points(project.data)[name].tolist() == rec["position"]
    origin = project.data["calibration"]["origin_marker"]
    assert origin not in project.data["model_solution"]["markers"]  # held at the origin: not re-calibrated
    assert markers[origin].tolist() == project.data["calibration"]["markers"][origin]["position"]
    # The calibration's own fit stays with the calibration; the record has the re-calibration's residuals.
    p1 = recal["p1"]
    assert "vanishing_points" not in p1 and set(p1["marker_residuals_px"]) == \
        set(project.data["photos"][0]["marker_observations"])


def test_a_calibration_overwritten_by_an_older_vebuild_is_refused(calibrated, tmp_path, capsys) -> None:
    from vebuild.project import decode, load_project

    path = _copy(calibrated, tmp_path / "room")
    data = json.loads(path.read_text())
    data["calibration"]["cameras"]["p3"]["recalibrated"] = True  # as `solve --recalibrate` wrote it before
    path.write_text(json.dumps(data))
    project = load_project(path)
    with pytest.raises(ProjectError, match=r"\$\.calibration\.cameras\.p3\.recalibrated: .*older vebuild.*"
                                           r"Run `vebuild calibrate` again"):
        decode.cameras(project)
    assert main(["solve", str(path), "--recalibrate"]) != 0
    err = capsys.readouterr().err
    assert "$.calibration.cameras.p3.recalibrated" in err and "Traceback" not in err
    assert json.loads(path.read_text()) == data  # nothing written
    # Calibrating again gives a calibration stage of its own, and the solve runs.
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["solve", str(path), "--recalibrate"]) == 0


def test_a_check_distance_on_a_model_vertex_waits_for_the_solve(tmp_path, capsys) -> None:
    folder = tmp_path / "room"
    shutil.copytree(EXAMPLE, folder)
    path = folder / "room.vebuild.json"
    data = json.loads(path.read_text())
    # T2 sits on the table top's corner v5 (the truth); cabinet:v0 is pinned in no photo, table.top:v1
    # in several (the calibration ties photos with it, and until now measured this check itself).
    checks = [("T2", "table.top:v1", 0.04), ("cabinet:v0", "C1", 2.0)]
    for a, b, dist in checks:
        data["reference_distances"].append({"a": a, "b": b, "distance": dist, "sigma": 0.002, "role": "check"})
    path.write_text(json.dumps(data, indent=1))
    assert main(["calibrate", str(path)]) == 0
    out = capsys.readouterr().out
    cal = json.loads(path.read_text())["calibration"]
    assert [(d["a"], d["b"]) for d in cal["checked_after_solve"]] == [(a, b) for a, b, _ in checks]
    assert {(d["a"], d["b"]) for d in cal["reference_distances"]} == {("O", "X5"), ("O", "Y4"), ("T2", "C1")}
    assert not any("table.top:v1" in w or "cabinet:v0" in w for w in cal["warnings"])
    assert "T2–table.top:v1  check  known 0.040 ± 0.002   ends on a model vertex: checked on the solved model by " \
           "`vebuild solve`" in out
    for flags in ((), ("--recalibrate",)):
        sol = _solve(path, *flags)["model_solution"]
        out = capsys.readouterr().out
        got = {(c["a"], c["b"]): c for c in sol["check_distances"]}
        assert set(got) == {("T2", "C1"), *((a, b) for a, b, _ in checks)}
        for (a, b), c in got.items():
            assert c["difference_m"] == pytest.approx(c["measured_m"] - c["known_m"], abs=1e-15)
            assert c["difference_ci95_m"] == pytest.approx([c["difference_m"] - Z95 * c["difference_sigma_m"],
                                                            c["difference_m"] + Z95 * c["difference_sigma_m"]])
            assert c["within_ci95"] == (abs(c["difference_m"]) <= Z95 * c["difference_sigma_m"])
            verdict = "within" if c["within_ci95"] else "OUTSIDE"
            assert f"  {a}–{b}  measured {c['measured_m']:.4f} ± {c['measured_sigma_m']:.4f}" in out
            assert f"{verdict} its 95 % interval" in out
        # The table top is 0.04 m thick (the truth): T2 (on v5) to v1 measures it, within its interval.
        t = got[("T2", "table.top:v1")]
        assert abs(t["measured_m"] - 0.04) < 3 * t["measured_sigma_m"] + 0.002 and t["within_ci95"]
        # The cabinet's corner is nowhere near 2 m from C1: the check fails, and says so.
        assert not got[("cabinet:v0", "C1")]["within_ci95"]


def test_a_scale_distance_on_a_vertex_keeps_its_part(tmp_path, capsys) -> None:
    """A scale distance on a model vertex is still used: by calibration where the vertex ties photos
    (pinned in two), by the re-calibration in any case; it is not deferred like a check."""
    folder = tmp_path / "room"
    shutil.copytree(EXAMPLE, folder)
    path = folder / "room.vebuild.json"
    data = json.loads(path.read_text())
    data["reference_distances"].append({"a": "O", "b": "floor:v1", "distance": 5.0, "sigma": 0.002,
                                        "role": "scale"})
    path.write_text(json.dumps(data, indent=1))
    assert main(["calibrate", str(path), "--quiet"]) == 0
    cal = json.loads(path.read_text())["calibration"]
    assert not cal["checked_after_solve"]
    assert ("O", "floor:v1") in {(d["a"], d["b"]) for d in cal["reference_distances"]}
    assert main(["solve", str(path), "--recalibrate"]) == 0


def test_pins_in_a_photo_without_a_camera_are_named(calibrated, tmp_path, capsys) -> None:
    from vebuild.project import decode, load_project

    path = _copy(calibrated, tmp_path / "room")
    data = _solve(path, "--recalibrate")
    # The camera deleted after a re-calibration: its re-calibrated one, made from it, is not used.
    del data["calibration"]["cameras"]["p4"]
    path.write_text(json.dumps(data))
    project = load_project(path)
    assert "p4" in project.data["model_solution"]["cameras"]
    assert "p4" not in decode.cameras(project) and "p4" not in decode.camera_records(project.data)
    n_pins = sum(p["photo"] == "p4" for p in data["model"]["pins"])
    n_edges = sum(e["photo"] == "p4" for e in data["model"]["edge_observations"])
    assert n_pins > 0
    for flags in ((), ("--recalibrate",)):
        sol = _solve(path, *flags)["model_solution"]
        out = capsys.readouterr().out
        words = f"{n_pins} pins" + (f" and {n_edges} edge observation{'s' if n_edges != 1 else ''}" if n_edges else "")
        want = (f"photo 'p4' has no calibrated camera, so its {words} are left out of the solve; give it a camera "
                "with `vebuild calibrate` (it has vanishing segments), then solve again")
        assert sol["warnings"] == [want]
        assert f"warnings:\n  - {want}" in out
        assert not any(p["photo"] == "p4" for p in sol["pins"])
    # Every photo with a camera: no warning.
    doc = copy.deepcopy(json.loads(calibrated.read_text()))
    path.write_text(json.dumps(doc))
    assert _solve(path)["model_solution"]["warnings"] == []
    capsys.readouterr()


def test_pins_in_a_photo_never_calibrated_name_the_register_command(tmp_path, capsys) -> None:
    folder = tmp_path / "room"
    shutil.copytree(EXAMPLE, folder)
    path = folder / "room.vebuild.json"
    data = json.loads(path.read_text())
    data["photos"][4]["vanishing_segments"] = {}  # p5: left for `vebuild register`
    pid = data["photos"][4]["id"]
    path.write_text(json.dumps(data, indent=1))
    assert main(["calibrate", str(path), "--quiet"]) == 0
    sol = _solve(path)["model_solution"]
    capsys.readouterr()
    n = sum(p["photo"] == pid and p.get("fixed", True) for p in data["model"]["pins"])
    assert n > 0 and len(sol["warnings"]) == 1
    assert sol["warnings"][0].startswith(f"photo '{pid}' has no calibrated camera, so its {n} pins")
    assert sol["warnings"][0].endswith(f"give it a camera with `vebuild register PROJECT {pid}`, then solve again")


def test_the_modelling_screen_says_the_warnings_and_check_distances(calibrated, tmp_path) -> None:
    from vebuild.edit.session import EditSession

    path = _copy(calibrated, tmp_path / "room")
    data = json.loads(path.read_text())
    del data["calibration"]["cameras"]["p4"]
    path.write_text(json.dumps(data))
    s = EditSession.open(path)
    s.solve(recalibrate=True)
    assert any(m.startswith("photo 'p4' has no calibrated camera, so its ") for m in s.messages)
    c = s.data["model_solution"]["check_distances"][0]
    assert (c["a"], c["b"]) == ("T2", "C1")
    assert any(m.startswith("check distance T2–C1: ") and m.endswith(
        f"{'within' if c['within_ci95'] else 'OUTSIDE'} its 95 % interval") for m in s.messages)


def test_a_solution_that_moved_past_the_solvers_tolerance_is_not_the_recorded_one() -> None:
    """The recorded solution stands on a re-run only where every figure agrees within
    REPRODUCED_SIGMA of its 1σ: a node moved by 2 × that share of its 1σ is a different answer,
    and so is a 1σ grown by as much, or another set of outliers."""
    import copy

    from vebuild.actions.solve import REPRODUCED_SIGMA, reproduces

    old = {"outliers": [], "nodes": {"box": {
        "dofs": {"x": {"value": 1.0, "sigma": 0.002}},
        "params": {"width": {"value": 0.6, "sigma": 0.001}, "depth": {"value": 0.4, "sigma": 0.0}},
        "handles": {"v0": {"value": [1.0, 2.0, 0.0], "sigma": [0.002, 0.002, None]}}}}}
    assert reproduces(old, copy.deepcopy(old))
    near = copy.deepcopy(old)
    near["nodes"]["box"]["params"]["width"]["value"] += 0.5 * REPRODUCED_SIGMA * 0.001
    assert reproduces(old, near)
    for change in (lambda n: n["params"]["width"].update(value=0.6 + 2 * REPRODUCED_SIGMA * 0.001),
                   lambda n: n["params"]["width"].update(sigma=0.001 * (1 + 2 * REPRODUCED_SIGMA)),
                   lambda n: n["params"]["depth"].update(value=0.4 + 1e-6),  # held (σ 0): any change counts
                   lambda n: n["handles"]["v0"].update(sigma=[0.002, 0.002, 0.003]),
                   lambda n: n["dofs"].pop("x")):
        moved = copy.deepcopy(old)
        change(moved["nodes"]["box"])
        assert not reproduces(old, moved)
    assert not reproduces(old, {**copy.deepcopy(old), "outliers": [{"photo": "p1", "node": "box"}]})
