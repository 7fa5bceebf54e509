"""Camera positions and marker positions in one metric world frame (paper §2.1).

The start is the paper's construction:

1. the origin marker fixes the world origin; for each photo that sees it, the camera lies on the
   ray from the origin in direction t̂ = −Rᵀ K⁻¹ u₀ (eq. 4 solved up to scale);
2. one such photo is put at unit distance; another photo k sharing ≥ 2 markers with a placed
   photo j gets the unit baseline B̂ⱼₖ as the eigenvector of the smallest eigenvalue of
   Γ = Σ Ĉᵢ Ĉᵢᵀ, Ĉᵢ = M̂ⱼᵢ × M̂ₖᵢ (eqs. 5–7), its sign fixed by cheirality (the markers lie in
   front of both cameras), and Cₖ is where the line from the origin along t̂ₖ meets the line from
   Cⱼ along B̂ⱼₖ (Figure 4);
3. markers seen by two placed photos are triangulated, and photos without the origin marker are
   placed from ≥ 2 markers of known position (resection with K and R known);
4. the reference distances, surveyed markers and photos' own camera heights fix the metric scale.

Then one robust least-squares solve refines every camera position and marker position over all
marker observations, scale distances and camera heights. Each photo's focal length, principal
point and rotation take part too, held by a Gaussian prior equal to their vanishing-point estimate
and covariance, so that the positions' uncertainty includes theirs; where a photo's calibration
estimated its lens distortion k1 (a 7×7 covariance, k1 last), k1 is refined the same way. Every
marker is projected through its photo's distortion (vebuild/camera.py).

Where the placement starts (baselines, resection, triangulation) is :mod:`vebuild.calibration.start`'s.
A photo placed alone, from the floor plane, is :mod:`vebuild.calibration.single_photo`'s.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import Lens, distortion_derivatives_each, intrinsic_matrix, project, skew_batch, so3_left_jacobian
from vebuild.constants import OUTLIER_SIGMAS, ROBUST_SCALE
from vebuild.determinism import deterministic
from vebuild.errors import CalibrationError

from .lm import levenberg_marquardt
from .lsq import (
    covariance_from_jacobian,
    is_numeric_failure,
    offsets_from_the_others,
    propagated_variance,
    variance_factor,
)
from .placement_checks import (
    K1_CORNER_RANGE,
    check_camera_covariances,
    check_finite_inputs,
    check_finite_start,
    contradictions,
    k1_in_range,
)
from .placement_types import (  # noqa: F401  (re-exported: the placement's words)
    TIE_SIGMA_K1,
    TIE_SIGMA_PX,
    CameraGroupPrior,
    MeasuredDistance,
    PhotoInput,
    PlacedCamera,
    Placement,
    ReferenceDistance,
)
from .start import initial_positions

Array = NDArray[np.float64]


@deterministic
def place_cameras(
    photos: Sequence[PhotoInput],
    *,
    origin: str | None = None,
    known_markers: Mapping[str, Array] | None = None,
    distances: Sequence[ReferenceDistance] = (),
    click_sigma_px: float = 1.0,
    camera_heights: Mapping[str, tuple[float, float]] | None = None,
    groups: Sequence[CameraGroupPrior] = (),
) -> Placement:
    """Camera and marker positions in metres, with covariances (paper §2.1, then refined).

    camera_heights : photo id → (height above the floor z = 0, 1σ), metres: what a photo's own
        scale (its camera height, a known length in it) says; each is a residual of the
        refinement and fixes the scale as a reference distance does (the origin marker, at z = 0,
        lies on the floor).
    groups : photos of one camera, placed with one set of intrinsics (CameraGroupPrior).

    Raises CalibrationError when a marker is seen once only, when a photo cannot be placed, or
    when nothing fixes the metric scale.
    """
    known = {k: np.asarray(v, float) for k, v in (known_markers or {}).items()}
    heights = {i: (float(h), float(s)) for i, (h, s) in (camera_heights or {}).items()
               if i in {p.id for p in photos}}
    check_finite_inputs(photos, known, distances)
    for pid, (h, s) in heights.items():
        if not (np.isfinite(h) and h > 0 and np.isfinite(s) and s > 0):
            raise CalibrationError(pid, f"its camera height above the floor: expected a height > 0 m with a σ > 0 m, "
                                   f"got {h!r} ± {s!r}; check its camera_height and known lengths")
    seen: dict[str, list[str]] = {}
    for p in photos:
        for name in p.markers:
            seen.setdefault(name, []).append(p.id)
    for name, ids in sorted(seen.items()):
        if len(ids) < 2 and name not in known:
            raise CalibrationError(
                ids[0],
                f"marker '{name}' is observed in this photo only; a marker needs observations in at "
                "least two photos (or a surveyed position) to be placed: mark it in another photo or "
                "remove it",
            )
    if origin is None:
        origin = max(sorted(seen), key=lambda n: len(seen[n])) if seen else None
    if origin is None:
        raise CalibrationError(
            None, "no marker is observed in any photo, so nothing fixes where the world's origin is: "
            "place a marker on a point seen in the photos (it becomes the origin) and mark it in each photo "
            "that shows it",
        )
    if origin not in seen:
        raise CalibrationError(
            None, f"the origin marker '{origin}' is not observed in any photo; mark it in at least one",
        )
    scale_refs = [d for d in distances if d.role == "scale"]
    if not scale_refs and len([k for k in known if k != origin]) == 0 and not heights:
        raise CalibrationError(
            None,
            "nothing fixes the metric scale: add a reference distance (role 'scale') between two "
            "markers, measured at the scene, a surveyed marker position, or a photo's camera height "
            "or known length",
        )
    for d in distances:
        for n in (d.a, d.b):
            if n not in seen and n not in known:
                raise CalibrationError(
                    None, f"reference distance {d.a}–{d.b}: marker '{n}' is not observed in any photo"
                )

    by_id = {p.id: p for p in photos}
    C, X = initial_positions(photos, origin, known)
    check_finite_start(C, X)
    check_scale_distances(X, scale_refs)
    s = _metric_scale(X, known, scale_refs, origin, C, heights)
    if not (np.isfinite(s) and s > 0):
        raise CalibrationError(None, f"the reference distances give the scene a scale of {s:g}, not a positive "
                               "number: check the distances' values and the markers' clicks")
    C = {k: v * s for k, v in C.items()}
    X = {k: (known[k] if k in known else v * s) for k, v in X.items()}
    placement = _refine_honest(by_id, C, X, origin, known, distances, click_sigma_px, heights, groups)
    # A k1 beyond what real lenses have is a misfit absorbed: solved again with it held (placement_checks).
    wild = [p for p in photos if p.covariance.shape == (7, 7) and not k1_in_range(
        placement.cameras[p.id].k1, p.corner_px, float(placement.cameras[p.id].K[0, 0]))]
    if not wild:
        return placement
    held = {p.id: replace(p, covariance=p.covariance[:6, :6], k1_sigma=float(np.sqrt(p.covariance[6, 6])))
            for p in wild}
    again = _refine_honest({i: held.get(i, p) for i, p in by_id.items()}, C, X, origin, known, distances,
                           click_sigma_px, heights, groups)
    notes = [f"photo '{p.id}': the joint placement moved its lens distortion k1 from {p.k1:+.3g} to "
             f"{placement.cameras[p.id].k1:+.3g}, beyond what real lenses have (a corner displaced by "
             f"{K1_CORNER_RANGE[0]:+.0%}…{K1_CORNER_RANGE[1]:+.0%}): a misfit of its vanishing lines and markers, not "
             "its lens; k1 is held at its calibration's value. Check its vanishing lines and markers" for p in wild]
    return replace(again, warnings=notes + again.warnings)


#: How often a contradicted photo's prior is widened by its variance factor and the solve run again.
PRIOR_REWEIGHTINGS = 4


def _refine_honest(photos: Mapping[str, PhotoInput], C0: Mapping[str, Array], X0: Mapping[str, Array],
                   origin: str, known: Mapping[str, Array], distances: Sequence[ReferenceDistance],
                   click_sigma: float, heights: Mapping[str, tuple[float, float]],
                   groups: Sequence[CameraGroupPrior] = ()) -> Placement:
    """:func:`_refine`, then, while a photo's markers contradict its vanishing-point prior
    (:mod:`.placement_checks`), that prior's covariance widened by the photo's variance factor and
    the solve run again (variance component estimation): a wrong prior held at its stated σ drags
    f, c and k1 with it; widened, the markers place the camera. The first warning per photo is kept."""
    by = dict(photos)
    notes: dict[str, str] = {}
    placement: Placement | None = None
    first: Placement | None = None
    for _ in range(PRIOR_REWEIGHTINGS):
        try:
            placement = _refine(by, C0, X0, origin, known, distances, click_sigma, heights, groups)
            first = placement if first is None else first
        except CalibrationError:
            # Widened, the priors no longer fix every camera (a photo whose markers contradict its
            # lines by a turn of its axes drags the others): the last placement that did stands,
            # its contradiction said, for the caller's tests of turned photos (.orientation).
            if placement is None:
                raise
            break
        for w in placement.warnings:
            notes.setdefault(w.split("'")[1], w)
        if not placement.prior_factors:
            break
        g = placement.prior_factors
        by = {i: replace(p, covariance=p.covariance * g.get(i, 1.0), k1_sigma=p.k1_sigma * np.sqrt(g.get(i, 1.0)))
              for i, p in by.items()}
    assert placement is not None  # PRIOR_REWEIGHTINGS ≥ 1, and the first failure is raised
    return replace(placement, warnings=list(notes.values()), unwidened=first if first is not placement else None)


#: Two scale distances whose implied scales differ by more than this factor contradict each other.
#: The unit-scale start (before the refinement) places markers to within some tens of percent on a
#: poor geometry, so a factor of 3 is no noise; a slip of units (4 m for 400 cm, 40 for 4) is 10× or more.
SCALE_DISAGREEMENT = 3.0


def check_scale_distances(X: Mapping[str, Array], refs: Sequence[ReferenceDistance]) -> None:
    """Before the full solve: the scale each reference distance implies from the unit-scale
    placement ``X`` (its length in metres over its markers' distance there) must agree with the
    others' to within :data:`SCALE_DISAGREEMENT`; otherwise a CalibrationError names the two that
    disagree most and by what factor (the solve would spend a minute and then blame a marker)."""
    implied = []
    for d in refs:
        if d.a not in X or d.b not in X:
            continue
        cur = float(np.linalg.norm(np.asarray(X[d.a]) - np.asarray(X[d.b])))
        if not (np.isfinite(cur) and cur > 0):
            raise CalibrationError(None, f"reference distance {d.a}–{d.b} ({d.distance:g} m): the photos place its "
                                   f"two markers at the same point; check their clicks (a marker clicked twice "
                                   "under two names?)")
        implied.append((d.distance / cur, d, cur))
    if len(implied) < 2:
        return
    lo, hi = min(implied, key=lambda t: t[0]), max(implied, key=lambda t: t[0])
    factor = hi[0] / lo[0]
    if factor > SCALE_DISAGREEMENT:
        (_, a, cur_a), (_, b, cur_b) = hi, lo
        raise CalibrationError(
            None,
            f"the scale distances {a.a}–{a.b} ({a.distance:g} m) and {b.a}–{b.b} ({b.distance:g} m) contradict each "
            f"other by a factor of {factor:.3g}: where the photos place the markers, {a.a}–{a.b} is "
            f"{cur_a / cur_b:.3g}× as long as {b.a}–{b.b}, but the distances say {a.distance / b.distance:.3g}×. "
            "Check both values and their units (m), and that each joins the markers it names")


def _metric_scale(X: Mapping[str, Array], known: Mapping[str, Array], refs: Sequence[ReferenceDistance],
                  origin: str, C: Mapping[str, Array] | None = None,
                  heights: Mapping[str, tuple[float, float]] | None = None) -> float:
    """Least-squares scale factor from the reference distances, surveyed markers and camera heights."""
    num = den = 0.0
    for pid, (h, sigma) in (heights or {}).items():
        if C is not None and pid in C:
            z = float(C[pid][2])
            num += z * h / sigma**2
            den += z * z / sigma**2
    for d in refs:
        if d.a in X and d.b in X:
            length = float(np.linalg.norm(X[d.a] - X[d.b]))
            w = 1.0 / d.sigma**2
            num += w * length * d.distance
            den += w * length * length
    for k, pos in known.items():
        if k in X and k != origin:
            cur = X[k] - X[origin]
            num += float(cur @ pos) / 1e-6
            den += float(cur @ cur) / 1e-6
    if den == 0.0:
        raise CalibrationError(None, "no reference distance joins two markers that could be placed; "
                               "add one between markers seen in two photos or more")
    return num / den


def _unbounded(x: Array) -> Array:
    """The placement's unknowns have no bounds: :func:`.lm.levenberg_marquardt`'s projection."""
    return x


def _refine(photos: Mapping[str, PhotoInput], C0: Mapping[str, Array], X0: Mapping[str, Array], origin: str,
            known: Mapping[str, Array], distances: Sequence[ReferenceDistance], click_sigma: float,
            heights: Mapping[str, tuple[float, float]] | None = None,
            groups: Sequence[CameraGroupPrior] = ()) -> Placement:
    from scipy.spatial.transform import Rotation  # imported at first use: docs/start-up.md

    ids = list(photos)
    heights = {i: h for i, h in (heights or {}).items() if i in photos}
    free_markers = [n for n in sorted(X0) if n != origin and n not in known]
    fixed = {origin: np.zeros(3), **known}
    # Each camera's block: (f, cx, cy, ω, C), then k1 where its calibration estimated it (7×7).
    refine_k1 = np.array([photos[i].covariance.shape == (7, 7) for i in ids])
    n_prior = np.where(refine_k1, 7, 6)
    size = np.where(refine_k1, 10, 9)
    off = np.r_[0, np.cumsum(size)[:-1]].astype(int)
    n_cam = int(size.sum())
    n_par = n_cam + 3 * len(free_markers)
    col = {n: n_cam + 3 * i for i, n in enumerate(free_markers)}
    idx9 = off[:, None] + np.arange(9)[None, :]
    k1_col = {k: int(off[k] + 9) for k in range(len(ids)) if refine_k1[k]}

    # Priors from each photo's vanishing-point calibration: whiten (q − q̂) with Σ^(−1/2); a camera
    # group's one prior, over its first photo's (f, c[, k1]) and every photo's ω, is its first's.
    q0 = {i: np.r_[photos[i].K[0, 0], photos[i].K[:2, 2]] for i in ids}
    grouped: list[tuple[str, ...]] = []
    prior_cols: dict[int, Array] = {}
    prior_cov = {k: photos[i].covariance for k, i in enumerate(ids)}
    for gp in groups:  # each group's photos placed here, its covariance marginal to them
        n_s = gp.covariance.shape[0] - 3 * len(gp.photos)
        here = [j for j, p in enumerate(gp.photos) if p in photos]
        if len(here) < 2:
            continue
        members = tuple(gp.photos[j] for j in here)
        lead, ks = ids.index(members[0]), [ids.index(m) for m in members]
        with_k1 = n_s == 4 and lead in k1_col  # else k1 is held: its row is marginalised out
        sel = [0, 1, 2, *([3] if with_k1 else []), *[n_s + 3 * j + d for j in here for d in range(3)]]
        grouped.append(members)
        prior_cov[lead] = np.asarray(gp.covariance, float)[np.ix_(sel, sel)]
        prior_cols[lead] = np.r_[off[lead] + np.arange(3), [k1_col[lead]] if with_k1 else [],
                                 *[off[k] + 3 + np.arange(3) for k in ks]].astype(int)
        n_prior[ks] = 0
        n_prior[lead] = len(prior_cols[lead])
    for k in range(len(ids)):
        if k not in prior_cols and n_prior[k]:
            prior_cols[k] = np.r_[off[k] + np.arange(6), [k1_col[k]] if k in k1_col else []].astype(int)
    L_inv = {}
    for k, i in enumerate(ids):
        if n_prior[k]:
            w, V = np.linalg.eigh(0.5 * (prior_cov[k] + prior_cov[k].T))
            L_inv[i] = (V / np.sqrt(np.maximum(w, 1e-18))).T
    # The tie of each group's photos to its first: (f, cx, cy[, k1]) equal.
    ties = [(ids.index(m[0]), ids.index(o)) for m in grouped for o in m[1:]]
    tie_k1 = [(a, b) for a, b in ties if a in k1_col and b in k1_col]
    obs = [(i, n, np.asarray(uv, float)) for i in ids for n, uv in sorted(photos[i].markers.items()) if n in X0]
    scale_refs = [d for d in distances if d.role == "scale" and d.a in X0 and d.b in X0]
    height_ids = [k for k, i in enumerate(ids) if i in heights]

    all_markers = sorted(X0)
    m_index = {n: j for j, n in enumerate(all_markers)}
    obs_cam = np.array([ids.index(i) for i, _, _ in obs], dtype=int)
    obs_mark = np.array([m_index[n] for _, n, _ in obs], dtype=int)
    obs_uv = np.array([uv for _, _, uv in obs]).reshape(-1, 2)
    ref_ab = np.array([[m_index[d.a], m_index[d.b]] for d in scale_refs], dtype=int).reshape(-1, 2)
    ref_d = np.array([d.distance for d in scale_refs])
    ref_s = np.array([d.sigma for d in scale_refs])
    h_val = np.array([heights[ids[k]][0] for k in height_ids])
    h_sig = np.array([heights[ids[k]][1] for k in height_ids])
    R0 = np.array([photos[i].R for i in ids])
    k1_0 = np.array([photos[i].k1 for i in ids], float)
    k2_0 = np.array([photos[i].k2 for i in ids], float)  # held: placement refines k1 only
    q0_stack = np.array([q0[i] for i in ids])
    free_rows = np.array([m_index[n] for n in free_markers], dtype=int)
    X_fixed = np.zeros((len(all_markers), 3))
    for n, pos in fixed.items():
        if n in m_index:
            X_fixed[m_index[n]] = pos
    n_obs, n_ref, n_h = len(obs), len(scale_refs), len(height_ids)
    r_prior = 2 * n_obs
    prior_rows = r_prior + np.r_[0, np.cumsum(n_prior)[:-1]].astype(int)
    r_ref = r_prior + int(n_prior.sum())
    r_h = r_ref + n_ref
    r_tie = r_h + n_h
    n_res = r_tie + 3 * len(ties) + len(tie_k1)

    def unpack(x: Array) -> tuple[Array, Array, Array, Array, Array]:
        """Per-camera (f, cx, cy), rotations, centres, k1; all marker positions."""
        cam = x[idx9]
        fc = q0_stack + cam[:, 0:3]
        R = np.einsum("kij,kjl->kil", Rotation.from_rotvec(cam[:, 3:6]).as_matrix(), R0)
        k1 = k1_0.copy()
        for k, c in k1_col.items():
            k1[k] += x[c]
        X = X_fixed.copy()
        X[free_rows] = x[n_cam:].reshape(-1, 3)
        return fc, R, cam[:, 6:9], k1, X

    def prior_delta(x: Array, k: int) -> Array:
        return x[prior_cols[k]]

    def tie_res(fc: Array, k1: Array) -> Array:
        if not ties:
            return np.zeros(0)
        a, b = np.array(ties).T
        out = [((fc[b] - fc[a]) / TIE_SIGMA_PX).ravel()]
        if tie_k1:
            ka, kb = np.array(tie_k1).T
            out.append((k1[kb] - k1[ka]) / TIE_SIGMA_K1)
        return np.concatenate(out)

    def residuals(x: Array) -> Array:
        fc, R, C, k1, X = unpack(x)
        xc = np.einsum("nij,nj->ni", R[obs_cam], X[obs_mark] - C[obs_cam])
        xn = xc[:, :2] / xc[:, 2:3]
        s = (distortion_derivatives_each(np.sum(xn**2, axis=1), np.stack([k1, k2_0], 1)[obs_cam])[0]
             if np.any(k1 != 0.0) or np.any(k2_0 != 0.0) else 1.0)
        uv = fc[obs_cam, 0:1] * xn * np.reshape(s, (-1, 1)) + fc[obs_cam, 1:3]
        reproj = ((uv - obs_uv) / click_sigma).ravel()
        prior = np.concatenate([L_inv[i] @ prior_delta(x, k) for k, i in enumerate(ids) if n_prior[k]] or [np.zeros(0)])
        dist = (np.linalg.norm(X[ref_ab[:, 0]] - X[ref_ab[:, 1]], axis=1) - ref_d) / ref_s
        hres = (C[height_ids, 2] - h_val) / h_sig if n_h else np.zeros(0)
        return np.concatenate([reproj, prior, dist, hres, tie_res(fc, k1)])

    rows_obs = np.arange(2 * n_obs).reshape(-1, 2)
    free_of_mark = np.full(len(all_markers), -1, dtype=int)
    for n in free_markers:
        free_of_mark[m_index[n]] = col[n]
    k1_of_cam = np.full(len(ids), -1, dtype=int)
    for k, c in k1_col.items():
        k1_of_cam[k] = c
    # The priors' entries, the same at every x: each photo's whitening over its (f, cx, cy, ω)
    # columns, and over its k1 column where k1 is refined.
    p_rows, p_cols, p_vals = [], [], []
    for k, i in enumerate(ids):
        n_k = int(n_prior[k])
        if not n_k:
            continue
        cols = prior_cols[k]
        p_rows.append(np.repeat(prior_rows[k] + np.arange(n_k), n_k))
        p_cols.append(np.tile(cols, n_k))
        p_vals.append(L_inv[i][:n_k, :n_k].ravel())

    def jacobian(x: Array) -> Any:
        """Analytic Jacobian of residuals, as a sparse matrix: an observation's two rows touch its
        camera's block and its marker only; dense where the unknowns are few (:mod:`.lm`)."""
        from scipy import sparse

        fc, R, C, k1, X = unpack(x)
        cam = x[idx9]
        d = X[obs_mark] - C[obs_cam]
        Ro = R[obs_cam]
        xc = np.einsum("nij,nj->ni", Ro, d)
        z = xc[:, 2]
        f = fc[obs_cam, 0]
        xn = xc[:, :2] / z[:, None]
        r2 = np.sum(xn**2, axis=1)
        s, ds_dr2, ds_dk, _ = distortion_derivatives_each(r2, np.stack([k1, k2_0], 1)[obs_cam])
        # u = f s(|xn|²) xn + c, xn = (x/z, y/z): ∂u/∂xn = f (s I + 2 s' xn xnᵀ), then ∂xn/∂x_cam.
        B = np.zeros((n_obs, 2, 3))
        B[:, 0, 0] = B[:, 1, 1] = 1.0 / z
        B[:, 0, 2] = -xc[:, 0] / z**2
        B[:, 1, 2] = -xc[:, 1] / z**2
        D = s[:, None, None] * np.eye(2)[None] + 2.0 * ds_dr2[:, None, None] * np.einsum("ni,nj->nij", xn, xn)
        A = f[:, None, None] * np.einsum("nij,njk->nik", D, B) / click_sigma
        Jl = np.array([so3_left_jacobian(w_) for w_ in cam[:, 3:6]])
        dxc_dw = -np.einsum("nij,njk->nik", skew_batch(xc), Jl[obs_cam])
        AR = np.einsum("nij,njk->nik", A, Ro)
        o = off[obs_cam]
        r3 = np.repeat(rows_obs, 3, axis=1)  # (n_obs, 6): each of the two rows for three columns
        rows = [rows_obs.ravel(), rows_obs[:, 0], rows_obs[:, 1], r3.ravel(), r3.ravel()]
        three = np.arange(3)[None, None, :]
        cols = [np.repeat(o, 2), o + 1, o + 2, (o[:, None, None] + 3 + three).repeat(2, 1).ravel(),
                (o[:, None, None] + 6 + three).repeat(2, 1).ravel()]
        vals = [(xn * s[:, None] / click_sigma).ravel(), np.full(n_obs, 1.0 / click_sigma),
                np.full(n_obs, 1.0 / click_sigma), np.einsum("nij,njk->nik", A, dxc_dw).ravel(), (-AR).ravel()]
        kc = k1_of_cam[obs_cam]
        with_k1 = kc >= 0
        if np.any(with_k1):
            rows.append(rows_obs[with_k1].ravel())
            cols.append(np.repeat(kc[with_k1], 2))
            vals.append((fc[obs_cam, 0][:, None] * xn * ds_dk[:, None] / click_sigma)[with_k1].ravel())
        mc = free_of_mark[obs_mark]
        free = mc >= 0
        rows.append(r3[free].ravel())
        cols.append((mc[free][:, None, None] + three).repeat(2, 1).ravel())
        vals.append(AR[free].ravel())
        rows += p_rows
        cols += p_cols
        vals += p_vals
        for j, (ia, ib) in enumerate(ref_ab):
            diff = X[ia] - X[ib]
            u = diff / max(np.linalg.norm(diff), 1e-12) / ref_s[j]
            for m, sign in ((ia, 1.0), (ib, -1.0)):
                if free_of_mark[m] >= 0:
                    rows.append(np.full(3, r_ref + j))
                    cols.append(free_of_mark[m] + np.arange(3))
                    vals.append(sign * u)
        if n_h:
            rows.append(r_h + np.arange(n_h))
            cols.append(off[height_ids] + 8)
            vals.append(1.0 / h_sig)
        for t, (a, b) in enumerate(ties):  # fc[b] − fc[a], three rows each
            for d in range(3):
                rows.append(np.full(2, r_tie + 3 * t + d))
                cols.append(np.array([off[b] + d, off[a] + d]))
                vals.append(np.array([1.0, -1.0]) / TIE_SIGMA_PX)
        for t, (a, b) in enumerate(tie_k1):
            rows.append(np.full(2, r_tie + 3 * len(ties) + t))
            cols.append(np.array([k1_col[b], k1_col[a]]))
            vals.append(np.array([1.0, -1.0]) / TIE_SIGMA_K1)
        return sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                                 shape=(n_res, n_par))

    x0 = np.zeros(n_par)
    for k, i in enumerate(ids):
        x0[off[k] + 6 : off[k] + 9] = C0[i]
    for n in free_markers:
        x0[col[n] : col[n] + 3] = X0[n]

    def culprit(r: Array) -> str:
        """Who the first non-finite residual belongs to: a photo's marker, a photo, a distance."""
        k = int(np.flatnonzero(~np.isfinite(r))[0])
        if k < r_prior:
            pid, name, _ = obs[k // 2]
            return f"photo '{pid}', marker '{name}'"
        if k < r_ref:
            return f"photo '{ids[int(np.searchsorted(prior_rows, k, side='right')) - 1]}' (its vanishing-point prior)"
        if k < r_h:
            d = scale_refs[k - r_ref]
            return f"reference distance {d.a}–{d.b} ({d.distance:g} m)"
        if k < r_tie:
            return f"photo '{ids[height_ids[k - r_h]]}' (its camera height)"
        return "a camera group (its photos' one set of intrinsics)"

    with np.errstate(all="ignore"):
        r0 = residuals(x0)
    if not np.all(np.isfinite(r0)):
        raise CalibrationError(None, f"{culprit(r0)}: its residual at the start of the refinement is not a finite "
                               "number (a marker in the camera's plane, or a camera on a marker); check that marker's "
                               "clicks and the photo's vanishing lines")
    try:
        # Soft-L1 on the markers' rows only: the priors, distances and heights are Gaussian, as the
        # covariance below takes them (a prior down-weighted in the solve but not in the covariance
        # let k1, f and c run far from it with a σ as if it had held).
        x = levenberg_marquardt(residuals, jacobian, x0, _unbounded, robust_rows=r_prior,
                                robust_scale=ROBUST_SCALE, tol=1e-10).x
        with np.errstate(all="ignore"):  # a non-finite residual is reported below, not warned about
            res = residuals(x)
        if not np.all(np.isfinite(res)):
            raise CalibrationError(None, f"{culprit(res)}: the refinement of cameras and markers went to a "
                                   "non-finite value there; check that marker's clicks in that photo")
        s2 = variance_factor(res, n_par)
        J = jacobian(x)
        cov_unscaled = covariance_from_jacobian(J)
        cov = cov_unscaled * s2
    except (ValueError, np.linalg.LinAlgError) as e:
        if not is_numeric_failure(e):
            raise
        raise CalibrationError(None, f"the refinement of camera and marker positions failed numerically ({e}); "
                               "a photo's vanishing lines or marker clicks make it degenerate: check the photos "
                               "with the fewest markers first") from None

    cam_cols = [np.r_[idx9[k], [k1_col[k]] if k in k1_col else []].astype(int) for k in range(len(ids))]
    check_camera_covariances(ids, cov, cam_cols, [int(np.sum(obs_cam == k)) for k in range(len(ids))])
    # Each photo's share of χ² and of the redundancy (its markers' rows, its prior's): contradictions.
    mark_rows = [rows_obs[obs_cam == k].ravel() for k in range(len(ids))]
    notes, widen, prior_factor = contradictions(ids, res, J, cov_unscaled, s2, mark_rows,
                                  [prior_rows[k] + np.arange(n_prior[k]) for k in range(len(ids))], click_sigma)
    fc, R, C, k1, Xa = unpack(x)
    X = {n: Xa[m_index[n]] for n in all_markers}
    # A click is an outlier where it lies from where the other observations put it (its deleted
    # residual) by more than OUTLIER_SIGMAS of the stated click noise, with the placement's own
    # uncertainty there: rᵀ (I − H)⁻¹ r > OUTLIER_SIGMAS², χ²(2) tail e⁻⁸ for an honest click.
    r_obs = np.array([project(intrinsic_matrix(*fc[ids.index(j)]), R[ids.index(j)], C[ids.index(j)], X[n],
                              Lens(float(k1[ids.index(j)]), float(k2_0[ids.index(j)]))) - uv
                      for j, n, uv in obs]).reshape(-1, 2)
    offsets, stat = offsets_from_the_others(J[: 2 * n_obs], cov_unscaled, r_obs / click_sigma)
    cameras = {}
    for k, i in enumerate(ids):
        K = intrinsic_matrix(*fc[k])
        resid = {n: r_obs[o] for o, (j, n, _) in enumerate(obs) if j == i}
        outl = [n for o, (j, n, _) in enumerate(obs) if j == i and stat[o] > OUTLIER_SIGMAS**2]
        away = {n: float(np.linalg.norm(offsets[o]) * click_sigma) for o, (j, n, _) in enumerate(obs)
                if j == i and n in outl}
        sl = idx9[k]
        k1_sigma = (float(np.sqrt(max(cov[k1_col[k], k1_col[k]] * widen[k], 0.0))) if k in k1_col
                    else photos[i].k1_sigma)
        cameras[i] = PlacedCamera(i, K, R[k].copy(), C[k].copy(), cov[np.ix_(sl, sl)] * widen[k], resid, outl,
                                  float(k1[k]), k1_sigma, float(k2_0[k]), away)
    markers = {}
    for n in sorted(X):
        c3 = cov[col[n] : col[n] + 3, col[n] : col[n] + 3].copy() if n in col else np.zeros((3, 3))
        markers[n] = (np.asarray(X[n], float).copy(), c3)
    measured = []
    for d in distances:
        if d.a not in X or d.b not in X:
            continue
        diff = X[d.a] - X[d.b]
        dist = float(np.linalg.norm(diff))
        g = np.zeros(n_par)
        u = diff / max(dist, 1e-12)
        if d.a in col:
            g[col[d.a] : col[d.a] + 3] += u
        if d.b in col:
            g[col[d.b] : col[d.b] + 3] -= u
        measured.append(MeasuredDistance(d, dist, float(np.sqrt(propagated_variance(g, cov)))))
    return Placement(cameras, markers, measured, origin, s2, dict(heights), notes,
                     {i: float(np.sqrt(widen[k])) for k, i in enumerate(ids) if widen[k] > 1.0},
                     {i: float(prior_factor[k]) for k, i in enumerate(ids) if prior_factor[k] > 1.0})
