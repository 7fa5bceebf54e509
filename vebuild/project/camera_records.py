"""The camera records that the stages after the calibration use: the calibration's, each replaced
by its re-calibration where the solution has one. Read from the document alone, so that both the
decoder (:mod:`.cameras`) and the record of what a result was computed from (:mod:`.provenance`)
can ask."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any


def camera_records(data: Mapping[str, Any]) -> dict[str, Mapping[str, Any]]:
    """The camera records later stages use, by photo id: the calibration's
    (``calibration.cameras``), each replaced by the re-calibrated one of the solution
    (``model_solution.cameras``, written by ``vebuild solve --recalibrate``) where it has one (a
    re-calibrated camera of a photo whose calibrated camera was deleted is not used)."""
    out = dict((data.get("calibration") or {}).get("cameras") or {})
    out.update(recalibrated_cameras(data, out))
    return out


def recalibrated_cameras(data: Mapping[str, Any], calibrated: Mapping[str, Any]) -> dict[str, Any]:
    """``model_solution.cameras`` of the photos the calibration still has a camera for: a photo
    whose calibrated camera was deleted has no camera (its re-calibration was made from it)."""
    recal = (data.get("model_solution") or {}).get("cameras") or {}
    return {pid: rec for pid, rec in recal.items() if pid in calibrated}
