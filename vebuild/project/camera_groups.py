"""The checks of the user's camera groups (scenes/FORMAT.md "Camera groups"), beyond the schema's.

Each named photo exists, is in one group only, and is not released from groups (``own_camera``);
a group's photos have one size as displayed (one camera held one way: one principal point).
"""

from __future__ import annotations

from typing import Any

from ..errors import ProjectError
from .validation import listing


def check_camera_groups(data: dict[str, Any], file: Any) -> None:
    """Raise ProjectError naming the file, the field and what was expected."""
    photos = {p["id"]: (i, p) for i, p in enumerate(data["photos"])}
    first_group: dict[str, int] = {}
    ids: dict[str, int] = {}
    for i, g in enumerate(data.get("camera_groups") or []):
        where = f"$.camera_groups[{i}]"
        if g["id"] in ids:
            raise ProjectError(file, f"{where}.id", f"the camera group id {g['id']!r} is already used by "
                               f"$.camera_groups[{ids[g['id']]}]; each camera group id must be unique")
        ids[g["id"]] = i
        size = None
        for k, pid in enumerate(g["photos"]):
            here = f"{where}.photos[{k}]"
            if pid not in photos:
                raise ProjectError(file, here, f"names the photo {pid!r}, but $.photos has no photo of that id "
                                   f"(the photos are: {listing(list(photos))})")
            if pid in first_group:
                raise ProjectError(file, here, f"the photo {pid!r} is already in $.camera_groups[{first_group[pid]}]; "
                                   "expected each photo in one camera group at most (a photo was taken with one "
                                   "camera)")
            first_group[pid] = i
            j, photo = photos[pid]
            if photo.get("own_camera"):
                raise ProjectError(file, here, f"the photo {pid!r} is released from camera groups ($.photos[{j}]."
                                   "own_camera is true); expected it either in a group or released: remove it "
                                   "from the group, or its own_camera")
            wh = (photo["width"], photo["height"])
            if size is None:
                size = (pid, wh)
            elif wh != size[1]:
                raise ProjectError(file, here, f"the photo {pid!r} is {wh[0]}×{wh[1]} px, but {size[0]!r}, the "
                                   f"group's first, is {size[1][0]}×{size[1][1]} px; expected the photos of one "
                                   "camera group to have one size as displayed (one camera, held one way: a "
                                   "photo turned a quarter or cropped has another principal point), so put it "
                                   "in a group of its own")
