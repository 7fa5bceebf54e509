"""The example project generator (scenes/generate_room.py) checked against itself.

Nothing here imports vebuild: the example scene is test data for vebuild, so it must be right on
its own terms. Projections in this file are written out again (P = K [R | −R C], homogeneous
division) rather than borrowed from the generator, so that a slip in one shows up against the other.
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
ROOM_DIR = ROOT / "scenes" / "room"
CLICK_SIGMA = 0.7  # px, the noise the generator puts on every click
ON_LINE_TOL = 3.0  # px: |N(0, 0.7)| stays below 3 px (≈ 4.3σ) for every one of the ~130 ends


def _load_generator():
    spec = importlib.util.spec_from_file_location("generate_room", ROOT / "scenes" / "generate_room.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("generate_room", mod)
    spec.loader.exec_module(mod)
    return mod


gen = _load_generator()


@pytest.fixture(scope="module")
def project() -> dict:
    return json.loads((ROOM_DIR / "room.vebuild.json").read_text())


@pytest.fixture(scope="module")
def truth() -> dict:
    return json.loads((ROOM_DIR / "ground_truth.json").read_text())


@pytest.fixture(scope="module")
def scene() -> dict:
    return gen.build_scene()


def _P(K, R, C) -> np.ndarray:
    K, R, C = (np.asarray(a, dtype=float) for a in (K, R, C))
    return K @ np.hstack([R, -(R @ C)[:, None]])


def _proj(P: np.ndarray, X) -> np.ndarray:
    X = np.atleast_2d(np.asarray(X, dtype=float))
    h = np.hstack([X, np.ones((len(X), 1))]) @ P.T
    assert np.all(h[:, 2] > 0), "point behind the camera"
    return h[:, :2] / h[:, 2:3]


def _dist_to_line(p, a, b) -> float:
    d = b - a
    return abs(d[0] * (p[1] - a[1]) - d[1] * (p[0] - a[0])) / math.hypot(*d)


# --- cameras -----------------------------------------------------------------------------------


def test_rotation_is_the_format_ypr():
    """R from yaw/pitch/roll equals FORMAT.md's Rᵀ = Rz(yaw) · Ry(−pitch) · B · Rz(roll)."""

    def Rz(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])

    def Ry(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])

    B = np.array([[0, -1, 0], [0, 0, -1], [1, 0, 0]], dtype=float).T  # columns as in FORMAT.md
    for cam in gen.cameras(1.0):
        y, p, r = (math.radians(cam[k]) for k in ("yaw_deg", "pitch_deg", "roll_deg"))
        np.testing.assert_allclose(cam["R"], (Rz(y) @ Ry(-p) @ B @ Rz(r)).T, atol=1e-12)


def test_camera_kinds(truth):
    """p3 is level with a centred principal point; p4 faces the north wall squarely; the rest tilt."""
    ph = truth["photos"]
    for pid in ("p1", "p2", "p5"):
        assert -30 <= ph[pid]["pitch_deg"] <= -15 and abs(ph[pid]["roll_deg"]) > 1
    for pid in ("p3", "p4"):
        assert ph[pid]["pitch_deg"] == 0 and ph[pid]["roll_deg"] == 0
        assert ph[pid]["principal_point"] == [ph[pid]["width"] / 2, ph[pid]["height"] / 2]
    # p3 is a two-point view: its optical axis is well away from both horizontal world axes, so
    # the x and y vanishing points are both finite (and z's is at infinity)
    fwd3 = np.array(ph["p3"]["R"])[2]
    assert min(abs(fwd3[0]), abs(fwd3[1])) > math.sin(math.radians(15)) and abs(fwd3[2]) < 1e-12
    R4 = np.array(ph["p4"]["R"])
    np.testing.assert_allclose(R4[2], [0, 1, 0], atol=1e-12)  # optical axis along +y
    for p in ph.values():
        assert 1.4 <= p["C"][2] <= 1.8
        assert 0 < p["C"][0] < 5 and 0 < p["C"][1] < 4


# --- (1) the ray caster and the projection agree, with the pixel-centre convention --------------


@pytest.fixture(scope="module")
def low_res(scene):
    """Every photo at scale 0.25, one sample per pixel: (camera, image, quad id per pixel)."""
    out = []
    for cam in gen.cameras(0.25):
        img, ids = gen.render_photo(scene, cam, cam["width"], cam["height"], 1, return_ids=True)
        out.append((cam, img, ids))
    return out


def test_quad_centre_pixel_has_that_quads_colour(scene, low_res):
    """At the pixel containing a quad centre's projection: that quad, with its texture's colour.

    The expected colour is the texture at the point where the ray through the pixel's centre
    (i + ½, j + ½) meets the quad's plane, shaded and exposed, encoded to sRGB (±1 level: the
    renderer accumulates in float32)."""
    names = ["floor", "wall_west", "wall_north", "wall_south.west", "table.top.+z", "cabinet.+x",
             "box.+z", "box.-y", "door.-y", "wall_east", "ceiling"]
    index = {q["name"]: k for k, q in enumerate(scene["quads"])}
    checked = 0
    for cam, img, ids in low_res:
        P = _P(cam["K"], cam["R"], cam["C"])
        Kinv = np.linalg.inv(cam["K"])
        for name in names:
            q = scene["quads"][index[name]]
            centre = q["corner"] + 0.5 * q["edge1"] + 0.5 * q["edge2"]
            if not gen.visible(scene, cam, centre[None], margin=2.0)[0]:
                continue
            u, v = _proj(P, centre)[0]
            i, j = int(math.floor(u)), int(math.floor(v))
            assert ids[j, i] == index[name], f"{cam['id']} {name}: pixel ({i}, {j}) shows quad {ids[j, i]}"
            # the ray through the pixel centre, intersected with the quad's plane
            d = cam["R"].T @ (Kinv @ np.array([i + 0.5, j + 0.5, 1.0]))
            n = np.cross(q["edge1"], q["edge2"])
            X = cam["C"] + ((q["corner"] - cam["C"]) @ n) / (d @ n) * d
            rel = X - q["tex_origin"]
            albedo = gen.TEXTURES[q["texture"]](np.array([rel @ q["tex_u"]]), np.array([rel @ q["tex_v"]]),
                                                *q["tex_size"])
            lin = gen.srgb_to_linear(np.clip(albedo, 0, 1)) * q["shade"] * cam["exposure"]
            expected = gen.to_8bit(lin)[0].astype(int)
            got = img[j, i].astype(int)
            assert np.all(np.abs(got - expected) <= 1), f"{cam['id']} {name}: {got} != {expected}"
            checked += 1
    assert checked >= 12


def test_id_buffer_matches_projected_outline(scene, low_res):
    """The pixels showing the table top are exactly those whose centre lies inside the projected
    table-top outline (half a pixel off would flip a whole border row)."""
    index = {q["name"]: k for k, q in enumerate(scene["quads"])}["table.top.+z"]
    q = scene["quads"][index]
    corners = q["corner"] + np.array([[0, 0], [1, 0], [1, 1], [0, 1]]) @ np.array([q["edge1"], q["edge2"]])
    for cam, _, ids in low_res:
        if cam["id"] not in ("p1", "p4"):  # both see the whole top, unoccluded
            continue
        poly = _proj(_P(cam["K"], cam["R"], cam["C"]), corners)
        h, w = ids.shape
        uc, vc = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
        # signed distances of pixel centres to the 4 edges (the outline is convex)
        sd = []
        for k in range(4):
            a, b = poly[k], poly[(k + 1) % 4]
            e = b - a
            sd.append((e[0] * (vc - a[1]) - e[1] * (uc - a[0])) / math.hypot(*e))
        sd = np.array(sd)
        sd *= np.sign(np.median(sd[:, ids == index], axis=1))[:, None, None]
        inside = np.all(sd > 0, axis=0)
        clear = np.all(np.abs(sd) > 1e-6, axis=0)
        assert inside.sum() > 200
        bad = (inside != (ids == index)) & clear
        assert not bad.any(), f"{cam['id']}: {bad.sum()} pixels disagree"


# --- (2) segments -------------------------------------------------------------------------------


def test_segments_lie_on_their_edges_and_point_along_their_axis(project, truth, scene):
    edges = {n: (p, q) for a in "xyz" for n, p, q in scene["edges"][a]}
    n_ends = 0
    for ph in project["photos"]:
        gt = truth["photos"][ph["id"]]
        P = _P(gt["K"], gt["R"], gt["C"])
        assert set(ph["vanishing_segments"]) == set("xyz"), ph["id"]
        for axis, segs in ph["vanishing_segments"].items():
            k = "xyz".index(axis)
            assert 4 <= len(segs) <= 6, f"{ph['id']} {axis}: {len(segs)} segments"
            assert len(gt["segments"][axis]) == len(segs)
            for seg, t in zip(segs, gt["segments"][axis], strict=True):
                X1, X2 = np.array(t["X1"]), np.array(t["X2"])
                p, q = edges[t["edge"]]
                # the clicked run is a piece of the named edge, running along +axis
                assert X2[k] > X1[k]
                np.testing.assert_allclose(np.delete(X1, k), np.delete(p, k), atol=1e-12)
                np.testing.assert_allclose(np.delete(X2, k), np.delete(q, k), atol=1e-12)
                a, b = _proj(P, [X1, X2])
                p1, p2 = np.array(seg[:2]), np.array(seg[2:])
                for end in (p1, p2):
                    assert _dist_to_line(end, a, b) < ON_LINE_TOL, f"{ph['id']} {axis} {t['edge']}"
                    assert 0 <= end[0] <= gt["width"] and 0 <= end[1] <= gt["height"]
                    n_ends += 1
                # p1 → p2 goes the way the positive axis goes in the image
                step = _proj(P, [X1, X1 + 0.01 * np.eye(3)[k]])
                assert (p2 - p1) @ (step[1] - step[0]) > 0, f"{ph['id']} {axis} {t['edge']} reversed"
                assert np.linalg.norm(p2 - p1) > 75
    assert n_ends > 100


def test_clicks_carry_the_stated_noise(project, truth):
    """Marker clicks scatter about the true projections with σ ≈ 0.7 px."""
    res = []
    for ph in project["photos"]:
        gt = truth["photos"][ph["id"]]
        P = _P(gt["K"], gt["R"], gt["C"])
        for name, uv in ph["marker_observations"].items():
            res.append(np.array(uv) - _proj(P, truth["markers"][name])[0])
    res = np.array(res).ravel()
    assert np.all(np.abs(res) < 3.5)
    assert 0.45 < np.sqrt(np.mean(res**2)) < 1.0  # ~70 values: a loose two-sided bound on σ


# --- (3) the shipped files are what the generator makes ----------------------------------------


def test_shipped_annotations_match_regeneration(project, scene):
    cams = gen.cameras(1.0)
    anns = gen.annotate_all(scene, cams)
    assert [p["id"] for p in project["photos"]] == [c["id"] for c in cams]
    for ph, cam, ann in zip(project["photos"], cams, anns, strict=True):
        fresh = gen.photo_annotations_json(ann)
        assert (ph["width"], ph["height"]) == (cam["width"], cam["height"])
        assert fresh["vanishing_segments"].keys() == ph["vanishing_segments"].keys()
        for axis, segs in fresh["vanishing_segments"].items():
            np.testing.assert_allclose(ph["vanishing_segments"][axis], segs, atol=2e-3)
        assert fresh["marker_observations"].keys() == ph["marker_observations"].keys()
        for name, uv in fresh["marker_observations"].items():
            np.testing.assert_allclose(ph["marker_observations"][name], uv, atol=2e-3)
    assert project["reference_distances"] == gen.reference_distances(scene)
    assert [m["name"] for m in project["markers"]] == [n for n in scene["markers"]]


def test_shipped_files_match_their_hashes_and_exif(project, truth):
    total = 0
    for ph in project["photos"]:
        path = ROOM_DIR / ph["file"]
        data = path.read_bytes()
        total += len(data)
        assert hashlib.sha256(data).hexdigest() == ph["sha256"], ph["file"]
        with Image.open(path) as im:
            assert im.format == "JPEG" and im.size == (ph["width"], ph["height"])
            exif = im.getexif()
            ifd = exif.get_ifd(0x8769)
        assert exif[0x010F] == ph["exif"]["make"] == "vebuild"
        assert exif[0x0110] == ph["exif"]["model"] == "synthetic"
        assert int(ifd[0xA210]) == 4  # focal plane resolution unit: mm
        focal_px = float(ifd[0x920A]) * float(ifd[0xA20E])
        assert focal_px == pytest.approx(truth["photos"][ph["id"]]["f"], rel=1e-4)
        assert ph["exif"]["focal_length_mm"] == float(ifd[0x920A])
        assert ph["exif"]["focal_plane_x_resolution_per_mm"] == float(ifd[0xA20E])
        assert ph["exif"]["focal_length_35mm"] == int(ifd[0xA405])
        assert ph["exif"]["focal_length_px"] == pytest.approx(focal_px, rel=1e-12)
    assert total < 3_000_000


def test_project_top_level(project):
    assert project["format"] == "vebuild-project" and project["version"] == 1
    assert project["settings"]["click_sigma_px"] == CLICK_SIGMA
    assert project["origin_marker"] == "O"
    roles = sorted(d["role"] for d in project["reference_distances"])
    assert roles == ["check", "scale", "scale"]
    names = {m["name"] for m in project["markers"]}
    assert all(d["a"] in names and d["b"] in names for d in project["reference_distances"])
    assert all("position" not in m for m in project["markers"])


def test_ground_truth_cameras_are_the_generators(truth):
    for cam in gen.cameras(1.0):
        gt = truth["photos"][cam["id"]]
        np.testing.assert_allclose(gt["K"], cam["K"], atol=0)
        np.testing.assert_allclose(gt["R"], cam["R"], atol=0)
        np.testing.assert_allclose(gt["C"], cam["C"], atol=0)


# --- (4) marker coverage --------------------------------------------------------------------------


def test_marker_coverage(project):
    obs = {p["id"]: set(p["marker_observations"]) for p in project["photos"]}
    for m in project["markers"]:
        assert sum(m["name"] in o for o in obs.values()) >= 2, m["name"]
    for pid in ("p1", "p2", "p3", "p5"):
        assert "O" in obs[pid], pid
    assert "O" not in obs["p4"]
    others = set().union(*(o for pid, o in obs.items() if pid != "p4"))
    assert len(obs["p4"] & others) >= 3
    assert 9 <= len(project["markers"]) <= 14
