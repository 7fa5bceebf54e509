"""Synthetic laser scans of a model: points sampled on its true surfaces with Gaussian noise of a
known σ along each face's normal, put in a scan frame by a known similarity, written as PLY, LAS,
LAZ or E57 with the libraries vebuild reads them with."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vebuild.analysis.scans import world_faces
from vebuild.calibration.similarity import Similarity


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def sample_surfaces(model, n: int, sigma: float, rng: np.random.Generator, skip: set[tuple[str, str]] = frozenset()
                    ) -> tuple[np.ndarray, np.ndarray]:
    """n points on the model's faces (area-weighted), each moved by N(0, σ²) along its face's normal;
    also the index into world_faces(model).names of the face each lies on."""
    faces = world_faces(model)
    T = faces.triangles
    keep = np.array([faces.names[f] not in skip for f in faces.face_of])
    T, owner = T[keep], faces.face_of[keep]
    area = 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)
    k = rng.choice(len(T), size=n, p=area / area.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    a, b, c = T[k, 0], T[k, 1], T[k, 2]
    normal = np.cross(b - a, c - a)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    P = a + u[:, None] * (b - a) + v[:, None] * (c - a) + rng.normal(0, sigma, n)[:, None] * normal
    return P, owner[k]


def to_scan_frame(sim: Similarity, world: np.ndarray) -> np.ndarray:
    """The inverse of ``sim``: world = s R x + t  ⇒  x = Rᵀ (world − t) / s."""
    return (np.asarray(world, float) - sim.translation) @ sim.rotation / sim.scale


def colours_of(P: np.ndarray) -> np.ndarray:
    return (np.abs(np.sin(P * 3.0)) * 255).astype(np.uint8)


def write_ply(path: Path, P: np.ndarray, colours: np.ndarray | None = None) -> None:
    import trimesh

    cloud = trimesh.PointCloud(P, colors=None if colours is None else np.c_[colours, np.full(len(P), 255)])
    Path(path).write_bytes(cloud.export(file_type="ply"))


def write_las(path: Path, P: np.ndarray, colours: np.ndarray | None = None, resolution: float = 1e-5) -> None:
    """LAS or LAZ (by the ending), point format 2 (with RGB) or 0; coordinates stored to ``resolution``."""
    import laspy

    header = laspy.LasHeader(point_format=2 if colours is not None else 0, version="1.2")
    header.offsets = np.floor(P.min(axis=0))
    header.scales = np.array([resolution] * 3)
    las = laspy.LasData(header)
    las.x, las.y, las.z = P[:, 0], P[:, 1], P[:, 2]
    if colours is not None:
        las.red, las.green, las.blue = (colours.astype(np.uint16) * 257).T
    las.write(str(path))


def write_e57(path: Path, P: np.ndarray, colours: np.ndarray | None = None) -> None:
    import pye57

    e57 = pye57.E57(str(path), mode="w")
    data = {"cartesianX": P[:, 0].copy(), "cartesianY": P[:, 1].copy(), "cartesianZ": P[:, 2].copy()}
    if colours is not None:
        for k, name in enumerate(("colorRed", "colorGreen", "colorBlue")):
            data[name] = colours[:, k].astype(np.uint8).copy()
    e57.write_scan_raw(data)
    e57.close()


WRITERS = {"ply": write_ply, "las": write_las, "laz": write_las, "e57": write_e57}


# ----------------------------------------------------------------------------------------------
# Files whose header lies: the E57 XML section rewritten, its pages' CRC-32C checksums made again


def _crc32c_table() -> list[int]:
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
        table.append(c)
    return table


_CRC32C = _crc32c_table()


def crc32c(data: bytes) -> int:
    """CRC-32C (Castagnoli), the checksum of each page of an E57 file."""
    c = 0xFFFFFFFF
    for b in data:
        c = _CRC32C[(c ^ b) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF


def rewrite_e57_xml(raw: bytes, edit) -> bytes:
    """An E57 file (as pye57 writes it: the XML section last) with its XML replaced by
    ``edit(xml_bytes)``, the header's lengths and every page's checksum made to match, so that
    libE57Format reads it as a well-formed file: a header that lies, not a damaged page."""
    import struct

    pages = [raw[i : i + 1024] for i in range(0, len(raw), 1024)]
    logical = bytearray(b"".join(p[:1020] for p in pages))
    sig, major, minor, _, xml_at, xml_length, page = struct.unpack("<8sIIQQQQ", logical[:48])
    start = xml_at - (xml_at // 1024) * 4
    xml = edit(bytes(logical[start : start + xml_length]))
    logical = logical[:start] + xml
    n = -(-len(logical) // 1020)
    logical += b"\0" * (n * 1020 - len(logical))
    logical[:48] = struct.pack("<8sIIQQQQ", sig, major, minor, n * 1024, xml_at, len(xml), page)
    out = bytearray()
    for i in range(n):
        data = bytes(logical[i * 1020 : (i + 1) * 1020])
        out += data + struct.pack(">I", crc32c(data))
    return bytes(out)


def write_ply_text(path: Path, P: np.ndarray) -> None:
    """An ASCII PLY of the points (as trimesh writes it)."""
    import trimesh

    Path(path).write_bytes(trimesh.PointCloud(P).export(file_type="ply", encoding="ascii"))
