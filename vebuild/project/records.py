"""How results are written into the project file: plain JSON numbers, one camera record, a view record.

A quantity the data do not determine has an infinite variance; JSON has no infinity, so it is
written as null (FORMAT.md: "null where the quantity is not determined by the data").
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vebuild.calibration.photo import ypr_with_sigma
from vebuild.camera import ImageCamera, Lens, distortion_displacement_px, focal_to_fov, ypr_from_rotation


def json_values(x: Any) -> Any:
    """A number or nested list of numbers as plain JSON; non-finite values become null."""
    a = np.asarray(x, float)
    if a.ndim == 0:
        return float(a) if np.isfinite(a) else None
    finite = np.isfinite(a)
    if finite.all():
        return a.tolist()  # Python floats, as float() gives them: a covariance of a house is millions
    out = a.astype(object)
    out[~finite] = None
    return out.tolist()


def value_sigma(value: Any, sigma: Any) -> dict[str, Any]:
    return {"value": json_values(value), "sigma": json_values(sigma)}


def camera_record(K: np.ndarray, R: np.ndarray, C: np.ndarray, covariance: np.ndarray,
                  distortion: dict[str, Any] | None = None) -> dict[str, Any]:
    """A camera's K, R, focal length, principal point, yaw/pitch/roll and position, each with its 1σ
    from ``covariance`` (9×9 over f, cx, cy, ω, C), and the covariance itself; ``distortion``: its
    lens distortion (:func:`distortion_record`), where the photo's lens has one."""
    sig = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    ypr, ypr_sig = ypr_with_sigma(R, covariance[3:6, 3:6])
    out = {
        "K": json_values(K),
        "R": json_values(R),
        "focal_px": value_sigma(K[0, 0], sig[0]),
        "principal_point": value_sigma(K[:2, 2], sig[1:3]),
        "ypr_deg": value_sigma(np.degrees(ypr), np.degrees(ypr_sig)),
        "position": value_sigma(C, sig[6:9]),
        "covariance": json_values(covariance),
    }
    if distortion is not None:
        out["distortion"] = distortion
    return out


def distortion_record(K: np.ndarray, width: int, height: int, k1: float, k1_sigma: float,
                      source: str, *, k2: float = 0.0, k2_sigma: float = 0.0, k2_source: str | None = None,
                      corner_sigma: float | None = None, k1_correlation: float | None = None) -> dict[str, Any]:
    """A lens distortion as FORMAT.md's ``distortion`` object: the division model's k1 with its 1σ,
    how far it moves the photo's corners (pixels, and the 1σ of that), and where k1 came from; the
    second term ``k2`` {value, sigma, source} beside k1 where it was tested (``k2_source``) or is
    not 0. ``corner_sigma``: the corner displacement's 1σ where the caller has it from the joint
    covariance of f, c, k1 and k2 (else from k1's 1σ alone); ``k1_correlation``: that of k1 and k2
    where both were estimated (written in k2's record, for the single-view measurements' 1σ)."""
    lens = Lens(k1, k2)
    corner = distortion_displacement_px(K, width, height, lens)
    if corner_sigma is None:
        step = max(abs(k1_sigma), 1e-12)
        slope = abs(distortion_displacement_px(K, width, height, Lens(k1 + step, k2)) - corner) / step
        corner_sigma = slope * k1_sigma
    out: dict[str, Any] = {"model": "division", "k1": value_sigma(k1, k1_sigma),
           "corner_displacement_px": value_sigma(corner, corner_sigma), "source": source}
    if k2_source is not None or k2 != 0.0:
        k2_record: dict[str, Any] = {**value_sigma(k2, k2_sigma), "source": k2_source or source}
        if k1_correlation is not None:
            k2_record["k1_correlation"] = float(k1_correlation)
        out["k2"] = k2_record
    return out


def view_record(cam: ImageCamera, name: str, description: str | None = None) -> dict[str, Any]:
    """A view record (FORMAT.md, ``views``) that reproduces ``cam``: its position, look direction,
    roll and horizontal field of view (the principal point is taken as the image centre); read
    back by :func:`vebuild.project.decode.view_camera`."""
    R = np.asarray(cam.R, float)
    roll = float(np.degrees(ypr_from_rotation(R)[2]))
    fov = float(np.degrees(focal_to_fov(cam.K[0, 0], cam.width)))
    out: dict[str, Any] = {"name": name, "position": [float(v) for v in cam.C],
                           "direction": [float(v) for v in R[2]], "roll_deg": roll,
                           "fov_deg": fov, "width": int(cam.width), "height": int(cam.height)}
    if description:
        out["description"] = description
    return out
