"""Laser scans: reading E57, PLY, LAS and LAZ, registration by a similarity (Umeyama) with its
uncertainty, the deviation of a scan from each face of the model, and scan points as observations
of the solve. The scans are sampled from the example room's solved model with Gaussian noise of
a known σ along each face's normal (tests/scan_scene.py) and put in a scan frame by a known
similarity."""

from __future__ import annotations

import copy
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from scan_scene import WRITERS, colours_of, random_rotation, sample_surfaces, to_scan_frame, write_ply  # noqa: E402

from vebuild.analysis.scans import face_deviations, project_model_as_written, scan_points_world  # noqa: E402
from vebuild.calibration.similarity import (  # noqa: E402
    DegenerateTargets,
    Similarity,
    fit_similarity,
    umeyama,
)
from vebuild.cli import main  # noqa: E402
from vebuild.errors import VebuildError  # noqa: E402
from vebuild.project import load_project  # noqa: E402
from vebuild.project.scans import read_point_cloud  # noqa: E402

#: 1σ of a scan point along its surface's normal (a phase scanner at a few metres), metres.
POINT_SIGMA = 0.003
#: 1σ of a target's centre as picked in the scan, per coordinate, metres.
TARGET_SIGMA = 0.002
#: Points per synthetic scan.
N_POINTS = 20_000
#: The scan frame: millimetres (scale 1e-3 into metres), turned and moved.
SCAN_SCALE = 1e-3
#: Handles of the example room used as targets (spread over the room, not on one line).
TARGETS = ("floor:v0", "floor:v1", "floor:v2", "floor:v3", "cabinet:v6", "wall_north:v4", "box:v5",
           "table.top:v6")
#: The 99.99 % point of χ² with 7 degrees of freedom (scipy.stats.chi2.ppf(0.9999, 7)).
CHI2_7_9999 = 29.88


def _sim(rng: np.random.Generator, scale: float = SCAN_SCALE) -> Similarity:
    return Similarity(scale, random_rotation(rng), rng.normal(0, 3.0, 3))


# ----------------------------------------------------------------------------------------------
# The math


def test_umeyama_exact_without_noise(rng):
    for _ in range(5):
        sim = _sim(rng, float(np.exp(rng.normal())))
        X = rng.normal(size=(6, 3))
        fit = umeyama(X, sim.apply(X))
        assert fit.scale == pytest.approx(sim.scale, rel=1e-12)
        assert np.abs(fit.rotation - sim.rotation).max() < 1e-10
        assert np.abs(fit.translation - sim.translation).max() < 1e-9


def test_umeyama_refuses_a_reflection_and_degenerate_targets(rng):
    X = rng.normal(size=(5, 3))
    fit = umeyama(X, X * [1, 1, -1])  # a mirror image: the nearest rotation, never a reflection
    assert np.linalg.det(fit.rotation) == pytest.approx(1.0)
    with pytest.raises(DegenerateTargets, match="at least 3"):
        umeyama(X[:2], X[:2])
    line = np.outer(np.arange(4.0), [1.0, 2.0, 0.5])
    with pytest.raises(DegenerateTargets, match="one line"):
        umeyama(line, line)


def test_registration_covariance_is_calibrated(rng):
    """Over many draws of the target noise, the error of the seven parameters measured by the
    covariance (with the true σ) is χ² with 7 degrees of freedom, and σ̂² estimates σ² without
    bias: both means are held to 4 standard errors of the mean on each side."""
    draws, n = 300, 6
    sigma = 0.004
    chi2, ratio = [], []
    X = rng.uniform(-3, 3, size=(n, 3))
    for _ in range(draws):
        sim = _sim(rng, 1.0 + 0.1 * rng.normal())
        Y = sim.apply(X) + rng.normal(0, sigma, size=(n, 3))
        fit = fit_similarity(X, Y)
        est = fit.similarity
        dR = est.rotation @ sim.rotation.T  # exp([ω]×) with R = exp([ω]×) R_true
        omega = 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
        e = np.r_[est.scale - sim.scale, omega, est.translation - sim.translation]
        cov_true_sigma = fit.covariance * (sigma / fit.sigma) ** 2
        chi2.append(e @ np.linalg.solve(cov_true_sigma, e))
        ratio.append(fit.sigma**2 / sigma**2)
    dof = 3 * n - 7
    assert abs(np.mean(chi2) - 7) <= 4 * np.sqrt(2 * 7 / draws)
    assert abs(np.mean(ratio) - 1) <= 4 * np.sqrt(2 / (dof * draws))


# ----------------------------------------------------------------------------------------------
# Files


@pytest.mark.parametrize("fmt", sorted(WRITERS))
def test_reader_round_trip(tmp_path, rng, fmt):
    P = rng.normal(0, 2.0, size=(2000, 3)) + [10.0, -4.0, 1.0]
    col = colours_of(P)
    path = tmp_path / f"scan.{fmt}"
    WRITERS[fmt](path, P, col)
    cloud = read_point_cloud(path)
    assert cloud.format == fmt
    # PLY (as trimesh writes it) and E57 (as pye57 writes it) hold float32; LAS stores 10 µm steps.
    tol = {"las": 5e-6, "laz": 5e-6}.get(fmt, 4e-6 * np.abs(P).max())
    assert cloud.points.shape == P.shape and np.abs(cloud.points - P).max() <= tol
    assert cloud.colours is not None and np.array_equal(cloud.colours, col)


def test_e57_scans_are_put_in_the_files_frame_by_their_poses(tmp_path, rng):
    """Two scans in one E57 file, the first with a pose (0.5 rad about z, then 10 m along x), the
    second with every tenth return marked invalid: one cloud in the file's frame, without them."""
    import pye57

    P = rng.normal(size=(100, 3))
    path = tmp_path / "two.e57"
    e57 = pye57.E57(str(path), mode="w")
    xyz = {"cartesianX": P[:, 0].copy(), "cartesianY": P[:, 1].copy(), "cartesianZ": P[:, 2].copy()}
    e57.write_scan_raw(xyz, rotation=np.array([np.cos(0.25), 0, 0, np.sin(0.25)]), translation=np.array([10.0, 0, 0]))
    invalid = np.arange(100) % 10 == 0
    e57.write_scan_raw({**xyz, "cartesianInvalidState": invalid.astype(np.int8)})
    e57.close()
    cloud = read_point_cloud(path)
    c, s = np.cos(0.5), np.sin(0.5)
    Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    assert cloud.points.shape == (190, 3) and cloud.colours is None
    assert np.abs(cloud.points[:100] - (P @ Rz.T + [10, 0, 0])).max() < 1e-6
    assert np.abs(cloud.points[100:] - P[~invalid]).max() < 1e-6


@pytest.mark.parametrize("fmt", sorted(WRITERS))
def test_unreadable_scan_names_the_file(tmp_path, fmt):
    path = tmp_path / f"broken.{fmt}"
    path.write_bytes(b"this is not a point cloud\n" * 20)
    with pytest.raises(VebuildError, match=rf"broken\.{fmt}.*cannot read it as {fmt.upper()}|broken\.{fmt}.*no points"):
        read_point_cloud(path)
    with pytest.raises(VebuildError, match="missing"):
        read_point_cloud(tmp_path / f"absent.{fmt}")
    with pytest.raises(VebuildError, match="ending in '.xyz'"):
        read_point_cloud(tmp_path / "scan.xyz")


# ----------------------------------------------------------------------------------------------
# The example room, solved, scanned


@pytest.fixture(scope="module")
def solved_room(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scans") / "room"
    shutil.copytree(Path(__file__).resolve().parents[1] / "scenes" / "room", folder)
    proj = folder / "room.vebuild.json"
    assert main(["calibrate", str(proj), "--quiet"]) == 0
    assert main(["solve", str(proj)]) == 0
    return proj


def _copy(solved_room, tmp_path) -> Path:
    folder = tmp_path / "room"
    shutil.copytree(solved_room.parent, folder)
    return folder / solved_room.name


def _scan(proj: Path, fmt: str, seed: int, truth_nodes=None, n=N_POINTS, skip=frozenset()):
    """Write a scan of the project's model (or of ``truth_nodes`` in its place) into its folder;
    return its file, the true similarity and the --target words."""
    rng = np.random.default_rng(seed)
    project = load_project(proj)
    truth = copy.deepcopy(project)
    if truth_nodes is not None:
        truth.data["model"]["nodes"] = truth_nodes
    model = project_model_as_written(truth)
    P, owner = sample_surfaces(model, n, POINT_SIGMA, rng, skip)
    sim = _sim(rng)
    path = proj.parent / f"scan{seed}.{fmt}"
    WRITERS[fmt](path, to_scan_frame(sim, P), colours_of(P))
    from vebuild.analysis.scans import resolve_points

    W = resolve_points(project, list(TARGETS), list(TARGETS))
    S = to_scan_frame(sim, W + rng.normal(0, TARGET_SIGMA, W.shape))
    words = [f"--target=T{k}={float(s[0])!r},{float(s[1])!r},{float(s[2])!r}:{t}"
             for k, (s, t) in enumerate(zip(S, TARGETS, strict=True))]
    return path, sim, words


@pytest.mark.parametrize("fmt", ["laz", "e57", "ply"])
def test_scan_add_registers_within_the_noise(solved_room, tmp_path, capsys, fmt):
    proj = _copy(solved_room, tmp_path)
    path, sim, words = _scan(proj, fmt, 11)
    before = path.read_bytes()
    assert main(["scan", "add", str(proj), str(path), *words]) == 0
    assert path.read_bytes() == before  # the scan file is never altered
    entry = load_project(proj).data["scans"][0]
    assert entry["file"] == path.name and entry["format"] == fmt and entry["point_count"] == N_POINTS
    assert not entry["use_in_solve"]
    reg = entry["registration"]
    assert [t["point"] for t in reg["targets"]] == list(TARGETS) and len(reg["residuals"]) == len(TARGETS)
    # Each coordinate of a target is off by TARGET_SIGMA; its residual is smaller by the fit's
    # redundancy (3n − 7 of 3n): the rms is held within a factor 2 either way.
    expect_rms = TARGET_SIGMA * np.sqrt(3 * (3 * len(TARGETS) - 7) / (3 * len(TARGETS)))
    assert expect_rms / 2 < reg["rms_m"] < 2 * expect_rms
    cov = np.array(reg["covariance"]["matrix"])
    sd = np.sqrt(np.diag(cov))
    s = reg["similarity"]
    # The whole error (scale, turn, translation) measured by the recorded covariance: below the
    # 99.99 % point of χ² with 7 degrees of freedom (the calibration over many draws is tested above).
    dR = np.array(s["rotation"]) @ sim.rotation.T
    omega = 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
    e = np.r_[s["scale"] - sim.scale, omega, np.array(s["translation"]) - sim.translation]
    assert e @ np.linalg.solve(cov, e) < CHI2_7_9999
    assert abs(e[0]) < 5 * sd[0]
    pts, col = scan_points_world(load_project(proj), 0, 1000)
    assert pts.shape == (1000, 3) and col.shape == (1000, 3)
    assert "registered from 8 targets" in capsys.readouterr().out


def test_scan_check_deviations(solved_room, tmp_path, capsys):
    """An undisplaced face: median ≈ 0, p95 of the distance ≈ 1.96 σ. The cabinet moved by a known
    offset along +x in the model: its right face (+x) shows −offset, its top and front 0."""
    proj = _copy(solved_room, tmp_path)
    path, _, words = _scan(proj, "laz", 12)
    assert main(["scan", "add", str(proj), str(path), *words]) == 0
    capsys.readouterr()
    assert main(["scan", "check", str(proj), "--json", str(tmp_path / "dev.json")]) == 0
    out = capsys.readouterr().out
    assert "cabinet:front" in out and "median mm" in out and f"{N_POINTS} points" in out
    assert main(["scan", "check", str(proj), "--max-points", "5000"]) == 0
    assert f"5000 of its {N_POINTS} points (a regular subsample)" in capsys.readouterr().out
    doc = json.loads((tmp_path / "dev.json").read_text())
    faces = {(r["node"], r["face"]): r for r in doc["scans"][0]["faces"]}
    # Faces with many points: their median (registration error, ≲ 1 mm, plus σ/√n) and p95.
    big = [r for r in faces.values() if r["count"] >= 1500]
    assert len(big) >= 3
    for r in big:
        # The median of n points of noise σ has 1σ 1.2533 σ/√n; the registration moves the face's
        # points by its own 1σ (carried from the covariance): 4σ of the two together.
        tol = 4 * np.hypot(1.2533 * POINT_SIGMA / np.sqrt(r["count"]), r["registration_sigma_m"])
        assert 0 < r["registration_sigma_m"] < 0.002 and abs(r["median_m"]) < tol, r
        assert 1.96 * POINT_SIGMA * 0.85 < r["p95_m"] < 1.96 * POINT_SIGMA * 1.25, r

    offset = 0.03
    data = json.loads(proj.read_text())
    cab = next(n for n in data["model"]["nodes"] if n["name"] == "cabinet")
    yaw = np.radians(cab["joint"]["yaw_deg"])
    cab["joint"]["position"][0] += offset  # along the floor's x (the cabinet turned by yaw ≈ 0)
    proj.write_text(json.dumps(data))
    project = load_project(proj)
    dev = face_deviations(project, 0)
    faces = {(r["node"], r["face"]): r for r in dev["faces"]}
    along = offset * np.cos(yaw)
    # (Its left face stands against the west wall, whose face takes those points.)
    for face, sign in (("right", -1.0), ("top", 0.0), ("front", 0.0)):
        r = faces[("cabinet", face)]
        tol = 4 * np.hypot(1.2533 * POINT_SIGMA / np.sqrt(r["count"]), r["registration_sigma_m"])
        assert abs(r["median_m"] - sign * along) < tol, r
    assert faces[("cabinet", "right")]["count"] > 150

    # The report's section: the table marks the displaced face, the map colours it.
    from PIL import Image

    from vebuild.report.deviation import scans
    from vebuild.report.page import Report

    (tmp_path / "rep" / "images").mkdir(parents=True)
    rep = Report(tmp_path / "rep")
    scans(project, rep)
    html = rep.sections[0]
    assert "<h2>Laser scans</h2>" in html and "scan-0-deviation.png" in html
    row = html[html.index("cabinet:right"):].split("</tr>")[0]
    assert "bad" in row
    for face in ("wall_north:front", "cabinet:top"):
        assert "bad" not in html[html.index(face):].split("</tr>")[0]
    img = np.asarray(Image.open(rep.images[0]))
    assert img.ndim == 3 and img.shape[0] > 300


def test_a_registration_whose_targets_moved_is_called_stale(solved_room, tmp_path, capsys):
    """Re-solved after the scan was registered, with the cabinet's pins moved: the target on the
    cabinet (cabinet:v6) now lies elsewhere, and `scan check` says the registration is stale."""
    proj = _copy(solved_room, tmp_path)
    path, _, words = _scan(proj, "laz", 14)
    assert main(["scan", "add", str(proj), str(path), *words]) == 0
    capsys.readouterr()
    assert main(["scan", "check", str(proj)]) == 0
    assert "stale" not in capsys.readouterr().out  # nothing moved: no warning
    data = json.loads(proj.read_text())
    for pin in data["model"]["pins"]:
        if pin["node"] == "cabinet":
            pin["uv"][0] += 6.0  # every sighting of the cabinet 6 px to the right
    proj.write_text(json.dumps(data))
    assert main(["solve", str(proj)]) == 0
    capsys.readouterr()
    assert main(["scan", "check", str(proj)]) == 0
    out = capsys.readouterr().out
    warned = [line for line in out.splitlines() if line.startswith("warning: ") and "stale" in line]
    assert any("target T4 (cabinet:v6) now lies" in line for line in warned), out
    assert not any("(floor:v0)" in line for line in warned), out  # the floor did not move


def test_solve_with_scan_moves_a_perturbed_primitive_toward_the_truth(solved_room, tmp_path):
    """The scan sees the cabinet 4 cm wider than the photos' solution: solved with the scan, the
    width moves to within a fifth of that of the scan's; without it, it stays."""
    proj = _copy(solved_room, tmp_path)
    data = json.loads(proj.read_text())
    solved_width = next(n for n in data["model"]["nodes"] if n["name"] == "cabinet")["primitive"]["params"]["width"]
    truth = copy.deepcopy(data["model"]["nodes"])
    cab = next(n for n in truth if n["name"] == "cabinet")
    true_width = solved_width + 0.04
    cab["primitive"]["params"]["width"] = true_width
    path, _, words = _scan(proj, "laz", 13, truth_nodes=truth)
    assert main(["scan", "add", str(proj), str(path), *words, "--use-in-solve", "--point-sigma", "0.003"]) == 0
    assert main(["solve", str(proj)]) == 0
    after = json.loads(proj.read_text())
    width = next(n for n in after["model"]["nodes"] if n["name"] == "cabinet")["primitive"]["params"]["width"]
    assert abs(width - true_width) < 0.2 * abs(solved_width - true_width)
    assert "scans/use_in_solve" in after["model_solution"]["computed_from"]


# ----------------------------------------------------------------------------------------------
# Bad input


@pytest.fixture(scope="module")
def scanned_room(solved_room, tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad") / "room"
    shutil.copytree(solved_room.parent, folder)
    proj = folder / solved_room.name
    path, _, words = _scan(proj, "laz", 14, n=3000)
    return proj, path, words


def _fails(capsys, argv, *needles):
    assert main(argv) == 2
    err = capsys.readouterr().err
    for n in needles:
        assert n in err, err
    return err


def test_bad_scan_input(scanned_room, capsys):
    proj, path, words = scanned_room
    before = proj.read_bytes()
    _fails(capsys, ["scan", "add", str(proj), str(proj.parent / "absent.laz"), *words], "absent.laz", "missing")
    bad = proj.parent / "garbage.las"
    bad.write_bytes(b"\0" * 500)
    _fails(capsys, ["scan", "add", str(proj), str(bad), *words], "garbage.las", "cannot read it as LAS")
    _fails(capsys, ["scan", "add", str(proj), str(path), *words[:2]], "2 targets", "at least 3")
    line = [f"--target=L{k}={k}.0,{2 * k}.0,0.5:{t}" for k, t in enumerate(("floor:v0", "floor:v1", "floor:v2"))]
    # Three targets on one line in the scan (the project points are not: the scan's are degenerate).
    _fails(capsys, ["scan", "add", str(proj), str(path), *line], "one line")
    unknown = [*words[:3], "--target=T9=1,2,3:nosuchnode:v0"]
    _fails(capsys, ["scan", "add", str(proj), str(path), *unknown], "T9", "nosuchnode", "unknown project point")
    _fails(capsys, ["scan", "add", str(proj), str(path), "--target", "T1=1,2:floor:v0"], "T1=1,2:floor:v0",
           "three finite numbers")
    _fails(capsys, ["scan", "add", str(proj), str(path), "--target", "T1"], "NAME=X,Y,Z:POINT")
    _fails(capsys, ["scan", "add", str(proj), str(path), *words[:3], words[0]], "given twice")
    csv = proj.parent / "targets.csv"
    csv.write_text("name,x,y\nT1,1,2\n")
    _fails(capsys, ["scan", "add", str(proj), str(path), "--targets", str(csv)], "targets.csv", "name, x, y, z, point")
    outside = proj.parent.parent / "outside.laz"
    shutil.copy(path, outside)
    _fails(capsys, ["scan", "add", str(proj), str(outside), *words], "outside.laz", "outside the project folder")
    _fails(capsys, ["scan", "check", str(proj)], "$.scans", "no laser scans")
    assert proj.read_bytes() == before  # nothing was written by a refused command


def test_scan_targets_from_csv_and_hash_mismatch_on_reload(scanned_room, tmp_path, capsys):
    proj0, path0, words = scanned_room
    folder = tmp_path / "room"
    shutil.copytree(proj0.parent, folder)
    proj, path = folder / proj0.name, folder / path0.name
    rows = ["name,x,y,z,point"]
    for w in words:
        name, rest = w.split("=", 1)[1].split("=", 1)
        xyz, point = rest.split(":", 1)
        rows.append(f"{name},{xyz},{point}")
    (folder / "targets.csv").write_text("\n".join(rows) + "\n")
    assert main(["scan", "add", str(proj), str(path), "--targets", str(folder / "targets.csv")]) == 0
    assert len(load_project(proj).data["scans"][0]["registration"]["targets"]) == len(TARGETS)
    capsys.readouterr()
    assert main(["check", str(proj)]) == 0
    assert "laser scans: 1 scan(s), hashes verified" in capsys.readouterr().out
    raw = bytearray(path.read_bytes())
    raw[-10] ^= 0xFF
    path.write_bytes(bytes(raw))
    capsys.readouterr()
    _fails(capsys, ["scan", "check", str(proj)], path.name, "$.scans[0].sha256", "changed or replaced")
    assert main(["check", str(proj)]) != 0
    assert "$.scans[0].sha256" in capsys.readouterr().err
    path.unlink()
    _fails(capsys, ["scan", "check", str(proj)], path.name, "$.scans[0].file", "missing")


# ----------------------------------------------------------------------------------------------
# Drawn in the walk-through


def test_the_walk_through_draws_the_scan_as_points_and_k_hides_it(tmp_path, xvfb_display):
    """A green scan of the box's top, registered by the identity from the box's corners, is drawn
    where the box's top is in the window; K hides it; a project without scans draws none."""
    from viewer_scene import write_project

    from vebuild.gl.window import Window
    from vebuild.render.renderer import RenderOptions
    from vebuild.viewer.app import Viewer
    from vebuild.viewer.keys import VIEWER_KEYS

    proj = write_project(tmp_path)
    project = load_project(proj)
    model = project_model_as_written(project)
    from vebuild.analysis.scans import world_faces

    others = {f for f in world_faces(model).names if f != ("box", "top")}
    top, _ = sample_surfaces(model, 20_000, 0.0, np.random.default_rng(5), skip=others)
    write_ply(proj.parent / "box.ply", top, np.tile([0, 255, 0], (len(top), 1)).astype(np.uint8))
    from vebuild.analysis.scans import resolve_points

    corners = ["box:v4", "box:v5", "box:v6", "box:v3"]
    W = resolve_points(project, corners, corners)
    words = [f"--target=C{k}={x!r},{y!r},{z!r}:{c}" for k, ((x, y, z), c) in enumerate(zip(W.tolist(), corners,
                                                                                              strict=True))]
    assert main(["scan", "add", str(proj), str(proj.parent / "box.ply"), *words]) == 0
    assert any(c.command == "toggle_scans" for b in VIEWER_KEYS.bindings for c in b.chords)

    window = Window(480, 320, "vebuild scan test", visible=True)
    try:
        viewer = Viewer(load_project(proj), window, RenderOptions.interactive(), view="at the box")
        assert viewer.show_scans

        def green() -> int:
            viewer.draw()
            img = np.frombuffer(window.ctx.screen.read(viewport=(0, 0, 480, 320), components=3, alignment=1),
                                np.uint8).reshape(320, 480, 3).astype(int)
            return int(np.sum((img[..., 1] > 200) & (img[..., 0] < 60) & (img[..., 2] < 60)))

        shown = green()
        assert shown > 200
        # Points inside the box (its top's, shrunk toward the middle and lowered by half its
        # height) are hidden by its faces: the frame's depth.
        mid = top.mean(axis=0)
        height = next(n for n in project.data["model"]["nodes"] if n["name"] == "box")["primitive"]["params"]["height"]
        hidden = mid + 0.8 * (top - mid) - [0.0, 0.0, height / 2]
        layer = viewer.scan_layer()
        layer.set_points(hidden, np.tile([0, 255, 0], (len(hidden), 1)))
        n_hidden = green()
        assert n_hidden < shown / 50
        layer.set_points(top, np.tile([0, 255, 0], (len(top), 1)))
        assert green() == shown
        viewer.toggle_scans()
        assert not viewer.show_scans and green() < shown / 50
        viewer.close()
    finally:
        window.close()


def test_the_modelling_screens_preview_draws_the_scan_over_its_frame(tmp_path):
    """Headless (EGL): points of the box's top drawn over the renderer's off-screen frame land on
    the box's top; points inside the box are hidden by it."""
    from viewer_scene import write_project

    from vebuild.analysis.scans import world_faces
    from vebuild.camera import project as project_points
    from vebuild.edit.preview import draw_points_over_frame
    from vebuild.gl import headless_context
    from vebuild.gl.points import PointLayer
    from vebuild.project.decode import view_camera
    from vebuild.render.renderer import Renderer, RenderOptions
    from vebuild.render.scene import load_scene

    proj = write_project(tmp_path)
    project = load_project(proj)
    model = project_model_as_written(project)
    others = {f for f in world_faces(model).names if f != ("box", "top")}
    top, _ = sample_surfaces(model, 5000, 0.0, np.random.default_rng(7), skip=others)
    ctx = headless_context()
    renderer = Renderer(ctx, load_scene(project), RenderOptions(samples=1, anisotropy=1.0, trilinear=False))
    cam = view_camera(next(v for v in project.data["views"] if v["name"] == "at the box"))
    layer = PointLayer(ctx)
    green = np.tile([0, 255, 0], (len(top), 1))

    def drawn(points) -> np.ndarray:
        layer.set_points(points, green)
        tex = renderer.frame(cam)
        draw_points_over_frame(renderer, cam, layer)
        img = np.frombuffer(tex.read(alignment=1), np.uint8).reshape(cam.height, cam.width, 4)[..., :3].astype(int)
        return (img[..., 1] > 200) & (img[..., 0] < 60) & (img[..., 2] < 60)

    mask = drawn(top)
    uv = project_points(cam.K, cam.R, cam.C, top)
    inside = (uv[:, 0] >= 0) & (uv[:, 0] < cam.width) & (uv[:, 1] >= 0) & (uv[:, 1] < cam.height)
    col, row = uv[inside, 0].astype(int), uv[inside, 1].astype(int)
    assert inside.sum() > 1000 and mask[row, col].mean() > 0.95  # each point at its own pixel (image order)
    height = next(n for n in project.data["model"]["nodes"] if n["name"] == "box")["primitive"]["params"]["height"]
    mid = top.mean(axis=0)
    assert drawn(mid + 0.8 * (top - mid) - [0.0, 0.0, height / 2]).sum() < mask.sum() / 50
    layer.release()
    renderer.release()


# ----------------------------------------------------------------------------------------------
# The point-to-face rows of the solve


def _surface_problem(points, free, sigma=POINT_SIGMA):
    from vebuild.analysis.scans import nearest_faces, world_faces
    from vebuild.model.scan_fit import ScanProblem, SurfaceObservation
    from vebuild.model.solver import FINAL_PRIOR_SCALE, ProblemOptions

    model = project_model_as_written(load_project(Path(__file__).resolve().parents[1] / "scenes" / "room"
                                                  / "room.vebuild.json"))
    faces = world_faces(model)
    idx, _ = nearest_faces(points, faces)
    obs = [SurfaceObservation(n, f, points[idx == k], sigma) for k, (n, f) in enumerate(faces.names)
           if (idx == k).any() and faces.flat[k]]
    return ScanProblem(model, {}, [], [], surfaces=obs,
                       options=ProblemOptions(free_nodes=free, prior_scale=FINAL_PRIOR_SCALE))


def test_scan_rows_jacobian_matches_their_residuals(rng):
    model = project_model_as_written(load_project(Path(__file__).resolve().parents[1] / "scenes" / "room"
                                                  / "room.vebuild.json"))
    P, _ = sample_surfaces(model, 3000, 0.01, rng)
    problem = _surface_problem(P, ["cabinet", "box"])
    assert problem.n_scan == 3000
    x = problem.x0() + 0.01
    J = problem.jacobian(x)
    J = J.toarray() if hasattr(J, "toarray") else J
    h = 1e-6
    numeric = np.column_stack([(problem.evaluate(x + h * e) - problem.evaluate(x - h * e)) / (2 * h)
                               for e in np.eye(len(x))])
    assert np.abs(J - numeric).max() < 1e-6 * np.abs(numeric).max()
    assert "scan point" in problem.describe_row(int(problem.rows_scan[5]))


def test_scan_rows_are_robust_to_a_cluster_off_the_face(rng):
    """A fifth of the box's front points 6 cm in front of it (something hung on it): the robust rows
    leave the box within a few σ of where its other points put it; plain least squares would move
    it by a fifth of 6 cm."""
    from vebuild.analysis.scans import world_faces

    model = project_model_as_written(load_project(Path(__file__).resolve().parents[1] / "scenes" / "room"
                                                  / "room.vebuild.json"))
    faces = world_faces(model)
    others = {f for f in faces.names if f[0] != "box"}
    P, owner = sample_surfaces(model, 4000, POINT_SIGMA, rng, skip=others)
    k_front = faces.names.index(("box", "front"))
    tri = faces.triangles[faces.face_of == k_front][0]
    normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
    normal /= np.linalg.norm(normal)
    front = np.flatnonzero(owner == k_front)
    moved, kept = front[: len(front) // 5], front[len(front) // 5:]
    P[moved] += 0.06 * normal
    from vebuild.analysis.scans import nearest_faces

    def kept_offset(robust: bool) -> float:
        """The median signed distance of the front's unmoved points from the solved front face."""
        import vebuild.model.scan_fit as fit

        problem = _surface_problem(P, ["box"])
        plain = fit.robust
        if not robust:  # the same rows without the loss: plain least squares
            fit.robust = lambda r, c=0.0: (r, np.ones_like(r))
        try:
            x = problem.solve(problem.x0()).x
        finally:
            fit.robust = plain
        problem.model.set_vector(problem.model_vector(x))
        idx, d = nearest_faces(P[kept], world_faces(problem.model))
        return float(np.median(d[idx == k_front]))

    robust_offset, plain_offset = kept_offset(True), kept_offset(False)
    # Plain least squares moves the face a fifth of 6 cm toward the cluster. The robust rows move it
    # to where the soft-L1 influence ψ(r) = r / √(1 + (r/c)²), c = 3σ, of the two groups balances:
    # 0.8 ψ(−δ) + 0.2 ψ(6 cm − δ) = 0 (the noise neglected: it changes δ by well under a millimetre).
    from scipy.optimize import brentq

    c = 3 * POINT_SIGMA

    def psi(r):
        return r / np.sqrt(1 + (r / c) ** 2)

    delta = brentq(lambda d: 0.8 * psi(-d) + 0.2 * psi(0.06 - d), 0.0, 0.06)
    assert abs(plain_offset + 0.2 * 0.06) < 0.003
    assert abs(robust_offset + delta) < 0.001 and delta < 0.25 * 0.2 * 0.06
