"""A registered photo's uncertainty, counted once (issue 17): over generated projects that register
a photo (``vebuild register``) from the solved model's vertices, the registered camera's 95 %
intervals, and after ``vebuild solve --recalibrate`` those of the model vertices the registered
photo sees, cover the truth 95 % of the time: neither too seldom nor too often.

Each project is vebuild.synthetic.model_scene's floor and three boxes seen by five known cameras:
four are calibrated exactly (covariance 0, so that the only uncertainties are the clicks' and
what follows from them), the fifth is left out, the model solved from the four, then the fifth
registered from its pins alone (no vanishing points), then the whole re-calibrated.

Measured at this commit (seeds 0–119, 67 usable scenes): the registered camera's position 97.0 %
of 201 axes (χ² over the 3 axes: 94.0 % of 67), the re-calibrated vertex 93.2 % of 148 axes.
With the model's vertices taken as exact and the registered photo held in the re-calibration by
its registration (vebuild before issue 17): 91.5 %, 83.6 % and 87.8 %.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from vebuild.actions.register import register_photos
from vebuild.actions.solve import solve_project
from vebuild.constants import Z95
from vebuild.errors import VebuildError
from vebuild.model.scene import model_from_dict
from vebuild.project import load_project
from vebuild.project.records import camera_record
from vebuild.synthetic import model_scene, write_project

#: Seeds tried. Some scenes cannot be used, as a user could not either: the four photos leave a
#: box's dimension undetermined (`vebuild solve` refuses), or the sixth sees fewer than 4 solved
#: vertices (`vebuild register` refuses); the rest (about 55 %) are the trials.
SEEDS = range(120)
#: The least number of usable scenes for the bounds below to mean something.
MIN_SCENES = 50
N_PHOTOS, N_BOXES = 5, 3
#: Two-sided bound on the observed coverage: the nominal 95 % ± this many binomial standard
#: deviations sqrt(0.95 · 0.05 / n), n the number of intervals counted (3 per scene: the axes;
#: 2.5σ: a correct implementation fails about 1 % of the time on other seeds). The three axes of
#: one camera or vertex are correlated, which widens the true spread a little; 2.5σ leaves room.
Z_BINOMIAL = 2.5
#: The 95 % quantile of χ² with 3 degrees of freedom (a camera's position).
CHI2_3_95 = 7.815


def _scene(seed: int, folder: Path) -> tuple[np.ndarray, float, np.ndarray] | None:
    """(z of the registered camera's position per axis, its χ² over the axes with the full 3×3
    covariance, z of the re-calibrated model's least-pinned box vertex that the registered photo
    pins, per axis that has a 1σ: a bottom corner's z is the floor's, exact), or None for an
    unusable scene."""
    rng = np.random.default_rng(seed)
    truth, start, pins, photos = model_scene(rng, n_boxes=N_BOXES, n_photos=N_PHOTOS)
    reg_id = f"p{N_PHOTOS}"
    path = write_project(folder, list(photos.values()), {"O": np.zeros(3), "M1": np.array([1.0, 0.0, 0.0])})
    project = load_project(path)
    data = project.data
    data["reference_distances"], data["markers"] = [], [{"name": "O"}]
    start["nodes"][0]["hold"] = ["width", "depth"]  # the floor's size taped (its corners are out of view)
    data["model"] = {"nodes": start["nodes"], "pins": pins}
    data["calibration"] = {
        "cameras": {p.id: {"mode": "3vp", **camera_record(p.K, p.R, p.C, np.zeros((9, 9)))}
                    for p in photos.values() if p.id != reg_id},
        "lengths": "metres", "origin_marker": "O",
        "markers": {"O": {"position": [0.0, 0.0, 0.0], "sigma": [0.0, 0.0, 0.0]}}}
    try:
        solve_project(project)
        reg = register_photos(project, [reg_id])[reg_id]
    except VebuildError:
        return None
    err = reg.C - photos[reg_id].C
    z_camera = err / np.sqrt(np.diag(reg.covariance)[6:9])
    chi2 = float(err @ np.linalg.solve(reg.covariance[6:9, 6:9], err))
    solve_project(project, recalibrate=True)
    true_model = model_from_dict(truth["nodes"], {"O": np.zeros(3)})
    seen = {(p["node"], p["handle"]) for p in pins if p["photo"] == reg_id and p["node"] != "floor"}
    count = {v: sum((p["node"], p["handle"]) == v for p in pins) for v in seen}
    node, handle = min(sorted(seen), key=lambda v: count[v])
    h = project.data["model_solution"]["nodes"][node]["handles"][handle]
    sigma = np.asarray(h["sigma"], float)
    err = np.asarray(h["value"]) - true_model.handle_world(node, handle)
    return z_camera, chi2, err[sigma > 0] / sigma[sigma > 0]


#: Every test here shares `trials`: they run in one pytest-xdist worker (`--dist loadgroup`,
#: pyproject's addopts), so that it is computed once, not once per worker.
pytestmark = pytest.mark.xdist_group("register_coverage.trials")


@pytest.fixture(scope="module")
def trials(tmp_path_factory: pytest.TempPathFactory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    folder = tmp_path_factory.mktemp("register-coverage")
    out = [r for s in SEEDS if (r := _scene(s, folder / str(s))) is not None]
    assert len(out) >= MIN_SCENES
    return (np.concatenate([r[0] for r in out]), np.array([r[1] for r in out]),
            np.concatenate([r[2] for r in out]))


def _bounds(n: int) -> tuple[float, float]:
    spread = Z_BINOMIAL * np.sqrt(0.95 * 0.05 / n)
    return 0.95 - spread, 0.95 + spread


Trials = tuple[np.ndarray, np.ndarray, np.ndarray]


def test_registered_camera_covers_its_true_position(trials: Trials) -> None:
    """Per axis, and as a χ² over the three axes (one per scene: at 67 scenes its upper bound
    lies above 100 %, so only too low a coverage can fail it)."""
    z, chi2 = trials[0], trials[1]
    lo, hi = _bounds(len(z))
    assert lo <= float(np.mean(np.abs(z) < Z95)) <= hi
    lo, hi = _bounds(len(chi2))
    assert lo <= float(np.mean(chi2 < CHI2_3_95)) <= hi


def test_recalibrated_vertex_seen_by_the_registered_photo_covers_the_truth(trials: Trials) -> None:
    """The box vertex the registered photo pins that the fewest photos pin, after re-calibration."""
    z = trials[2]
    lo, hi = _bounds(len(z))
    assert lo <= float(np.mean(np.abs(z) < Z95)) <= hi
