"""The example room without its vanishing segments, one photo keeping only a few of its marker
sightings (tests/test_orientation.py, tests/test_edit_x_axis_unresolved.py)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"


def stripped_room(folder: Path, photo: str, kept: int) -> Path:
    """The example room copied to ``folder`` with every vanishing segment removed and ``photo``
    keeping only its first ``kept`` marker sightings (by name); the copy's project file."""
    shutil.copytree(ROOM, folder)
    path = folder / "room.vebuild.json"
    doc = json.loads(path.read_text())
    for p in doc["photos"]:
        p.pop("vanishing_segments", None)
        p.pop("vanishing_segment_sigmas", None)
        if p["id"] == photo:
            p["marker_observations"] = dict(sorted(p["marker_observations"].items())[:kept])
    path.write_text(json.dumps(doc))
    return path
