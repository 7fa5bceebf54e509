"""Which photos were taken with one camera, and so share its intrinsics (scenes/FORMAT.md "Camera groups").

Pure functions over the project's photo records and its ``camera_groups`` (plain data, as
:mod:`.exif` reads them). Two rules, the user's first:

1. the user's groups (``camera_groups``: an id and its photos), whatever EXIF says;
2. EXIF: photos that record the same make, model, body serial (where recorded), focal length in
   millimetres and orientation, and have the same size as displayed, are one camera. A body serial
   tells two bodies of one model apart; where EXIF records none (many cameras do not write one, and
   editors strip it), two bodies of one model at one focal length are merged: their photos then
   share one focal length and principal point although each body has its own, which a photo whose
   lines contradict the group's focal length beyond 3σ reveals (it is released, with a warning),
   and the group's record says the serial was missing. Photos without EXIF (or without make, model
   or focal length) are not grouped unless the user groups them.

A photo with ``own_camera: true`` is in no group: released from its EXIF group by the user.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class CameraGroup:
    """Photos of one camera: their ids in project order, the group's id, how it was found
    (``"exif"`` or ``"user"``), and for an EXIF group its camera and whether a body serial told it
    apart (``serial`` None: none recorded, two bodies of that model would be merged)."""

    id: str
    photos: tuple[str, ...]
    source: str
    camera: str = ""
    serial: str | None = None


def exif_camera_key(photo: Mapping[str, Any]) -> tuple[Any, ...] | None:
    """What makes two photos one camera by EXIF (module docstring), or None where EXIF cannot say."""
    exif = photo.get("exif") or {}
    make, model, f_mm = exif.get("make"), exif.get("model"), exif.get("focal_length_mm")
    if not make or not model or not f_mm:
        return None
    return (" ".join(str(make).split()).lower(), " ".join(str(model).split()).lower(), exif.get("body_serial"),
            float(f_mm), int(exif.get("orientation", 1)), int(photo["width"]), int(photo["height"]))


def _exif_name(photo: Mapping[str, Any]) -> tuple[str, str | None]:
    exif = photo["exif"]
    serial = exif.get("body_serial")
    name = f"{' '.join(str(exif['make']).split())} {' '.join(str(exif['model']).split())}"
    if serial:
        name += f" #{serial}"
    return f"{name} at {float(exif['focal_length_mm']):g} mm", serial


def camera_groups(photos: Sequence[Mapping[str, Any]], user_groups: Sequence[Mapping[str, Any]] = (),
                  only: set[str] | None = None) -> list[CameraGroup]:
    """The camera groups of a project's photos: the user's, then EXIF's (module docstring).

    only : the photos that can take part (those with vanishing segments); a group keeps its
        members among them and is a group only with two or more.
    """
    by_id = {p["id"]: p for p in photos}
    order = {p["id"]: i for i, p in enumerate(photos)}
    ok = set(by_id) if only is None else only & set(by_id)
    out: list[CameraGroup] = []
    taken: set[str] = set()
    for g in user_groups:
        members = tuple(sorted((pid for pid in g["photos"] if pid in ok), key=order.__getitem__))
        taken.update(g["photos"])
        if len(members) >= 2:
            out.append(CameraGroup(str(g["id"]), members, "user"))
    keyed: dict[tuple[Any, ...], list[str]] = {}
    for p in photos:
        if p["id"] in taken or p["id"] not in ok or p.get("own_camera"):
            continue
        key = exif_camera_key(p)
        if key is not None:
            keyed.setdefault(key, []).append(p["id"])
    names: dict[str, int] = {}
    exif_groups = []
    for key, ids in keyed.items():
        if len(ids) < 2:
            continue
        name, serial = _exif_name(by_id[ids[0]])
        names[name] = names.get(name, 0) + 1
        exif_groups.append((name, key, ids, serial))
    used = {g.id for g in out}
    for name, key, ids, serial in exif_groups:
        gid = name if names[name] == 1 else f"{name}, {key[5]}×{key[6]} px, orientation {key[4]}"
        while gid in used:
            gid += "'"
        used.add(gid)
        out.append(CameraGroup(gid, tuple(ids), "exif", name, serial))
    return out
