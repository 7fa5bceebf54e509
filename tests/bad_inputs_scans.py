"""Bad-input cases of laser scans for tests/bad_inputs_corpus.py: scan files whose header disagrees
with their body (PLY ASCII and binary, LAS, LAZ, E57: more points declared than held, fewer, 10¹²,
a body cut short, data after the last point) and scans with too many non-finite points, through
``vebuild scan add`` and, recorded in the project with their true hash, ``vebuild scan check`` and
``vebuild check``.

:data:`SCAN_CASES` holds (name, mutation, commands, what the message names); the corpus adds each
with its ``case()``. A mutation writes the scan file into the copied project folder (and, for the
recorded cases, its ``$.scans`` entry into the document)."""

from __future__ import annotations

import hashlib
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

N = 1200
#: Three syntactically valid targets: a scan is read before its targets are resolved.
TARGETS = ["--target=T0=0,0,0:floor:v0", "--target=T1=1,0,0:floor:v1", "--target=T2=0,1,0:floor:v2"]


def _points() -> np.ndarray:
    return np.random.default_rng(5).normal(0, 2.0, size=(N, 3)) + [2.0, 2.0, 1.0]


def _ply(ascii_: bool, n: int | None = None, extra: bytes = b"", non_finite: int = 0) -> bytes:
    import trimesh

    P = _points()
    P[:non_finite, 0] = np.nan
    raw = trimesh.PointCloud(P).export(file_type="ply", encoding="ascii" if ascii_ else "binary")
    if n is not None:
        raw = raw.replace(f"element vertex {N}\n".encode(), f"element vertex {n}\n".encode(), 1)
    return raw + extra


def _las(path: Path, fmt: str, n: int | None = None, extra: bytes = b"") -> bytes:
    import laspy

    header = laspy.LasHeader(point_format=0, version="1.2")
    P = _points()
    header.offsets, header.scales = np.floor(P.min(axis=0)), np.array([1e-5] * 3)
    las = laspy.LasData(header)
    las.x, las.y, las.z = P.T
    las.write(str(path.with_suffix("." + fmt)))
    raw = path.with_suffix("." + fmt).read_bytes()
    if n is not None:
        raw = raw[:107] + struct.pack("<I", n) + raw[111:]
    return raw + extra


def _e57(path: Path, n: int) -> bytes:
    import pye57
    from scan_scene import rewrite_e57_xml

    P = _points()
    e57 = pye57.E57(str(path), mode="w")
    e57.write_scan_raw({"cartesianX": P[:, 0].copy(), "cartesianY": P[:, 1].copy(), "cartesianZ": P[:, 2].copy()})
    e57.close()
    return rewrite_e57_xml(path.read_bytes(), lambda x: x.replace(f'recordCount="{N}"'.encode(),
                                                                  f'recordCount="{n}"'.encode()))


def _write(name: str, make: Callable[[Path], bytes], record: bool = False) -> Callable[[Any], None]:
    """Write the scan file ``name`` into the project folder (made by ``make``, given its path);
    with ``record``, its ``$.scans`` entry too, with its true hash and the identity registration."""
    def mutate(ctx: Any) -> None:
        path = ctx.folder / name
        data = make(path)
        path.write_bytes(data)
        if record:
            targets = [{"name": f"T{k}", "scan_xyz": xyz, "point": f"floor:v{k}", "project_xyz": xyz}
                       for k, xyz in enumerate(([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]))]
            ctx.doc["scans"] = [{
                "file": name, "sha256": hashlib.sha256(data).hexdigest(), "format": name.rsplit(".", 1)[1],
                "point_count": N, "use_in_solve": False,
                "registration": {"targets": targets,
                                 "similarity": {"scale": 1.0, "rotation": [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]],
                                                "translation": [0.0, 0.0, 0.0]},
                                 "rms_m": 0.0,
                                 "residuals": [{"name": t["name"], "residual_m": [0.0, 0.0, 0.0], "distance_m": 0.0}
                                               for t in targets]}}]
    return mutate


def _add(name: str) -> list[list[str]]:
    return [["scan", "add", "{P}", "{D}/" + name, *TARGETS]]


#: (case name, mutation, commands, what the message must name).
SCAN_CASES: list[tuple[str, Callable[[Any], None], list[Any], list[Any]]] = [
    ("scan-ply-ascii-claims-10^12", _write("scan.ply", lambda p: _ply(True, 10**12)), _add("scan.ply"),
     ["{D}/scan.ply", "SCANFILE", "element vertex 1000000000000"]),
    ("scan-ply-ascii-claims-fewer", _write("scan.ply", lambda p: _ply(True, N - 200)), _add("scan.ply"),
     ["{D}/scan.ply", "element vertex 1000"]),
    ("scan-ply-ascii-extra-line", _write("scan.ply", lambda p: _ply(True, extra=b"1 2 3\n")), _add("scan.ply"),
     ["{D}/scan.ply", "element vertex 1200", "holds 1201"]),
    ("scan-ply-binary-claims-more", _write("scan.ply", lambda p: _ply(False, N + 100)), _add("scan.ply"),
     ["{D}/scan.ply", "element vertex 1300"]),
    ("scan-ply-binary-extra-bytes", _write("scan.ply", lambda p: _ply(False, extra=bytes(12))), _add("scan.ply"),
     ["{D}/scan.ply", "element vertex 1200"]),
    ("scan-ply-non-finite-over-1-percent", _write("scan.ply", lambda p: _ply(False, non_finite=13)),
     _add("scan.ply"), ["{D}/scan.ply", "13 of its 1200 points", "non-finite"]),
    ("scan-las-claims-more", _write("scan.las", lambda p: _las(p, "las", N + 100)), _add("scan.las"),
     ["{D}/scan.las", "point count 1300"]),
    ("scan-las-claims-fewer", _write("scan.las", lambda p: _las(p, "las", N - 200)), _add("scan.las"),
     ["{D}/scan.las", "point count 1000"]),
    ("scan-las-extra-bytes", _write("scan.las", lambda p: _las(p, "las", extra=bytes(20))), _add("scan.las"),
     ["{D}/scan.las", "point count 1200"]),
    ("scan-laz-extra-bytes", _write("scan.laz", lambda p: _las(p, "laz", extra=bytes(20))), _add("scan.laz"),
     ["{D}/scan.laz", "chunk table"]),
    ("scan-e57-claims-more", _write("scan.e57", lambda p: _e57(p, N + 100)), _add("scan.e57"),
     ["{D}/scan.e57", "recordCount 1300"]),
    ("scan-e57-claims-fewer", _write("scan.e57", lambda p: _e57(p, N - 200)), _add("scan.e57"),
     ["{D}/scan.e57", "recordCount 1000"]),
    ("scan-recorded-ply-claims-fewer", _write("scan.ply", lambda p: _ply(True, N - 200), record=True),
     ["scan-check", "check"], ["{D}/scan.ply", "$.scans[0].file", "element vertex 1000"]),
    ("scan-recorded-e57-claims-more", _write("scan.e57", lambda p: _e57(p, N + 100), record=True),
     ["scan-check", "check"], ["{D}/scan.e57", "$.scans[0].file", "recordCount 1300"]),
]
