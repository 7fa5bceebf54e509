"""The generated L-shaped room to model by clicking (vebuild.synthetic.click_room), calibrated
headlessly (`vebuild calibrate`, as a user would have before modelling), and the true pixels a user
clicks on it: shared by tests/test_room_clicks.py and tests/test_edit_room_clicks_window.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from vebuild.cli import main
from vebuild.synthetic import CLICK_NOISE_PX, project_points, projection_matrix
from vebuild.synthetic.click_room import ClickRoom, click_room

#: The seed of the room the tests model.
SEED = 7
#: The photo the clicks are made on (it sees every floor corner, the doorway and the table).
PHOTO = "p1"
#: The room bench's tolerance on a solved dimension: 1 cm per metre of its true value, and 1 cm
#: under a metre (vebuild/bench/rooms.py, "dimension_error_worst_cm_per_m"). With the clicks'
#: 0.7 px noise (1σ), a corner 4–9 m from the camera (f ≈ 1230 px) moves 2.3–5 mm (1σ) along the
#: floor, and the calibration's camera position (1σ 1–2 cm, 9 m from the far wall) moves the
#: floor by a fraction of a per cent: inside it by about two σ, and far below what a wrong
#: convention (a wall's thickness, a sign, a swapped corner: tens of centimetres) makes.
TOL_PER_M = 0.01


def calibrated_room(folder: Path) -> tuple[ClickRoom, Path]:
    """The room, its project written and calibrated (exit 0) in ``folder``."""
    room = click_room(np.random.default_rng(SEED))
    path = room.write(folder)
    assert main(["calibrate", str(path), "--quiet"]) == 0
    return room, path


def true_pixels(room: ClickRoom, X: np.ndarray, rng: np.random.Generator | None = None) -> np.ndarray:
    """The pixels (n, 2) of world points X (n, 3) in PHOTO, with a click's noise when ``rng`` is given."""
    cam = next(p for p in room.photos if p.id == PHOTO)
    uv, depth = project_points(projection_matrix(cam.K, cam.R, cam.C), np.atleast_2d(X))
    assert np.all(depth > 0)
    return uv + (rng.normal(0.0, CLICK_NOISE_PX, uv.shape) if rng is not None else 0.0)


def table_clicks(room: ClickRoom) -> tuple[list[int], int]:
    """The table's three bottom corners a user sees and clicks in turn round it (the one nearest the
    camera and its two neighbours; the far one is hidden), and the top corner over the nearest."""
    cam = next(p for p in room.photos if p.id == PHOTO)
    k = int(np.argmin(np.linalg.norm(room.table_corners()[:4] - cam.C, axis=1)))
    return [(k - 1) % 4, k, (k + 1) % 4], 4 + k


def worst_error_per_m(solved: dict[str, float], truth: dict[str, float]) -> tuple[float, str]:
    """The largest error per metre over the truth's dimensions, as the room bench counts it
    (vebuild/bench/rooms.py, room_figures): |solved − true| / max(|true|, 1 m), so that a
    dimension under a metre (a doorway's width, a table's height) is held to 1 cm; and which."""
    errs = {k: abs(solved[k] - v) / max(abs(v), 1.0) for k, v in truth.items()}
    worst = max(errs, key=lambda k: errs[k])
    return errs[worst], worst
