"""The ID pass's erosion (paper §4, Figure 8): the face borders and silhouettes seen from a photo,
drawn over its ID buffer as "nothing" so that no texel is taken from a pixel that blends an
occluder's edge into the surface behind it (:meth:`vebuild.texture.gpu.Extractor.id_pass`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera, world_to_camera
from vebuild.texture.layout import SceneMesh

#: Edges are moved this share of their depth toward the camera (the same pixels, nearer) so that
#: their band, drawn at the edge's own depth, wins the depth test over the faces it borders where
#: a face recedes: 0.5 % covers a face whose depth changes 0.25 % per pixel across a 2-pixel band;
#: a face receding faster keeps a thinner band on its own side (seen on the example's table edge
#: at 0.3 % per pixel). An edge hidden less than 0.5 % behind a nearer surface (1.5 cm at 3 m) is
#: drawn too: a little more erosion there. 1 % drew the legs' hidden tops through the table top.
EDGE_SHRINK = 1.0 - 5e-3


def edge_lines(mesh: SceneMesh, border: NDArray[np.intp], interior: NDArray[np.intp], cam: ImageCamera,
               near: float) -> NDArray[np.float32]:
    """Face borders and the silhouettes of curved faces seen from ``cam``, clipped to z > near: the
    ID pass's lines (pairs of world points), drawn as its erosion band. ``border`` and ``interior``
    are :meth:`SceneMesh.boundary_edges`'s."""
    V = mesh.vertices
    t = mesh.triangles
    if len(interior):
        tri_n = np.cross(V[t[:, 1]] - V[t[:, 0]], V[t[:, 2]] - V[t[:, 0]])
        facing = np.einsum("ij,ij->i", tri_n, cam.C - V[t[:, 0]]) > 0
        sil = interior[facing[interior[:, 2]] != facing[interior[:, 3]], :2]
        edges = np.concatenate([border, sil])
    else:
        edges = border
    a, b = V[edges[:, 0]], V[edges[:, 1]]
    za = world_to_camera(cam.R, cam.C, a)[:, 2]
    zb = world_to_camera(cam.R, cam.C, b)[:, 2]
    z0 = 1.01 * near / EDGE_SHRINK
    keep = (za > z0) | (zb > z0)
    a, b, za, zb = a[keep], b[keep], za[keep], zb[keep]
    # Move an end behind the near plane onto it.
    with np.errstate(divide="ignore", invalid="ignore"):  # where() drops the unused quotients
        t_a = np.where(za < z0, (z0 - za) / (zb - za), 0.0)[:, None]
        t_b = np.where(zb < z0, (z0 - zb) / (za - zb), 0.0)[:, None]
    a, b = a + t_a * (b - a), b + t_b * (a - b)
    return np.stack([a, b], axis=1).reshape(-1, 3).astype("f4")
