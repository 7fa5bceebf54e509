"""Named evidence views and photos' cameras as :class:`~vebuild.camera.ImageCamera` (pure numpy).

A view (FORMAT.md, ``views``) is a position, a look direction (``direction``, or ``look_at`` a
point), an optional roll, a horizontal field of view (``fov_deg``, default
:data:`DEFAULT_FOV_DEG`) or a 35 mm-equivalent focal length (``focal_length_mm``, over a 36 mm
wide frame), and an image size. Its principal point is the image centre.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vebuild.camera import ImageCamera, focal_to_fov, fov_to_focal, intrinsic_matrix, look_rotation, ypr_from_rotation
from vebuild.errors import ProjectError
from vebuild.project import Project

#: Horizontal field of view of a view that gives neither ``fov_deg`` nor ``focal_length_mm``.
DEFAULT_FOV_DEG = 60.0
#: Width of the 35 mm film frame, for 35 mm-equivalent focal lengths.
FRAME_35MM_WIDTH_MM = 36.0


def view_camera(view: dict[str, Any], where: str = "") -> ImageCamera:
    """The camera of one view record (validated by the project's schema); ``where``: its JSON path
    (``$.views[2]``), which the camera's :attr:`~vebuild.camera.ImageCamera.source` names."""
    C = np.asarray(view["position"], float)
    direction = np.asarray(view["look_at"], float) - C if "look_at" in view else np.asarray(view["direction"], float)
    R = look_rotation(direction, np.radians(view.get("roll_deg", 0.0)))
    w, h = int(view["width"]), int(view["height"])
    if "focal_length_mm" in view:
        f = view["focal_length_mm"] / FRAME_35MM_WIDTH_MM * w
    else:
        f = fov_to_focal(np.radians(view.get("fov_deg", DEFAULT_FOV_DEG)), w)
    K = intrinsic_matrix(f, w / 2, h / 2)
    return ImageCamera(view["name"], K, R, C, w, h,
                       source=f"{where or 'view ' + repr(view['name'])} (width × height)")


def view_record(cam: ImageCamera, name: str, description: str | None = None) -> dict[str, Any]:
    """A view record (FORMAT.md) that reproduces ``cam``: its position, look direction, roll and
    horizontal field of view (the principal point is taken as the image centre)."""
    R = np.asarray(cam.R, float)
    roll = float(np.degrees(ypr_from_rotation(R)[2]))
    fov = float(np.degrees(focal_to_fov(cam.K[0, 0], cam.width)))
    out: dict[str, Any] = {"name": name, "position": [float(v) for v in cam.C],
                           "direction": [float(v) for v in R[2]], "roll_deg": roll,
                           "fov_deg": fov, "width": int(cam.width), "height": int(cam.height)}
    if description:
        out["description"] = description
    return out


def find_view(project: Project, name: str) -> ImageCamera:
    """The camera of the view called ``name``; an error listing the views if there is none."""
    views = project.data.get("views", [])
    for i, v in enumerate(views):
        if v["name"] == name:
            return view_camera(v, f"$.views[{i}]")
    known = ", ".join(repr(v["name"]) for v in views) or "none (add them under \"views\")"
    raise ProjectError(project.path, "$.views", f"no view is called {name!r}; the views are: {known}")


def photo_camera(project: Project, photo: str) -> ImageCamera:
    """The calibrated camera of a photo, by id (or by its 1-based position in ``photos``)."""
    ids = [p["id"] for p in project.data["photos"]]
    if photo not in ids and photo.isdigit() and 1 <= int(photo) <= len(ids):
        photo = ids[int(photo) - 1]
    if photo not in ids:
        raise ProjectError(project.path, "$.photos", f"no photo has the id {photo!r}; the photos are: "
                           + (", ".join(repr(i) for i in ids) or "none"))
    cam = ((project.data.get("calibration") or {}).get("cameras") or {}).get(photo)
    if cam is None:
        raise ProjectError(project.path, "$.calibration.cameras",
                           f"photo {photo!r} has no calibrated camera; run `vebuild calibrate` (or `vebuild register`)")
    # Decoded, checked (K a pinhole matrix, R a rotation), by the one decoder every command uses.
    from vebuild.actions.solve import cameras_from_calibration
    checked = cameras_from_calibration(project)[photo]
    p = project.photo(photo)
    i = ids.index(photo)
    return ImageCamera(photo, checked.K, checked.R, checked.C, int(p["width"]), int(p["height"]),
                       source=f"$.photos[{i}] (photo {photo!r}: width × height)")
