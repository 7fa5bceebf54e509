"""The model solver through the photos' lens distortion (the division model of vebuild/camera.py).

Synthetic scenes (vebuild.synthetic.model_scene) with pinhole pins, moved through a known barrel
distortion here (camera.distort_pixels), then the click noise added: the solver must recover the
boxes when it knows k1, a pinhole solve of the same pins must be measurably wrong, and
re-calibration must move a wrong k1 toward the truth.
"""

from __future__ import annotations

import numpy as np
import pytest
from jacobian_check import assert_jacobian_matches_differences
from lens_distortion import barrel_k1
from scipy.stats import chi2

from vebuild.calibration.positions import ReferenceDistance
from vebuild.camera import ImageCamera, Lens, distort_pixels, distortion_displacement_px, project
from vebuild.model.residuals import EdgeObservation, MarkerObservation, Pin
from vebuild.model.scene import model_from_dict
from vebuild.model.solution import solution_at
from vebuild.model.solver import FINAL_PRIOR_SCALE, MarkerData, Problem, ProblemOptions
from vebuild.synthetic import CLICK_NOISE_PX, ROOM, model_scene

MARKERS = {"O": np.zeros(3)}
def distorted_scene(seed: int, n_boxes: int = 2, n_photos: int = 3, noise_px: float = CLICK_NOISE_PX):
    """Truth, a perturbed start, the photos' cameras (each with its barrel k1) and pins: pinhole
    pixels of the true corners, distorted by each lens, then the click noise added."""
    rng = np.random.default_rng(seed)
    truth, start, pins, photos = model_scene(rng, n_boxes=n_boxes, n_photos=n_photos, noise_px=0.0)
    cams = {}
    for p in photos.values():
        cams[p.id] = ImageCamera(p.id, p.K, p.R, p.C, p.width, p.height, lens=Lens(barrel_k1(p.K, p.width, p.height)))
    out = []
    for p in pins:
        cam = cams[p["photo"]]
        uv = distort_pixels(cam.K, np.array(p["uv"]), cam.lens) + rng.normal(0.0, noise_px, 2)
        out.append(Pin(p["photo"], p["node"], p["handle"], uv))
    return (model_from_dict(truth["nodes"], MARKERS), model_from_dict(start["nodes"], MARKERS), cams, out, rng)


def test_the_scene_is_visibly_distorted() -> None:
    """The tests' lenses move the corners by tens of pixels: a pinhole model could not hide it."""
    _, _, cams, _, _ = distorted_scene(3)
    for cam in cams.values():
        assert distortion_displacement_px(cam.K, cam.width, cam.height, cam.lens) > 20.0


@pytest.mark.parametrize("k2", [0.0, -0.02])  # one term; a second, held (a wide lens's)
def test_the_jacobian_through_the_lens_agrees_with_central_differences(k2: float) -> None:
    """Pins, edges and marker sightings projected through each camera's k1, with k1 itself an
    unknown (re-calibration with intrinsics): the analytic columns (pose, f, c, k1, markers) and
    the differenced ones (the model's, and the cameras' effect on edges) against an independent
    central difference of the residual vector."""
    truth, _, cams, pins, rng = distorted_scene(21)
    markers = {"O": np.zeros(3), "A": np.array([1.0, 2.0, 0.0]), "B": np.array([3.0, 0.5, 0.0])}
    cov = np.diag([25.0] * 3 + [np.radians(0.2) ** 2] * 3 + [0.02**2] * 3)
    sightings, edges, cams_cov = [], [], {}
    for cid, c in cams.items():
        cam = ImageCamera(cid, c.K, c.R, c.C, c.width, c.height, covariance=cov, lens=Lens(c.lens.k1, k2))
        cams_cov[cid] = cam
        sightings += [MarkerObservation(cid, m, project(cam.K, cam.R, cam.C, X, cam.lens)) for m, X in markers.items()]
        a, b = truth.handle_world("box0", "v4"), truth.handle_world("box0", "v5")
        edges.append(EdgeObservation(cid, "box0", "e4", project(cam.K, cam.R, cam.C,
                                                                  np.array([a + 0.3 * (b - a), a + 0.7 * (b - a)]),
                                                                  cam.lens) + rng.normal(0, 2.0, (2, 2))))
    distances = [ReferenceDistance("A", "B", 2.5, 0.002), ReferenceDistance("O", "box0:v1", 2.0, 0.01)]
    problem = Problem(truth, cams_cov, pins, edges,
                      options=ProblemOptions(click_sigma_px=0.7, recalibrate=True, refine_intrinsics=True,
                                             k1_sigma={cid: 0.01 for cid in cams}),
                      markers=MarkerData(markers, ["O"], sightings, distances))
    layout = problem.layout
    assert all(b.k1_index is not None and b.names[-1].endswith(".k1") for b in layout.cameras.values())
    x = problem.x0()
    assert [x[b.k1_index] for b in layout.cameras.values()] == [c.lens.k1 for c in cams.values()]
    # Away from the start, where errors could hide.
    x[layout.model.slice] += rng.normal(0.0, 0.02, len(layout.model))
    for b in layout.cameras.values():
        x[b.start : b.pose_start] += rng.normal(0.0, 2.0, 3)
        x[b.pose_start : b.pose_start + 3] += rng.normal(0.0, 2e-3, 3)
        x[b.k1_index] *= 1.3
    for b in layout.markers.values():
        x[b.slice] += rng.normal(0.0, 0.01, 3)
    J, F = assert_jacobian_matches_differences(problem, layout, x)  # the bounds of tests/jacobian_check.py
    k1_cols = [b.k1_index for b in layout.cameras.values()]
    assert np.count_nonzero(J[: problem.n_data, k1_cols]) > 0.9 * np.count_nonzero(F[: problem.n_data, k1_cols])
    assert np.count_nonzero(F[: problem.n_data, k1_cols]) > 0  # k1 moves the pins: a real comparison


def _solve(model, cams, pins, **options):
    problem = Problem(model, cams, pins, options=ProblemOptions(click_sigma_px=CLICK_NOISE_PX,
                                                                prior_scale=FINAL_PRIOR_SCALE, **options))
    fit = problem.solve()
    return problem, fit, solution_at(problem, fit.x)


#: A size the pins determine: its 1σ from the click noise is below this (the rest, a floor corner
#: no photo sees, are undetermined and held by the final solve's faint pull).
DETERMINED_SIGMA_M = 0.05
#: An error beyond this many of its 1σ (from the injected click noise through the solve's
#: covariance) fails: by chance with p ≈ 6·10⁻⁵ per size.
Z_BOUND = 4.0
#: The pinhole solve of distorted pins must miss some size by at least this many of the
#: distortion-aware solve's 1σ. Measured over seeds 0–7 of this scene: 13.9–33.3 σ.
PINHOLE_BIAS_SIGMAS = 10.0


def test_sizes_from_distorted_pins_with_k1_known_and_a_pinhole_solve_is_biased() -> None:
    truth, start, cams, pins, _ = distorted_scene(2, n_boxes=3, n_photos=4)
    names = truth.parameter_names()
    true = truth.vector()

    def sizes(problem, fit, solution):
        sig = np.sqrt(np.diag(solution.covariance) / solution.variance_factor)  # from the click noise alone
        idx = [j for j, n in enumerate(problem.names) if n.rsplit(".", 1)[1] in ("width", "depth", "height")
               and sig[j] < DETERMINED_SIGMA_M]
        err = np.array([fit.x[j] - true[names.index(problem.names[j])] for j in idx])
        return err, sig[idx], float(np.sum(fit.residuals[: problem.n_data] ** 2)), problem.n_data - problem.n

    err, sig, chi2_lens, dof = sizes(*_solve(model_from_dict(start.to_dict(), MARKERS), cams, pins))
    assert len(err) >= 8, "the scene determines most sizes"
    worst = int(np.argmax(np.abs(err) / sig))
    assert np.all(np.abs(err) <= Z_BOUND * sig), \
        f"size error {err[worst] * 1e3:.1f} mm = {err[worst] / sig[worst]:.1f}σ"
    assert chi2.ppf(0.001, dof) < chi2_lens < chi2.ppf(0.999, dof), "through the lens, the pins fit as their noise"
    lo, hi = rms_band(len(err))
    assert lo < np.sqrt(np.mean((err / sig) ** 2)) < hi, "the sizes' 1σ are honest: neither too narrow nor too wide"

    pinhole = {k: ImageCamera(c.id, c.K, c.R, c.C, c.width, c.height) for k, c in cams.items()}
    err_p, _, chi2_pinhole, _ = sizes(*_solve(model_from_dict(start.to_dict(), MARKERS), pinhole, pins))
    bias = np.abs(err_p) / sig
    assert bias.max() > PINHOLE_BIAS_SIGMAS, f"pinhole bias only {bias.max():.1f}σ ({np.abs(err_p).max() * 1e3:.1f} mm)"
    assert np.abs(err_p).max() > 3 * np.abs(err).max()
    assert chi2_pinhole > chi2.ppf(0.999, dof), "a pinhole cannot fit distorted pins"


def rms_band(n: int) -> tuple[float, float]:
    """Two-sided band (99.9 %) on the RMS of n values of error / reported 1σ, as tests/test_model.py:
    n·RMS² follows χ² with n degrees of freedom for honest uncertainties."""
    return float(np.sqrt(chi2.ppf(0.0005, n) / n)), float(np.sqrt(chi2.ppf(0.9995, n) / n))


#: The calibration's covariance given to the cameras of the re-calibration test: f and c 5 px,
#: rotation 0.2°, position 2 cm (1σ), about what vebuild calibrate reports for such photos.
CAL_COV = np.diag([5.0**2] * 3 + [np.radians(0.2) ** 2] * 3 + [0.02**2] * 3)


def test_recalibration_refines_a_wrong_k1_toward_the_truth() -> None:
    """Each photo's k1 starts at half its true value with a 1σ of half its size (the truth 1σ away):
    the pins move it to within 3σ (the refined 1σ) of the truth, narrower than its prior, and
    closer to the truth over the photos than it started."""
    truth, start, cams, pins, _ = distorted_scene(2, n_boxes=3, n_photos=4)
    wrong = {k: ImageCamera(c.id, c.K, c.R, c.C, c.width, c.height, covariance=CAL_COV, lens=Lens(0.5 * c.lens.k1))
             for k, c in cams.items()}
    prior = {k: 0.5 * abs(c.lens.k1) for k, c in cams.items()}
    _, _, sol = _solve(start, wrong, pins, recalibrate=True, refine_intrinsics=True, k1_sigma=prior)
    before, after, z = [], [], []
    for k, c in cams.items():
        k1, s = sol.cameras[k].lens.k1, sol.k1_sigma[k]
        assert abs(k1 - c.lens.k1) <= 3 * s, f"photo {k}: k1 {k1:.4f}, truth {c.lens.k1:.4f}, 1σ {s:.4f}"
        z.append((k1 - c.lens.k1) / s)
        assert s < 0.5 * prior[k]
        before.append((wrong[k].lens.k1 - c.lens.k1) / c.lens.k1)
        after.append((k1 - c.lens.k1) / c.lens.k1)
    assert np.sqrt(np.mean(np.square(after))) < 0.5 * np.sqrt(np.mean(np.square(before)))
    lo, hi = rms_band(len(z))
    assert lo < np.sqrt(np.mean(np.square(z))) < hi, "the refined 1σ of k1 is honest both ways"
    # Held: no prior 1σ, the k1 stays as calibrated.
    _, _, held = _solve(start, wrong, pins, recalibrate=True, refine_intrinsics=True)
    assert all(held.cameras[k].lens.k1 == wrong[k].lens.k1 for k in cams) and not held.k1_sigma


def _project_file(tmp_path, seed: int, k1_scale: float, k1_sigma):
    """A project of the distorted scene: photos, the calibration's records (each camera's truth
    with CAL_COV, its k1 times ``k1_scale`` with 1σ ``k1_sigma(k1)``), the start model and its pins."""
    from vebuild.project import load_project
    from vebuild.project.file import save_project
    from vebuild.project.records import camera_record, distortion_record
    from vebuild.synthetic import SyntheticPhoto, write_project

    truth, start, cams, pins, _ = distorted_scene(seed, n_boxes=3, n_photos=4)
    photos = [SyntheticPhoto(c.id, "3vp", c.width, c.height, c.K, c.R, c.C) for c in cams.values()]
    path = write_project(tmp_path, photos, {"O": np.zeros(3), "A": np.array([1.0, 0.0, 0.0])})
    project = load_project(path)
    data = project.data
    data["markers"], data["reference_distances"] = [{"name": "O"}], []  # the scale is the cameras' own
    data["calibration"] = {"cameras": {}, "origin_marker": "O",
                           "markers": {"O": {"position": [0.0, 0.0, 0.0], "sigma": [0.0] * 3}}}
    for c in cams.values():
        k1 = k1_scale * c.lens.k1
        rec = camera_record(c.K, c.R, c.C, CAL_COV,
                            distortion_record(c.K, c.width, c.height, k1, k1_sigma(c.lens.k1) or 0.0, "user"))
        if k1_sigma(c.lens.k1) is None:
            rec["distortion"]["k1"]["sigma"] = None
        data["calibration"]["cameras"][c.id] = rec
    data["model"] = {"nodes": start.to_dict(), "edge_observations": [],
                     "pins": [{"photo": p.photo, "node": p.node, "handle": p.handle, "uv": [float(v) for v in p.uv],
                               "fixed": True} for p in pins]}
    save_project(project)
    return load_project(path), truth, cams


def test_solve_recalibrate_writes_the_refined_distortion_into_the_record(tmp_path) -> None:
    from vebuild.actions.solve import REFINED_SOURCE, solve_project

    project, truth, cams = _project_file(tmp_path, 2, 0.5, lambda k1: 0.5 * abs(k1))
    result = solve_project(project, recalibrate=True)
    assert not result["outliers"]
    recal = project.data["model_solution"]["cameras"]
    for cid, c in cams.items():
        d = recal[cid]["distortion"]
        k1, s = d["k1"]["value"], d["k1"]["sigma"]
        assert abs(k1 - c.lens.k1) <= 3 * s < 1.5 * abs(c.lens.k1), cid
        assert d["source"] == f"user; {REFINED_SOURCE}"
        K = np.array(recal[cid]["K"])
        assert d["corner_displacement_px"]["value"] == pytest.approx(
            distortion_displacement_px(K, c.width, c.height, Lens(k1)), rel=1e-12)
        assert d["corner_displacement_px"]["sigma"] > 0
        # The calibration's record, the next re-calibration's prior, keeps its own k1.
        assert project.data["calibration"]["cameras"][cid]["distortion"]["source"] == "user"
        assert project.data["calibration"]["cameras"][cid]["distortion"]["k1"]["value"] == 0.5 * c.lens.k1
    # Read back, the final cameras carry the refined k1, the calibration's the prior's.
    from vebuild.project.decode import cameras, cameras_from_calibration
    back, prior = cameras(project), cameras_from_calibration(project)
    assert all(back[cid].lens.k1 == recal[cid]["distortion"]["k1"]["value"] for cid in cams)
    assert all(prior[cid].lens.k1 == 0.5 * cams[cid].lens.k1 for cid in cams)
    # The solved sizes through the refined lens: within the claimed dimension tolerance.
    from claims import dimension_tolerance
    for node in truth.nodes:
        if node.name.startswith("box"):
            for k, v in result["nodes"][node.name]["params"].items():
                tv = float(node.primitive.params[node.primitive.PARAMS.index(k)])
                assert abs(v["value"] - tv) < dimension_tolerance(tv), f"{node.name}.{k}"


@pytest.mark.parametrize("sigma", [0.0, None])
def test_a_k1_without_a_prior_sigma_stays_as_calibrated(tmp_path, sigma) -> None:
    from vebuild.actions.solve import solve_project

    project, _, cams = _project_file(tmp_path, 2, 1.0, lambda k1: sigma)
    solve_project(project, recalibrate=True)
    for cid, c in cams.items():
        d = project.data["model_solution"]["cameras"][cid]["distortion"]
        assert d["k1"] == {"value": c.lens.k1, "sigma": sigma} and d["source"] == "user"


def test_a_negative_k1_sigma_is_refused_naming_its_field(tmp_path) -> None:
    from vebuild.actions.solve import solve_project
    from vebuild.errors import ProjectError

    project, _, _ = _project_file(tmp_path, 2, 1.0, lambda k1: 0.01)
    project.data["calibration"]["cameras"]["p2"]["distortion"]["k1"]["sigma"] = -0.01
    with pytest.raises(ProjectError, match=r"\$\.calibration\.cameras\.p2\.distortion\.k1\.sigma.*"
                                           r"expected the 1σ of k1 as a number ≥ 0 \(or null\), got -0\.01"):
        solve_project(project, recalibrate=True)


@pytest.fixture(scope="module")
def solved_distorted(tmp_path_factory):
    """The distorted scene's project, its k1 known (held) and solved: the analyses' model."""
    from vebuild.actions.solve import solve_project
    from vebuild.project.file import save_project

    project, truth, cams = _project_file(tmp_path_factory.mktemp("solved"), 2, 1.0, lambda k1: 0.0)
    solve_project(project)
    save_project(project)
    return project, truth, cams


def test_a_ray_from_a_distorted_click_passes_through_the_point_seen(solved_distorted) -> None:
    """A pixel where the lens shows a point of the model (a box's top-face centre, off the photo's
    centre where the lens bends most) is undistorted onto the ray to that very point; read as a
    pinhole's pixel, it would land centimetres away."""
    import dataclasses

    from vebuild.analysis.points import parse_point
    from vebuild.analysis.solved import SolvedModel
    from vebuild.camera import world_to_camera
    from vebuild.project.decode import cameras_from_calibration

    proj, _, _ = solved_distorted
    solved = SolvedModel.from_project(proj)
    cams = cameras_from_calibration(proj)
    tried = missed = 0
    for cid, cam in cams.items():
        for node in ("box0", "box1", "box2"):
            X = solved.world(parse_point(f"{node}@top", solved))
            if world_to_camera(cam.R, cam.C, X)[2] <= 0:
                continue
            project_uv = project(cam.K, cam.R, cam.C, X, cam.lens)
            u, v = float(project_uv[0]), float(project_uv[1])
            if not (0 <= u <= cam.width and 0 <= v <= cam.height):
                continue
            Y = solved.world(parse_point(f"photo:{cid}@{u!r},{v!r}", solved, resolve_camera=lambda h, n: cams[n]))
            if np.linalg.norm(Y - X) > 0.05:
                continue  # another surface hides it from this photo
            tried += 1
            # Undistortion is closed-form and the ray meets the face's triangles exactly: a
            # micrometre is rounding (the division model inverted at 1e-16, times metres).
            assert np.linalg.norm(Y - X) < 1e-6, (cid, node)
            pin = {cid: dataclasses.replace(cam, lens=Lens(0.0))}
            Z = solved.world(parse_point(f"photo:{cid}@{u!r},{v!r}", solved,
                                         resolve_camera=lambda h, n, pin=pin: pin[n]))
            # How far the lens moves that pixel, at the point's depth: the pinhole reading's miss.
            shift = np.linalg.norm(project(cam.K, cam.R, cam.C, X) - project_uv)
            if shift > 5.0:
                assert np.linalg.norm(Z - X) > 1e-3, (cid, node)
                missed += 1
    assert tried >= 3 and missed >= 2


def _polyline_distance(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Each point's distance from the polyline (n, 2)."""
    A, B = poly[:-1], poly[1:]
    d = B - A
    t = np.clip(np.einsum("pnk,nk->pn", points[:, None] - A[None], d) / np.maximum(np.sum(d * d, axis=1), 1e-30),
                0.0, 1.0)
    return np.min(np.linalg.norm(points[:, None] - (A[None] + t[..., None] * d[None]), axis=-1), axis=1)


def test_the_overlay_draws_edges_axes_and_horizon_through_the_lens(solved_distorted) -> None:
    """In the modelling screen's overlay of a distorted photo each straight model edge is a chain
    of lines within CURVE_TOL_PX of the true curve (its 3D points projected through the lens, 2001
    along it), where the straight chord between its ends strays by pixels (for edges inside the
    photo: outside it the lens model bends edges far more); the horizon's points lie on the
    horizon; handles sit where the lens puts them."""
    from vebuild.camera import undistort_pixels, world_to_camera
    from vebuild.edit.session import EditSession
    from vebuild.model.drag import CURVE_TOL_PX

    proj, _, _ = solved_distorted
    s = EditSession.open(proj.path, autosave=False)
    worst, chord_worst, n_edges = 0.0, 0.0, 0
    for cid, cam in s.cameras.items():
        assert not cam.lens.is_pinhole
        ov = s.overlay(cid)
        chains: dict = {}
        for ln in ov.of_kind("edge")[0]:
            chains.setdefault(ln.key, []).append(ln.p)
        model = s.model
        for (node, edge), pieces in chains.items():
            a, b = next((a, b) for e, a, b in model.node(node).primitive.edges() if e == edge)
            A, B = model.handle_world(node, a), model.handle_world(node, b)
            t = np.linspace(0.0, 1.0, 2001)[:, None]
            P = A + t * (B - A)
            assert np.all(world_to_camera(cam.R, cam.C, P)[:, 2] > 0)
            true = project(cam.K, cam.R, cam.C, P, cam.lens)
            poly = np.array([p[:2] for p in pieces] + [pieces[-1][2:]])
            assert all(np.allclose(p[2:], q[:2]) for p, q in zip(pieces[:-1], pieces[1:], strict=True)), "a chain"
            worst = max(worst, float(_polyline_distance(true, poly).max()))
            if np.all((true >= 0) & (true <= [cam.width, cam.height])):  # an edge inside the photo
                chord_worst = max(chord_worst, float(_polyline_distance(true, poly[[0, -1]]).max()))
            n_edges += 1
        for n, h, uv, _ in s.handles(cid):
            assert uv == pytest.approx(project(cam.K, cam.R, cam.C, model.handle_world(n, h), cam.lens), abs=1e-9)
        horizon = ov.of_kind("horizon")[0]
        if horizon:
            q = np.array([ln.p[:2] for ln in horizon] + [horizon[-1].p[2:]])
            line = np.linalg.inv(cam.K).T @ cam.R[:, 2]
            und = undistort_pixels(cam.K, q, cam.lens)
            assert np.all(np.abs(und @ line[:2] + line[2]) / np.linalg.norm(line[:2]) < 1e-6)
    assert n_edges > 20
    assert worst <= CURVE_TOL_PX, f"a drawn edge strays {worst:.3f} px from its curve"
    assert chord_worst > 3 * CURVE_TOL_PX, "the lens bends these edges: a straight line would not do"


def test_a_drag_in_a_distorted_photo_puts_the_handle_under_the_mouse(solved_distorted) -> None:
    """The mouse is in the photo's (distorted) pixels: the dragged corner follows it through the
    lens, and the pin it leaves is where the lens shows the corner."""
    from vebuild.edit.modelling import FOLLOW_TOL_PX
    from vebuild.edit.session import EditSession

    proj, _, _ = solved_distorted
    s = EditSession.open(proj.path, autosave=False)
    cid, node, handle, uv = next((c, n, h, uv) for c in s.cameras for n, h, uv, _ in s.handles(c)
                                 if n == "box1" and h == "v6")
    cam = s.cameras[cid]
    s.begin_drag(cid, node, handle)
    target = (uv[0] + 6.0, uv[1] - 4.0)
    fb = s.drag_to(target)
    assert fb.ok and np.hypot(fb.handle_px[0] - target[0], fb.handle_px[1] - target[1]) < FOLLOW_TOL_PX
    s.end_drag()
    X = s.model.handle_world(node, handle)
    assert np.hypot(*(project(cam.K, cam.R, cam.C, X, cam.lens) - target)) < FOLLOW_TOL_PX
    pin = next(p for p in s.data["model"]["pins"] if (p["photo"], p["node"], p["handle"]) == (cid, node, handle))
    assert pin["uv"] == pytest.approx(target)


def test_register_keeps_a_photos_known_lens(solved_distorted, tmp_path) -> None:
    """Re-registering a photo from the solved model's vertices (no vanishing segments) holds the
    k1 of its camera record: the record keeps that distortion, the mode reason says so, and the
    camera lands on the truth within 3σ of its reported uncertainty."""
    import shutil

    from vebuild.actions.register import register_photos
    from vebuild.project import load_project

    proj, _, cams = solved_distorted
    folder = tmp_path / "copy"
    shutil.copytree(proj.path.parent, folder)
    project = load_project(folder / proj.path.name)
    before = project.data["calibration"]["cameras"]["p2"]["distortion"]
    reg = register_photos(project, ["p2"])["p2"]
    rec = project.data["calibration"]["cameras"]["p2"]
    assert rec["mode"] == "registered" and "through its lens distortion (k1 " in rec["mode_reason"]
    assert rec["distortion"]["k1"] == before["k1"] and rec["distortion"]["source"] == before["source"]
    sigma = np.sqrt(np.diag(reg.covariance))
    truth = cams["p2"]
    assert abs(reg.K[0, 0] - truth.K[0, 0]) <= 3 * sigma[0]
    assert np.all(np.abs(reg.C - truth.C) <= 3 * sigma[6:9])
    # Without the record's distortion the photo is registered as a pinhole, and its focal length
    # misses by more than that (measured: 4.2 of the pinhole's own, inflated, 1σ).
    del rec["distortion"]
    pinhole = register_photos(project, ["p2"])["p2"]
    assert "distortion" not in project.data["calibration"]["cameras"]["p2"]
    assert abs(pinhole.K[0, 0] - truth.K[0, 0]) > 3 * np.sqrt(pinhole.covariance[0, 0])


def test_an_edge_observation_through_the_lens_measures_the_photos_pixels() -> None:
    """Two clicked points on the curve a model edge makes through the lens leave no residual; moved
    by δ across the curve they leave δ (in the photo's pixels, whitened by the click σ) to first
    order, where the pinhole image's distance alone would be off by the lens's local stretch."""
    truth, _, cams, _, _ = distorted_scene(5, n_boxes=1, n_photos=3)
    sigma = 0.7
    a, b = truth.handle_world("box0", "v4"), truth.handle_world("box0", "v5")
    edge = next(e for e, p, q in truth.node("box0").primitive.edges() if (p, q) == ("v4", "v5"))
    for cid, cam in cams.items():
        on = project(cam.K, cam.R, cam.C, np.array([a + 0.2 * (b - a), a + 0.8 * (b - a)]), cam.lens)
        # The curve's normal at each point, from its neighbours along the edge.
        nb = project(cam.K, cam.R, cam.C, np.array([a + 0.2001 * (b - a), a + 0.8001 * (b - a)]), cam.lens) - on
        normal = np.stack([-nb[:, 1], nb[:, 0]], axis=1) / np.linalg.norm(nb, axis=1, keepdims=True)
        for delta in (0.0, 2.0):
            obs = EdgeObservation(cid, "box0", edge, on + delta * normal)
            problem = Problem(truth, {cid: cam}, [], [obs], options=ProblemOptions(click_sigma_px=sigma))
            r = problem.residuals(problem.x0())[problem.rows_edge[0]] * sigma
            # First order in δ: the curve's bend over 2 px adds ≪ 0.01 px.
            assert np.abs(np.abs(r) - delta) == pytest.approx(0.0, abs=0.01), (cid, delta, r)


def test_a_new_primitive_placed_at_a_distorted_pixel_lands_on_the_floor_point_seen(solved_distorted) -> None:
    """Adding a box at a pixel of a distorted photo puts it where that pixel's ray, undistorted,
    meets the floor (to a micrometre), not where a pinhole's ray would (centimetres away)."""
    from vebuild.edit.session import EditSession

    proj, _, _ = solved_distorted
    s = EditSession.open(proj.path, autosave=False)
    cid, cam = "p1", s.cameras["p1"]
    P = np.array([ROOM[0] * 0.5 + 0.6, ROOM[1] * 0.5 - 0.4, 0.0])  # on the floor, off the photo's centre
    uv = project(cam.K, cam.R, cam.C, P, cam.lens)
    assert 0 <= uv[0] <= cam.width and 0 <= uv[1] <= cam.height
    name = s.add_primitive("box", at=(cid, (float(uv[0]), float(uv[1]))))
    origin = s.model.world_transforms()[name][:3, 3]
    assert np.linalg.norm(origin - P) < 1e-6, (origin, P)
    assert np.linalg.norm(project(cam.K, cam.R, cam.C, P) - uv) > 3.0  # the lens moved that pixel
