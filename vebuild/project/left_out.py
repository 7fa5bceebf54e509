"""The vanishing segments a photo's calibration left out as not meeting at their axis' vanishing
point, read from its record (FORMAT.md ``rejected``, per axis): indices into the photo's segments
as they were calibrated, so nothing is read as left out once an axis' segments have changed in
number since (the indices would name other segments)."""

from __future__ import annotations

from typing import Any


def rejected_by_calibration(record: Any, n_segments: int) -> dict[int, str]:
    """Segment index → why the calibration left it out, in plain words, from the photo's
    vanishing-point record of one axis (FORMAT.md ``rejected``); nothing where the axis' segments
    have changed in number since."""
    if not isinstance(record, dict) or not isinstance(record.get("rejected"), list):
        return {}
    if len(record.get("residuals_px") or []) != n_segments:
        return {}
    out = {}
    for r in record["rejected"]:
        if isinstance(r, dict) and isinstance(r.get("segment"), int) and 0 <= r["segment"] < n_segments:
            m = r.get("misfit_sigmas")
            if r.get("reason") == "axis left out" or not isinstance(m, (int, float)):
                out[r["segment"]] = "its axis was left out: most of its segments do not meet at one point"
            else:
                out[r["segment"]] = f"{m:.1f}σ off the vanishing point of the other lines"
    return out
