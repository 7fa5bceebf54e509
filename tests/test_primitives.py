"""Parametric primitives: handles, derivatives, faces, meshes and atlases against hand-made answers."""

from __future__ import annotations

import copy
import pickle
import re

import numpy as np
import pytest

from vebuild.model import (
    PRIMITIVE_TYPES,
    Box,
    Cylinder,
    Frustum,
    Primitive,
    Quad,
    Sphere,
    Wedge,
    primitive_from_dict,
)
from vebuild.model.mesh import GUTTER_TEXELS

trimesh = pytest.importorskip("trimesh")

SAMPLES: list[Primitive] = [
    Quad(2.0, 3.0),
    Box(1.0, 2.0, 3.0),
    Wedge(1.2, 2.5, 0.8),
    Cylinder(0.4, 1.5),
    Frustum(0.6, 0.25, 0.9),
    Frustum(0.5, 0.0, 1.1),  # a cone
    Sphere(0.7),
]
SOLIDS = [p for p in SAMPLES if not isinstance(p, Quad)]
CURVED = (Cylinder, Frustum, Sphere)


def ids(p: Primitive) -> str:
    return repr(p)


# ---------------------------------------------------------------------------------------------
# Handles


def test_handles_at_hand_computed_positions() -> None:
    w, d, h = 2.0, 4.0, 3.0
    ring = [[-1, -2, 0], [1, -2, 0], [1, 2, 0], [-1, 2, 0]]
    top = [[x, y, h] for x, y, _ in ring]
    assert Quad(w, d).handles() == pytest.approx(np.array(ring, float))
    assert Box(w, d, h).handles() == pytest.approx(np.array(ring + top, float))
    # The wedge's top edge is the back (+y) edge: v4 above v3, v5 above v2.
    assert Wedge(w, d, h).handles() == pytest.approx(np.array(ring + [[-1, 2, 3], [1, 2, 3]], float))
    r, h = 0.5, 2.0
    cyl = [[r, 0, 0], [0, r, 0], [-r, 0, 0], [0, -r, 0], [r, 0, h], [0, r, h], [-r, 0, h], [0, -r, h], [0, 0, 0],
           [0, 0, h]]
    assert Cylinder(r, h).handles() == pytest.approx(np.array(cyl, float))
    fr = [[0.6, 0, 0], [0, 0.6, 0], [-0.6, 0, 0], [0, -0.6, 0], [0.2, 0, 1], [0, 0.2, 1], [-0.2, 0, 1], [0, -0.2, 1],
          [0, 0, 0], [0, 0, 1]]
    assert Frustum(0.6, 0.2, 1.0).handles() == pytest.approx(np.array(fr, float))
    sph = [[0, 0, 0], [0, 0, 1.4], [0.7, 0, 0.7], [-0.7, 0, 0.7], [0, 0.7, 0.7], [0, -0.7, 0.7]]
    assert Sphere(0.7).handles() == pytest.approx(np.array(sph, float))


def test_handle_names_follow_the_file_format() -> None:
    assert Quad.handle_names() == ("v0", "v1", "v2", "v3")
    assert Box.handle_names() == tuple(f"v{i}" for i in range(8))
    assert Wedge.handle_names() == tuple(f"v{i}" for i in range(6))
    assert Cylinder.handle_names() == Frustum.handle_names() == ("b0", "b1", "b2", "b3", "t0", "t1", "t2", "t3",
                                                                  "bc", "tc")
    assert Sphere.handle_names() == ("bottom", "top", "px", "nx", "py", "ny")


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_handles_take_trial_params(prim: Primitive, rng: np.random.Generator) -> None:
    p = rng.uniform(0.2, 2.0, len(prim.PARAMS))
    assert prim.handles(p) == pytest.approx(prim.with_params(p).handles(), abs=1e-15)
    assert prim.handles().shape == (len(prim.handle_names()), 3)


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_handle_jacobian_matches_central_differences(prim: Primitive, rng: np.random.Generator) -> None:
    p = rng.uniform(0.2, 2.0, len(prim.PARAMS))
    J = prim.handle_jacobian(p)
    assert J.shape == (len(prim.handle_names()), 3, len(prim.PARAMS))
    for k in range(len(p)):
        step = 1e-6 * p[k]
        dp = np.zeros_like(p)
        dp[k] = step
        fd = (prim.handles(p + dp) - prim.handles(p - dp)) / (2 * step)
        assert J[:, :, k] == pytest.approx(fd, rel=1e-6, abs=1e-9)


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_handles_batch_equals_looping(prim: Primitive, rng: np.random.Generator) -> None:
    P = rng.uniform(0.1, 3.0, (7, len(prim.PARAMS)))
    batch = prim.handles_batch(P)
    assert batch.shape == (7, len(prim.handle_names()), 3)
    assert batch == pytest.approx(np.stack([prim.handles(p) for p in P]), abs=0)
    with pytest.raises(ValueError, match="shape"):
        prim.handles_batch(P[:, :1] if P.shape[1] > 1 else np.ones((7, 2)))


# ---------------------------------------------------------------------------------------------
# Edges and outlines


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_edges_join_named_handles(prim: Primitive) -> None:
    edges = prim.edges()
    assert [e[0] for e in edges] == [f"e{i}" for i in range(len(edges))]
    assert all(a in prim.handle_names() and b in prim.handle_names() for _, a, b in edges)


def test_edge_lists() -> None:
    assert len(Quad.edges()) == 4 and len(Box.edges()) == 12 and len(Wedge.edges()) == 9
    assert len(Cylinder.edges()) == len(Frustum.edges()) == 4 and Sphere.edges() == []
    assert Box.edges()[5] == ("e5", "v5", "v6") and Box.edges()[11] == ("e11", "v3", "v7")
    assert Wedge.edges()[4] == ("e4", "v4", "v5")
    assert Cylinder.edges()[2] == ("e2", "b2", "t2")
    # Box edge lengths: bottom and top rings alternate width/depth, verticals are the height.
    box = Box(1.0, 2.0, 3.0)
    H = dict(zip(box.handle_names(), box.handles(), strict=True))
    lengths = [np.linalg.norm(H[a] - H[b]) for _, a, b in box.edges()]
    assert lengths == pytest.approx([1, 2, 1, 2, 1, 2, 1, 2, 3, 3, 3, 3])


def test_wedge_is_a_ramp_rising_toward_plus_y() -> None:
    w, d, h = 1.2, 2.5, 0.8
    H = dict(zip(Wedge.handle_names(), Wedge(w, d, h).handles(), strict=True))
    assert H["v4"] - H["v3"] == pytest.approx([0, 0, h]) and H["v5"] - H["v2"] == pytest.approx([0, 0, h])
    assert H["v2"][1] == H["v3"][1] == d / 2  # the back, vertical face is at +y
    # v0, v1, v5, v4 are coplanar: the slope.
    n = np.cross(H["v1"] - H["v0"], H["v4"] - H["v0"])
    assert (H["v5"] - H["v0"]) @ n == pytest.approx(0.0, abs=1e-12)


def test_outline_points() -> None:
    rims = Frustum(0.6, 0.2, 1.0).outline_points(24)
    assert len(rims) == 2 and all(r.shape == (25, 3) for r in rims)
    assert np.linalg.norm(rims[0][:, :2], axis=1) == pytest.approx(np.full(25, 0.6))
    assert rims[1][:, 2] == pytest.approx(np.ones(25)) and rims[0][0] == pytest.approx(rims[0][-1], abs=0)
    assert len(Frustum(0.5, 0.0, 1.0).outline_points()) == 1  # a cone's apex has no rim
    equator, meridian = Sphere(0.7).outline_points(params=[2.0])
    for line in (equator, meridian):
        assert np.linalg.norm(line - [0, 0, 2.0], axis=1) == pytest.approx(np.full(49, 2.0))
    assert equator[:, 2] == pytest.approx(np.full(49, 2.0)) and meridian[:, 1] == pytest.approx(np.zeros(49))
    assert Box(1, 1, 1).outline_points() == []


# ---------------------------------------------------------------------------------------------
# Restable faces


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_face_frames_are_right_handed_orthonormal_and_outward(prim: Primitive) -> None:
    centre = prim.mesh().vertices.mean(axis=0)  # inside every convex solid
    for name, (o, x, y, n) in prim.faces().items():
        M = np.column_stack([x, y, n])
        assert M.T @ M == pytest.approx(np.eye(3), abs=1e-12), name
        assert np.linalg.det(M) == pytest.approx(1.0), name
        if not isinstance(prim, Quad):
            assert (o - centre) @ n > 0, name


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_face_frames_sit_on_the_mesh_faces_of_the_same_name(prim: Primitive) -> None:
    m = prim.mesh()
    for name, (o, _, _, n) in prim.faces().items():
        fid = m.face_names.index(name) + 1
        v = np.unique(m.faces[m.face_ids == fid])
        assert (m.vertices[v] - o) @ n == pytest.approx(np.zeros(len(v)), abs=1e-12), name  # in the plane
        assert m.normals[v] == pytest.approx(np.tile(n, (len(v), 1)), abs=1e-12), name
        assert m.vertices[v].mean(axis=0) == pytest.approx(o, abs=1e-12), name  # centred


def test_named_faces() -> None:
    assert set(Quad(1, 1).faces()) == {"top"}
    assert set(Box(1, 1, 1).faces()) == {"top", "bottom"}
    assert set(Wedge(1, 1, 1).faces()) == {"bottom", "back"}
    assert set(Cylinder(1, 1).faces()) == {"top", "bottom"}
    assert set(Frustum(1, 0.5, 1).faces()) == {"top", "bottom"}
    assert set(Frustum(1, 0.0, 1).faces()) == {"bottom"}
    assert Sphere(1).faces() == {}
    o, x, y, n = Box(1.0, 2.0, 3.0).face_frame("top")
    assert o == pytest.approx([0, 0, 3]) and n == pytest.approx([0, 0, 1]) and x == pytest.approx([1, 0, 0])
    o, _, _, n = Box(1.0, 2.0, 3.0).face_frame("bottom")
    assert o == pytest.approx([0, 0, 0]) and n == pytest.approx([0, 0, -1])
    o, x, y, n = Wedge(1.0, 2.0, 3.0).face_frame("back")
    assert o == pytest.approx([0, 1, 1.5]) and n == pytest.approx([0, 1, 0]) and y == pytest.approx([0, 0, 1])
    # Trial params, as the solver passes them:
    assert Box(1, 1, 1).face_frame("top", [1.0, 1.0, 2.5])[0] == pytest.approx([0, 0, 2.5])
    assert Cylinder(1, 1).face_frame("top", [1.0, 0.75])[0] == pytest.approx([0, 0, 0.75])
    with pytest.raises(ValueError, match="sphere has no face 'top'; its faces: none"):
        Sphere(1).face_frame("top")
    with pytest.raises(ValueError, match="frustum has no face 'top'; its faces: bottom"):
        Frustum(1, 0, 1).face_frame("top")


PLANES = {"quad": {"top"}, "box": {"front", "right", "back", "left", "top", "bottom"},
          "wedge": {"right", "back", "left", "bottom", "slope"}, "cylinder": {"top", "bottom"},
          "frustum": {"top", "bottom"}, "sphere": set()}


def _random_like(prim: Primitive, rng: np.random.Generator) -> Primitive:
    """The same type with sizes drawn from 0.1–3 m (a cone stays a cone)."""
    p = rng.uniform(0.1, 3.0, len(prim.PARAMS))
    return prim.with_params(np.where(prim.params == 0, 0.0, p))


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_planes_are_named_right_handed_outward_and_on_their_mesh_faces(prim: Primitive) -> None:
    """Every flat face, for random sizes: an orthonormal right-handed frame whose normal points
    out of the solid, centred on the mesh face of the same name (a click on it picks the plane),
    every corner of that face in the plane, the mesh's normals the plane's."""
    rng = np.random.default_rng(18)
    cone = isinstance(prim, Frustum) and prim.params[1] == 0
    for _ in range(5):
        q = _random_like(prim, rng)
        assert set(q.planes()) == PLANES[q.TYPE] - ({"top"} if cone else set())
        m = q.mesh()
        centre = m.vertices.mean(axis=0)
        for name, (o, x, y, n) in q.planes().items():
            M = np.column_stack([x, y, n])
            assert M.T @ M == pytest.approx(np.eye(3), abs=1e-12), name
            assert np.linalg.det(M) == pytest.approx(1.0), name
            if not isinstance(q, Quad):
                assert (o - centre) @ n > 0, name
            v = np.unique(m.faces[m.face_ids == m.face_names.index(name) + 1])
            assert (m.vertices[v] - o) @ n == pytest.approx(np.zeros(len(v)), abs=1e-12), name
            assert m.normals[v] == pytest.approx(np.tile(n, (len(v), 1)), abs=1e-12), name
            assert m.vertices[v].mean(axis=0) == pytest.approx(o, abs=1e-12), name
            if abs(n[2]) < 1e-12:  # a vertical face: y up, x to the right seen from outside
                assert y == pytest.approx([0, 0, 1]) and np.cross(y, n) == pytest.approx(x), name
        for name, frame in q.faces().items():  # the restable faces are the same planes
            assert all(np.array_equal(a, b) for a, b in zip(frame, q.plane_frame(name), strict=True)), name


def test_plane_frames_take_trial_params_and_name_what_a_primitive_has() -> None:
    o, x, y, n = Box(1, 1, 1).plane_frame("front", [2.0, 4.0, 3.0])
    assert o == pytest.approx([0, -2, 1.5]) and x == pytest.approx([1, 0, 0]) and n == pytest.approx([0, -1, 0])
    o, x, y, n = Wedge(1, 1, 1).plane_frame("slope", [1.0, 4.0, 3.0])
    assert o == pytest.approx([0, 0, 1.5]) and y == pytest.approx([0, 0.8, 0.6]) and n == pytest.approx([0, -0.6, 0.8])
    o, _, _, n = Wedge(1, 1, 1).plane_frame("left", [1.2, 3.0, 0.9])
    assert o == pytest.approx([-0.6, 0.5, 0.3]) and n == pytest.approx([-1, 0, 0])
    with pytest.raises(ValueError, match="sphere has no flat face 'top'; its flat faces: none"):
        Sphere(1).plane_frame("top")
    with pytest.raises(ValueError, match="box has no flat face 'side'; its flat faces: front, right, back, left"):
        Box(1, 1, 1).plane_frame("side")


# ---------------------------------------------------------------------------------------------
# Meshes


def _ngon_area(r: float, s: int) -> float:
    return s / 2 * r * r * np.sin(2 * np.pi / s)


def _pyramid_frustum(a1: float, a2: float, h: float) -> float:
    return h / 3 * (a1 + a2 + np.sqrt(a1 * a2))


def _volumes(prim: Primitive, s: int) -> tuple[float, float]:
    """(exact volume of the solid, exact volume of its inscribed tessellation with s segments)."""
    if isinstance(prim, Box):
        return (v := float(np.prod(prim.params))), v
    if isinstance(prim, Wedge):
        return (v := float(np.prod(prim.params)) / 2), v
    if isinstance(prim, Sphere):
        r = prim.radius
        phi = np.linspace(-np.pi / 2, np.pi / 2, s // 2 + 1)
        rho, z = r * np.cos(phi), r * np.sin(phi)
        rho[[0, -1]] = 0.0
        bands = [_pyramid_frustum(_ngon_area(rho[j], s), _ngon_area(rho[j + 1], s), z[j + 1] - z[j])
                 for j in range(len(phi) - 1)]
        return 4 / 3 * np.pi * r**3, float(np.sum(bands))
    rb, rt, h = (prim.radius, prim.radius, prim.height) if isinstance(prim, Cylinder) else tuple(prim.params)
    exact = np.pi * h / 3 * (rb * rb + rb * rt + rt * rt)
    return exact, _pyramid_frustum(_ngon_area(rb, s), _ngon_area(rt, s), h)


@pytest.mark.parametrize("segments", [8, 32])
@pytest.mark.parametrize("prim", SOLIDS, ids=ids)
def test_solid_meshes_are_closed_outward_and_have_the_right_volume(prim: Primitive, segments: int) -> None:
    m = prim.mesh(segments=segments)
    t = trimesh.Trimesh(m.vertices, m.faces, process=True)  # merges the duplicated border vertices
    assert t.is_watertight and t.is_winding_consistent
    exact, inscribed = _volumes(prim, segments)
    assert t.volume > 0
    assert t.volume == pytest.approx(inscribed, rel=1e-9, abs=1e-12)
    # The stated tessellation error (Primitive.mesh): (2π/s)²/6 for cylinders and frustums, 2.5× for spheres.
    bound = (2 * np.pi / segments) ** 2 / 6 * (2.6 if isinstance(prim, Sphere) else 1.0)
    assert 0 <= 1 - t.volume / exact <= bound


def test_quad_mesh_is_its_rectangle_facing_up() -> None:
    m = Quad(2.0, 3.0).mesh()
    assert m.face_names == ["top"] and len(m.faces) == 2
    t = trimesh.Trimesh(m.vertices, m.faces)
    assert t.area == pytest.approx(6.0) and t.face_normals == pytest.approx(np.tile([0, 0, 1.0], (2, 1)))


def test_logical_faces() -> None:
    assert Box(1, 1, 1).mesh().face_names == ["front", "right", "back", "left", "top", "bottom"]
    assert Wedge(1, 1, 1).mesh().face_names == ["right", "back", "left", "slope", "bottom"]
    assert Cylinder(1, 1).mesh().face_names == ["side", "top", "bottom"]
    assert Frustum(1, 0, 1).mesh().face_names == ["side", "bottom"]
    assert Sphere(1).mesh().face_names == ["surface"]
    m = Box(1.0, 2.0, 3.0).mesh()
    n = dict(zip(m.face_names, [m.normals[m.faces[m.face_ids == i][0, 0]] for i in range(1, 7)], strict=True))
    assert n["front"] == pytest.approx([0, -1, 0]) and n["right"] == pytest.approx([1, 0, 0])
    assert n["back"] == pytest.approx([0, 1, 0]) and n["left"] == pytest.approx([-1, 0, 0])


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_mesh_arrays_and_normals(prim: Primitive) -> None:
    m = prim.mesh()
    nv, nf, F = len(m.vertices), len(m.faces), len(m.face_names)
    assert m.vertices.shape == (nv, 3) and m.vertices.dtype == np.float64
    assert m.faces.shape == (nf, 3) and m.faces.dtype == np.int32
    assert m.face_ids.shape == (nf,) and m.face_ids.dtype == np.int32
    assert set(m.face_ids.tolist()) == set(range(1, F + 1))  # ids start at 1; 0 means "nothing"
    assert m.uv.shape == (nv, 2) and m.normals.shape == (nv, 3)
    assert m.chart_size_m.shape == (F, 2) and m.chart_uv.shape == (F, 4)
    assert np.unique(m.faces).tolist() == list(range(nv))  # no unused vertices
    # Vertex normals are unit and agree with each triangle's winding: outward.
    assert np.linalg.norm(m.normals, axis=1) == pytest.approx(np.ones(nv))
    tri = m.vertices[m.faces]
    g = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.all(np.linalg.norm(g, axis=1) > 0)  # no degenerate triangles
    for k in range(3):
        assert np.all(np.einsum("ij,ij->i", g, m.normals[m.faces[:, k]]) > 0)
    # Vertices are duplicated at face borders: no vertex is shared by two logical faces.
    owner = np.zeros(nv, int)
    for fid, f in zip(m.face_ids, m.faces, strict=True):
        assert np.all((owner[f] == 0) | (owner[f] == fid))
        owner[f] = fid


def _uv_area(uv: np.ndarray) -> np.ndarray:
    a, b = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    return 0.5 * np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])


@pytest.mark.parametrize("tpm", [None, 200.0])
@pytest.mark.parametrize("prim", SAMPLES + [Box(1.4, 0.8, 0.04)], ids=ids)
def test_uv_charts_are_disjoint_in_the_unit_square_with_uniform_density(prim: Primitive, tpm: float | None) -> None:
    m = prim.mesh(texels_per_metre=tpm)
    assert np.all((m.uv > 0) & (m.uv < 1))
    rects = m.chart_uv
    assert np.all(rects[:, 2:] > rects[:, :2]) and np.all((rects >= 0) & (rects <= 1))
    for i in range(len(rects)):
        for j in range(i):
            a, b = rects[i], rects[j]
            assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1], (i, j)
    assert (rects[:, 2:] - rects[:, :2]) * m.atlas_size_m == pytest.approx(m.chart_size_m)
    uv = m.uv[m.faces]
    lo, hi = rects[m.face_ids - 1, None, :2], rects[m.face_ids - 1, None, 2:]
    assert np.all((uv >= lo - 1e-12) & (uv <= hi + 1e-12))  # every triangle inside its own chart
    # Texel density: exact on flat faces (the chart is the face, measured), never below nominal on curved ones.
    tri = m.vertices[m.faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    ratio = area / (_uv_area(uv) * m.atlas_size_m**2)
    flat = np.array([n not in ("side", "surface") for n in m.face_names])[m.face_ids - 1]
    assert ratio[flat] == pytest.approx(np.ones(flat.sum()), rel=1e-9)
    assert np.all(ratio[~flat] <= 1 + 1e-9)
    if tpm is not None:  # whole texels: the atlas side and every chart corner, with the gutter between
        n = m.atlas_size_m * tpm
        assert n == pytest.approx(round(n), abs=1e-6)
        corners = rects[:, :2] * n
        assert corners == pytest.approx(np.round(corners), abs=1e-6)
        assert np.all(corners >= GUTTER_TEXELS - 1e-6)


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_mesh_is_a_pure_function_of_the_params(prim: Primitive) -> None:
    a, b = prim.mesh(), prim.mesh()
    assert np.array_equal(a.vertices, b.vertices) and np.array_equal(a.uv, b.uv)
    for name in ("vertices", "uv"):
        assert getattr(prim.with_params(prim.params * 2).mesh(), name).shape == getattr(a, name).shape


def test_mesh_rejects_bad_arguments() -> None:
    with pytest.raises(ValueError, match="segments must be at least 3"):
        Cylinder(1, 1).mesh(segments=2)
    with pytest.raises(ValueError, match="texels_per_metre must be > 0"):
        Box(1, 1, 1).mesh(texels_per_metre=0)


# ---------------------------------------------------------------------------------------------
# Parameters, dicts and errors


@pytest.mark.parametrize("prim", SAMPLES, ids=ids)
def test_dict_round_trip_and_value_semantics(prim: Primitive) -> None:
    d = prim.to_dict()
    assert d["type"] == prim.TYPE and list(d["params"]) == list(prim.PARAMS)
    back = primitive_from_dict(d)
    assert type(back) is type(prim) and back == prim and hash(back) == hash(prim)
    assert type(prim).from_dict(d) == prim and Primitive.from_dict(d) == prim
    assert copy.deepcopy(prim) == prim and pickle.loads(pickle.dumps(prim)) == prim
    for name, value in d["params"].items():
        assert getattr(prim, name) == value


def test_params_are_read_only_and_with_params_makes_a_new_primitive() -> None:
    box = Box(1.0, 2.0, 3.0)
    with pytest.raises(ValueError):
        box.params[0] = 5.0
    with pytest.raises(ValueError):
        box.params.flags.writeable = True
    with pytest.raises(AttributeError):
        box.width = 5.0  # type: ignore[misc]
    taller = box.with_params({"height": 4.0})
    assert taller == Box(1.0, 2.0, 4.0) and box.height == 3.0
    assert box.with_params(np.array([3.0, 2.0, 1.0])) == Box(width=3, depth=2, height=1)
    assert Box.from_dict({"type": "box", "params": {"width": 1, "depth": 2, "height": 3}}) == box
    assert list(PRIMITIVE_TYPES) == ["quad", "box", "wedge", "cylinder", "frustum", "sphere", "room"]


@pytest.mark.parametrize(("d", "message"), [
    ({"type": "cone", "params": {}}, "expected one of quad, box, wedge, cylinder, frustum, sphere, room; got 'cone'"),
    ({"params": {}}, "expected one of quad, box, wedge, cylinder, frustum, sphere, room; got None"),
    ({"type": "box", "params": {"width": 1, "depth": 2}}, "box needs params width, depth, height; missing height"),
    ({"type": "box", "params": {"width": 1}}, "box needs params width, depth, height; missing depth, height"),
    ({"type": "box", "params": {"width": -1, "depth": 2, "height": 3}}, "box: width must be > 0, got -1.0"),
    ({"type": "sphere", "params": {"radius": 0}}, "sphere: radius must be > 0, got 0.0"),
    ({"type": "frustum", "params": {"radius_bottom": 1, "radius_top": -0.5, "height": 1}},
     "frustum: radius_top must be >= 0, got -0.5"),
    ({"type": "quad", "params": {"width": "2", "depth": 1}}, "quad: width must be a number, got '2'"),
    ({"type": "quad", "params": {"width": True, "depth": 1}}, "quad: width must be a number, got True"),
    ({"type": "quad", "params": {"width": float("nan"), "depth": 1}}, "quad: width must be a finite number, got nan"),
    ({"type": "quad", "params": {"width": 1, "depth": 1, "height": 1}},
     "quad: unknown param 'height'; expected width, depth"),
    ({"type": "quad", "params": [1, 2]}, "quad: params must be an object {width, depth}, got list"),
    (["box"], "expected an object {type, params}, got list"),
])
def test_bad_dicts_raise_value_errors_that_say_what_is_wrong(d: object, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        primitive_from_dict(d)  # type: ignore[arg-type]


def test_bad_params_elsewhere() -> None:
    with pytest.raises(ValueError, match=re.escape("box: height must be > 0, got -2.0")):
        Box(1.0, 1.0, 1.0).with_params([1.0, 1.0, -2.0])
    with pytest.raises(ValueError, match=re.escape("expected type 'box', got 'quad'")):
        Box.from_dict({"type": "quad", "params": {"width": 1, "depth": 1}})
    with pytest.raises(ValueError, match="expected params of shape"):
        Box(1, 1, 1).handles([1.0, 2.0])
    with pytest.raises(TypeError):
        Quad(1.0, 2.0, 3.0)
    assert Frustum(1.0, 0.0, 1.0).radius_top == 0.0  # a cone is allowed


def test_the_schema_lists_exactly_the_registered_primitive_types() -> None:
    """A new primitive is one class in model/primitives.py; the file format's list of types must
    name it too (and nothing that is not registered), or projects using it are refused."""
    import json
    from pathlib import Path

    import vebuild
    from vebuild.model import PRIMITIVE_TYPES

    schema = json.loads((Path(vebuild.__file__).parent / "schema" / "project-v1.schema.json").read_text())
    found = []

    def walk(node: object) -> None:
        if isinstance(node, dict):
            props = node.get("properties", {})
            # A primitive record: a type and an object of params (a relation's params are a list).
            if "type" in props and props.get("params", {}).get("type") == "object":
                found.append(node["properties"]["type"]["enum"])
            for v in node.values():
                walk(v)
        elif isinstance(node, list):
            for v in node:
                walk(v)

    walk(schema)
    assert found, "the schema has no primitive record"
    for enum in found:
        assert list(enum) == list(PRIMITIVE_TYPES)


def test_a_mesh_is_made_once_per_primitive_and_shared_read_only():
    """Equal primitives share one kept mesh (a house's screens ask again for every unchanged
    primitive's after each edit); another size, segment count or density is another mesh; the
    shared arrays cannot be written, so no caller can change another's mesh."""
    a, b = Cylinder(radius=0.31, height=0.72), Cylinder(radius=0.31, height=0.72)
    m = a.mesh(segments=16)
    assert b.mesh(segments=16) is m
    assert a.mesh(segments=24) is not m and a.mesh(None, 16) is m
    assert a.mesh(200.0, 16) is not m
    other = Cylinder(radius=0.32, height=0.72).mesh(segments=16)
    assert other is not m and not np.allclose(other.vertices.max(axis=0), m.vertices.max(axis=0))
    for arr in (m.vertices, m.faces, m.face_ids, m.normals, m.uv, m.chart_size_m, m.chart_uv):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 0
