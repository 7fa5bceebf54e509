"""What no photo saw, in a glTF export (:mod:`vebuild.render.export`; docs/manual.md, "Export"): each
atlas page's coverage map as a second image and texture named by its material's
``extras.vebuild_coverage``, and each mesh primitive's share of surface some photo saw in its
``extras.vebuild_seen``."""

from __future__ import annotations

from pathlib import PurePosixPath
from typing import Any

import numpy as np

#: The material ``extras`` key that names a page's coverage map, and the primitive ``extras`` key
#: with the share of its surface some photo saw.
COVERAGE_EXTRAS = "vebuild_coverage"
SEEN_EXTRAS = "vebuild_seen"
_NEAREST, _CLAMP_TO_EDGE = 9728, 33071


def add_coverage(doc: dict[str, Any], buf: Any, contents: Any, used: list[int],
                  materials: list[dict[str, Any]]) -> None:
    """Each used page's coverage map as an image and texture, named by its material's extras."""
    from vebuild.render.observed import LEGEND_TEXT
    from vebuild.texture.merge import COVERAGE_DROPPED_ONLY, COVERAGE_UNSEEN, COVERAGE_VIEWS

    scene = contents.scene
    if len(scene.coverage_files) != len(contents.pages):
        return
    doc["samplers"].append({"magFilter": _NEAREST, "minFilter": _NEAREST, "wrapS": _CLAMP_TO_EDGE,
                            "wrapT": _CLAMP_TO_EDGE})
    record = contents.project.data["textures"]["pages"]
    for k, mat in zip(used, materials, strict=True):
        doc["images"].append({"name": PurePosixPath(str(record[k]["coverage"])).name, "mimeType": "image/png",
                              "bufferView": buf.view(scene.coverage_files[k])})
        doc["textures"].append({"name": f"coverage page {k}", "sampler": len(doc["samplers"]) - 1,
                                "source": len(doc["images"]) - 1})
        mask = scene.masks[k]
        on = mask > 127
        mat["extras"] = {COVERAGE_EXTRAS: {
            "texture": {"index": len(doc["textures"]) - 1, "texCoord": 0},
            "sha256": scene.mask_hashes[k],
            "unseen_rgba": list(COVERAGE_UNSEEN),
            "dropped_only_rgba": list(COVERAGE_DROPPED_ONLY),
            "views_rgba": [list(c) for c in COVERAGE_VIEWS],
            "off_face_alpha": 0,
            "meaning": "per texel: unseen_rgba where no photo saw it (its colour was filled in); views_rgba[n-1] "
                       "where n photos saw it (the last: 4 or more); dropped_only_rgba where only views far worse "
                       "than the best saw it; transparent off the faces",
            "unseen_texel_share_of_page": round(float(on.mean()), 6),
            "legend": LEGEND_TEXT["hatch"]}}


def seen_extras(contents: Any, part: Any) -> dict[str, Any] | None:
    """A primitive's share of surface some photo saw (area-weighted over its faces' recorded
    ``seen_fraction``) and each face's, or None when the project has no textures record."""
    faces = {int(f["id"]): f for f in (contents.project.data.get("textures") or {}).get("faces", [])}
    if not contents.scene.textured or not faces:
        return None
    P = part.positions[part.triangles]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    fid = part.face_ids[part.triangles[:, 0]]
    out, total, seen = [], 0.0, 0.0
    for f in np.unique(fid):
        rec = faces.get(int(f))
        if rec is None:
            return None
        a = float(area[fid == f].sum())
        total += a
        seen += a * float(rec["seen_fraction"])
        out.append({"id": int(f), "face": rec["face"], "seen_fraction": rec["seen_fraction"],
                    "area_m2": round(a, 6)})
    return {"seen_fraction": round(seen / total, 6) if total else 0.0,
            "unseen_area_m2": round(total - seen, 6), "faces": out}
