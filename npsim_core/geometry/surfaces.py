"""Render geometry from stereo: robust per-segment surface fits (docs/relight.md "Nights of real frames").

Semi-global matching errs in structured ways (docs/relight.md, "Nights of real frames"): streaks along rows, object edges
fattened toward the background, speckle islands, 1/16 px steps, wrong depth on weakly textured
and glossy surfaces. Meshed as they are, they become streaked, melted surfaces in the night
(the lamps' light lands on every facet differently). The labels say where a surface is simple,
so :func:`fit_surfaces` replaces the stereo there by a robust fit:

1. **Speckle islands** -- connected regions of at most ``speckle_area`` pixels (at 2048 px wide)
   whose disparity differs by more than ``speckle_px`` from their surroundings are dropped
   (OpenCV ``filterSpeckles``, what SGM pipelines run after matching).
2. **Edge fattening** -- stereo within ``edge_px`` (at 2048 px wide) of a segment border is
   not used; the fit extends the segment's own surface there.
3. **Robust local plane fits in inverse depth**, per segment (a connected component of one
   instance, or of one label for classes without instances). A 3-D plane is exactly linear in
   inverse depth over the image, ``1/z = a + b u + c v``, so a weighted local linear regression
   (normalised convolution of order 1, Gaussian window σ) is exact on planes whatever σ and
   smooth on curved surfaces. Weights are iteratively reweighted (Cauchy, scale from the
   segment's median absolute residual), so streaks and edge-fattened pixels do not pull the
   fit. σ by class: large for façades, walls, fences and ground (``plane_sigma``: they are
   planes or smooth height fields), per instance for vehicles (``vehicle_sigma``), moderate for
   vegetation (``vegetation_sigma``), small for people, bicycles and motorcycles
   (``detail_sigma``); thin objects (poles, signs, traffic lights) get one robust depth per
   component (a flat card at their depth: stereo on them is mostly holes and edge fattening;
   the median of all their stereo, not trimmed at their edges since they are all edge, and
   beyond the stereo's range when they have none within it).
   Bicycles are not cards: a card facing the ego low beams lit the wheels white (busy street,
   512x256: bicycle structure ratio 2.05, 6 % of its pixels at white; with the small window
   0.75 and none, exact depth 1.26).
4. **Normals** come from the fitted planes analytically (``n ∝ −(b fx, c fy, a + b cx + c cy)``),
   so the refinement is not guided by stereo noise.
5. **Kerbs**: a sidewalk above a road border gets the vertical face through the border
   (:func:`_kerbs`); its plane alone had no kerb, and the night lacked the lamps' line along it.
6. **Vehicles upright**: inverse depth per column, slope ridge-regressed toward facing the
   camera (:func:`_upright_columns`); local planes laid cars back or turned them sideways, and
   their lamps' spots then lit the sky or grazed a façade in row streaks.
7. **Wide edge fattening**: stereo near a nearer segment (along the row, ``fattening_px``) is
   dropped and the segment refitted (:func:`_fattened`).
8. **Crowns locally upright**: vegetation's local fit has no slope along the rows and a window
   twice as tall as wide (``vegetation_upright``): local planes on SGM's foliage turned every
   patch of a crown a different way (median normal error 38-41° at 512-1024 px wide, from the
   depth), and the lamps drew that in the night; a crown is a vertical, smooth blob at the
   scale of the window. Depth AbsRel against the exact depth does not get worse.
9. **Vehicles as boxes** (``vehicle_box``): a near vehicle's column profile becomes the two faces
   of an upright box (:func:`_two_faces`): the column line rounded the corner between side and
   rear over its window (glossy paint mirrored a lamp there as a vertical line) and followed a
   nearer car's disparity band wider than the fattening window (a rear turned ~85° toward the
   street, and the light on its glass lit the wrong surfaces); the band is an outlier to a box.

Where a façade or ground segment has too little stereo support in the window, the local fit
hands over (blended in the coefficients) to the segment's robust plane, so the surface goes on
over the left border SGM cannot match and over occlusion holes; in other segments the caller's
hole filling (the scaled pop-up prior) is kept there. On the ground the plane also goes on over
the pixels whose stereo was dropped (``fit_over_dropped``): that stereo was a pole's or a car's.
The fits run on a grid about σ/6 coarser than the image (at most 512 px wide; the coefficients are
smooth) and are evaluated at full resolution.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from ..camera import Intrinsics

__all__ = ["SurfaceParams", "fit_surfaces", "PLANE_CLASSES", "VEHICLE_CLASSES", "THIN_CLASSES", "DETAIL_CLASSES",
           "VEGETATION_CLASSES"]

#: Façades, walls, fences, ground: planes or smooth height fields.
PLANE_CLASSES = (6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 22, 4, 5)
#: The ground among them (ground, road, sidewalk, parking, rail track): one surface per segment.
GROUND_CLASSES = (6, 7, 8, 9, 10)
#: Vehicles: smooth per instance.
VEHICLE_CLASSES = (26, 27, 28, 29, 30, 31)
#: Thin objects: one depth per component.
THIN_CLASSES = (17, 18, 19, 20)
#: Irregular surfaces: a small window (people) or a moderate one (tree crowns, hedges).
DETAIL_CLASSES = (24, 25)
VEGETATION_CLASSES = (21,)
#: Never fitted: unlabeled, ego vehicle, borders, sky.
_SKIP = (0, 1, 2, 3, 23)
_WORK_WIDTH = 512
_NOMINAL_BASELINE = 0.209313  # Cityscapes; only scales the speckle threshold to pixels of disparity


@dataclass(frozen=True)
class SurfaceParams:
    """Parameters of :func:`fit_surfaces`; sizes in pixels at 2048 px wide (scaled to the image).

    plane_sigma, vehicle_sigma, vegetation_sigma, detail_sigma : Gaussian window σ of the local
        plane fits (façades and ground, vehicles, vegetation, people and other classes).
    speckle_area, speckle_px : speckle islands (area, disparity difference in px) dropped; both
        at 2048 px wide (disparity scales with the width, area with its square).
    edge_px : stereo this close to a segment border is not used (edge fattening).
    iterations : reweighting iterations of the robust fit.
    min_support : below this window weight the hole filling is kept (classes other than planes).
    handover : on façades and the ground, below this window weight the local fit hands over to the
        segment's robust plane (blended), which extends them over stereo holes where the hole
        filling's depth agrees within ``handover_agreement`` (relative), or, on the ground
        (``fit_over_dropped``), where the pixel had stereo that was dropped (speckle, fattened edges):
        the filling there is that stereo.
    fattening_px, fattening_margin : stereo within ``fattening_px`` along its row of a segment nearer
        by more than ``fattening_margin`` (relative, by a first fit) is dropped and the segment
        refitted (edge fattening toward the background; 0 = off).
    vehicle_upright, vehicle_column_sigma : vehicles are fitted as upright surfaces, inverse depth per
        column (robust median over rows, then a robust local line along the columns with this σ);
        off = local planes with ``vehicle_sigma``.
    vehicle_noise_px : disparity noise (px) assumed when believing a vehicle's slope along the
        columns (a ridge toward facing the camera; 0 = none).
    kerb_max_m : sidewalks above a road border get a vertical kerb face up to this height (m) where
        their fitted plane lies above the road's (0 = off; docs/relight.md).
    vegetation_upright, vegetation_v_factor : tree crowns and hedges are fitted locally upright (inverse
        depth a function of the column within the window, no slope along the rows) in a window
        ``vegetation_v_factor`` times taller than wide; off = local planes with ``vegetation_sigma``.
    vehicle_matched_px : a vehicle's stereo within this many pixels along its row of a nearer segment
        and equal to that segment's depth (within 5 %) is dropped before the refit (0 = off, the
        default; 64 measured in docs/geometry.md: better cars, but the proposals then change; with
        ``vehicle_box`` the band is an outlier to the box anyway).
    vehicle_box, vehicle_box_tolerance, vehicle_box_disparity, vehicle_box_min_face : vehicles whose
        median disparity is at least ``vehicle_box_disparity`` px become the two visible faces of an
        upright box (perpendicular vertical planes, a sharp corner; :func:`_two_faces`) when the
        box's truncated residual is within ``vehicle_box_tolerance`` times the column line's
        (+ 0.002) and each face is seen over at least ``vehicle_box_min_face`` columns; off = the
        column line alone (docs/geometry.md, "Vehicles as boxes").
    """

    plane_sigma: float = 96.0
    vehicle_sigma: float = 64.0
    vegetation_sigma: float = 16.0
    detail_sigma: float = 8.0
    speckle_area: int = 400
    speckle_px: float = 1.0
    edge_px: float = 4.0
    iterations: int = 3
    min_support: float = 0.02
    handover: float = 0.1
    handover_agreement: float = 0.15
    fit_over_dropped: bool = True
    kerb_max_m: float = 0.3
    fattening_px: float = 24.0
    vehicle_upright: bool = True
    vehicle_column_sigma: float = 32.0
    vehicle_noise_px: float = 0.5
    fattening_margin: float = 0.05
    vegetation_upright: bool = True
    vegetation_v_factor: float = 2.0
    vehicle_matched_px: float = 0.0
    vehicle_box: bool = True
    vehicle_box_tolerance: float = 1.5
    vehicle_box_disparity: float = 20.0
    vehicle_box_min_face: float = 64.0


def _speckle_mask(depth: np.ndarray, valid: np.ndarray, fx: float, W: int, p: SurfaceParams) -> np.ndarray:
    """Valid pixels that belong to small disparity islands (True = speckle)."""
    disp = np.where(valid, _NOMINAL_BASELINE * fx / np.where(valid, depth, 1.0), 0.0)
    d16 = np.clip(np.rint(disp * 16.0), 0, 32767).astype(np.int16)
    kept = d16.copy()
    area = max(4, int(round(p.speckle_area * (W / 2048.0) ** 2)))
    cv2.filterSpeckles(kept, 0, area, max(1, int(round(p.speckle_px * 16 * W / 2048.0))))
    return valid & (kept == 0) & (d16 > 0)


def _segments(labels: np.ndarray, instances: np.ndarray | None) -> tuple[np.ndarray, int]:
    """Connected components of the instance (or label) map; 0 = no segment."""
    key = labels.astype(np.int32) if instances is None else np.where(instances >= 1000, instances,
                                                                     labels.astype(np.int32))
    key = np.where(np.isin(labels, _SKIP), -1, key)
    seg = np.zeros(labels.shape, np.int32)
    n = 0
    for k in np.unique(key):
        if k < 0:
            continue
        cnt, comp = cv2.connectedComponents((key == k).astype(np.uint8), connectivity=4)
        if cnt > 1:
            m = comp > 0
            seg[m] = comp[m] + n
            n += cnt - 1
    return seg, n


def _local_planes(q: np.ndarray, w0: np.ndarray, uu: np.ndarray, vv: np.ndarray, sigma: float,
                  iterations: int, ridge: float, sigma_v: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Robust weighted local plane fit of ``q`` over (uu, vv): coefficients (h, w, 3) and support.

    ``uu``/``vv`` are coordinates scaled to about unit range over the crop; the plane is
    ``q = c0 + c1 uu + c2 vv``. ``ridge`` pulls the slopes to 0 where the window is degenerate.
    ``sigma_v``: the window's σ along the rows (default ``sigma``).
    """
    w = w0.copy()
    sv_ = sigma if sigma_v is None else sigma_v
    k, kv = int(2 * round(3 * sigma) + 1), int(2 * round(3 * sv_) + 1)

    def blur(a):
        return cv2.GaussianBlur(a, (k, kv), sigma, sigmaY=sv_, borderType=cv2.BORDER_CONSTANT)

    coef = np.zeros(q.shape + (3,), np.float64)
    support = blur(w0.astype(np.float32)).astype(np.float64)
    for it in range(max(1, iterations)):
        f = [w, w * uu, w * vv, w * uu * uu, w * uu * vv, w * vv * vv, w * q, w * uu * q, w * vv * q]
        s0, su, sv, suu, suv, svv, sq, suq, svq = (blur(x.astype(np.float32)).astype(np.float64) for x in f)
        A = np.stack([np.stack([s0, su, sv], -1), np.stack([su, suu + ridge * s0, suv], -1),
                      np.stack([sv, suv, svv + ridge * s0], -1)], -2)
        A += np.eye(3) * 1e-9
        rhs = np.stack([sq, suq, svq], -1)[..., None]
        ok = s0 > 1e-6
        coef[:] = 0
        coef[ok] = np.linalg.solve(A[ok], rhs[ok])[..., 0]
        if it == iterations - 1:
            break
        pred = coef[..., 0] + coef[..., 1] * uu + coef[..., 2] * vv
        r = np.where(w0 > 0, (q - pred) / np.maximum(np.abs(pred), 1e-9), 0.0)
        sel = w0 > 0
        scale = max(1.4826 * float(np.median(np.abs(r[sel]))) if sel.any() else 0.0, 0.005)
        w = w0 / (1.0 + (r / (2.385 * scale)) ** 2)
    return coef, support


def _segment_plane(q: np.ndarray, m: np.ndarray, x0: int, y0: int, iterations: int = 4) -> np.ndarray | None:
    """Robust (Cauchy IRLS) plane ``q = a + b u + c v`` over the pixels ``m`` of a crop whose
    top-left pixel is (x0, y0); (a, b, c) in full-image pixel coordinates, None when < 12 pixels."""
    vv, uu = np.nonzero(m)
    if vv.size < 12:
        return None
    if vv.size > 20000:  # a fixed subsample: the plane has three unknowns
        k = np.linspace(0, vv.size - 1, 20000).astype(np.int64)
        vv, uu = vv[k], uu[k]
    y = q[vv, uu].astype(np.float64)
    A = np.stack([np.ones_like(y), (uu + x0).astype(np.float64), (vv + y0).astype(np.float64)], -1)
    cu, cv = A[:, 1].mean(), A[:, 2].mean()
    A[:, 1] -= cu
    A[:, 2] -= cv
    w = np.ones_like(y)
    coef = np.zeros(3)
    for _ in range(iterations):
        sw = np.sqrt(w)
        coef = np.linalg.lstsq(A * sw[:, None], y * sw, rcond=None)[0]
        r = (y - A @ coef) / np.maximum(np.abs(y), 1e-9)
        scale = max(1.4826 * float(np.median(np.abs(r))), 0.005)
        w = 1.0 / (1.0 + (r / (2.385 * scale)) ** 2)
    return np.array([coef[0] - coef[1] * cu - coef[2] * cv, coef[1], coef[2]])


def _fattened(seg: np.ndarray, q: np.ndarray, radius: int, margin: float) -> np.ndarray:
    """Pixels within ``radius`` along their row of another segment whose inverse depth ``q`` at
    the border is larger (nearer) by more than ``margin`` (relative) than their own segment's
    ``radius`` pixels inside the border (the first fit follows the fattened stereo up to the
    border, so it is read beyond it)."""
    H, W = seg.shape
    cols = np.arange(W)[None, :]
    qn = np.nan_to_num(q, nan=0.0)

    def run_start(s):
        start = np.ones((H, W), bool)
        start[:, 1:] = s[:, 1:] != s[:, :-1]
        return np.maximum.accumulate(np.where(start, cols, 0), axis=1)

    out = np.zeros((H, W), bool)
    for flip in (False, True):
        s = seg[:, ::-1] if flip else seg
        qq = qn[:, ::-1] if flip else qn
        st = run_start(s)
        end = (W - 1 - run_start(s[:, ::-1]))[:, ::-1]                  # last pixel of each run
        j = st - 1                                                      # the pixel before the run
        jj = np.clip(j, 0, W - 1)
        qf = np.take_along_axis(qq, jj, 1)
        sf = np.take_along_axis(s, jj, 1)
        qref = np.take_along_axis(qq, np.minimum(st + radius, end), 1)
        m = (j >= 0) & (sf > 0) & (cols - j <= radius) & (qref > 0) & (qf > qref * (1.0 + margin))
        out |= m[:, ::-1] if flip else m
    return out


def _upright_columns(q: np.ndarray, w0: np.ndarray, sigma: float, iterations: int, noise_px: float,
                     box: tuple[float, float, float, float, float, float] | None = None,
                     had: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray] | None:
    """A vehicle as an upright surface: inverse depth per column of its bounding box, (q, dq/du).

    Per column the median of its stereo (``w0``) over rows, then a robust (Cauchy) local linear fit
    along the columns (Gaussian σ in px, weighted by each column's count): corners between a car's
    rear and side stay, a lean does not (glass and paint matched to the background above a car
    made fitted bodies face up, and a lamp on one threw its light at the sky or along a facade).
    The slope along the columns is a ridge regression toward facing the camera: with disparity
    noise ``noise_px`` a far car's slope is noise (at 57 m, 0.1 px of disparity turns its face
    by 45°), so it is believed only as far as the stereo resolves it (prior: tan of the angle to
    the camera ~ N(0, 1), i.e. slope σ_b = q/fx; ridge (σ_n/σ_b)² = (noise_px / (baseline q))²).
    ``box`` = (first column of the crop in the image, fx, cx, minimum disparity px, minimum face
    px, tolerance), None = off: where the car's median disparity reaches the minimum, the profile
    becomes the two faces of an upright box (:func:`_two_faces`, :func:`_box_within`) if their
    truncated residual is within ``tolerance`` times the local line's (+ 0.002); ``had`` (the
    vehicle's pixels with any stereo before the drops) tells the columns whose stereo was dropped
    from those that never had any. None when fewer than 3 columns have stereo.
    """
    n = w0.sum(0).astype(np.float64)
    if (n >= 3).sum() < 3:
        return None
    med = np.nanmedian(np.where(w0, q, np.nan)[:, n >= 3], axis=0)
    wc = np.zeros(q.shape[1])
    wc[n >= 3] = n[n >= 3]
    qv = np.zeros(q.shape[1])
    qv[n >= 3] = med
    u = np.arange(q.shape[1], dtype=np.float64)
    k = int(2 * round(3 * sigma) + 1)

    def blur(a):
        return cv2.GaussianBlur(a[None, :], (k, 1), max(sigma, 0.5), borderType=cv2.BORDER_CONSTANT)[0]

    w = wc.copy()
    a = np.zeros_like(u)
    b = np.zeros_like(u)
    ridge = (noise_px / (_NOMINAL_BASELINE * float(np.median(med)))) ** 2 if np.median(med) > 0 else 0.0
    for it in range(max(1, iterations)):
        s0, su, suu, sq, suq = (blur(x) for x in (w, w * u, w * u * u, w * qv, w * u * qv))
        suu = suu + ridge / (2.5066 * max(sigma, 0.5))   # the blurred sums are normalised by the window
        # Columns far from any stereo take the whole box's robust line (large window).
        det = s0 * suu - su * su
        okd = (s0 > 1e-3 * max(wc.max(), 1)) & (det > 1e-9 * np.maximum(s0, 1) ** 2)
        b = np.where(okd, (s0 * suq - su * sq) / np.where(okd, det, 1), 0.0)
        a = np.where(s0 > 0, (sq - b * su) / np.maximum(s0, 1e-12), 0.0)
        if not okd.all():
            W0 = w.sum()
            mu, mq = (w * u).sum() / W0, (w * qv).sum() / W0
            vu = (w * (u - mu) ** 2).sum() + ridge
            bg = (w * (u - mu) * (qv - mq)).sum() / vu if vu > 1e-9 else 0.0
            a = np.where(okd, a, mq - bg * mu)
            b = np.where(okd, b, bg)
        if it == iterations - 1:
            break
        r = np.where(wc > 0, (qv - (a + b * u)) / np.maximum(np.abs(qv), 1e-9), 0.0)
        sel = wc > 0
        scale = max(1.4826 * float(np.median(np.abs(r[sel]))), 0.005)
        w = wc / (1.0 + (r / (2.385 * scale)) ** 2)
    qh = a + b * u
    # The box only where the stereo resolves its faces (a far car's slope is noise: see above).
    if box is not None and _NOMINAL_BASELINE * box[1] * float(np.median(med)) >= box[3]:
        fit = _two_faces(u + box[0], qv, wc, box[1], box[2])
        sel = wc > 0
        if fit is not None and fit[2] <= box[5] * _truncated_cost(qv[sel], qh[sel], wc[sel]) + 0.002:
            qh, b = _box_within(qh, b, fit, sel, box[4], None if had is None else had.sum(0) > 0)
    if not (qh > 1e-4).all():
        return None
    return qh, b


def _truncated_cost(qv: np.ndarray, qh: np.ndarray, wc: np.ndarray, cap: float = 0.05) -> float:
    """Weighted mean of the relative residuals of a column fit, each capped at ``cap``."""
    r = np.minimum(np.abs(qv - qh) / np.maximum(np.abs(qv), 1e-9), cap)
    return float((wc * r).sum() / max(wc.sum(), 1e-12))


def _two_faces(U: np.ndarray, qv: np.ndarray, wc: np.ndarray, fx: float, cx: float, max_yaw_deg: float = 30.0,
               yaw_step_deg: float = 2.5, steps: int = 41) -> tuple[np.ndarray, np.ndarray, float] | None:
    """A vehicle's column profile as the two visible faces of an upright box (perpendicular vertical
    planes), in inverse depth per column.

    A vertical plane with horizontal normal (n_x, n_z) has ``q = k (n_x (U - cx)/fx + n_z)`` along
    the columns (``k`` = 1 / its distance). The faces are n_A = (sin θ, cos θ) (rear or front, θ
    within ``max_yaw_deg`` of facing the camera) and n_B = (cos θ, -sin θ) (the side); a ray enters
    a convex box through the farther of the two planes, so ``q = min(q_A, q_B)`` -- a sharp corner
    (a local line rounds it over its window, and a glossy rounded corner mirrors a lamp as a
    vertical line). Grid over θ, the column where the faces meet (``steps``) and the side the rear
    is on; each face's ``k`` is the weighted median of its columns; the least truncated relative
    residual (:func:`_truncated_cost`) wins. Returns (q, dq/dU per column, cost) or None with
    fewer than 6 supported columns (``wc`` > 0).
    """
    sel = wc > 0
    if sel.sum() < 6:
        return None
    xt = (U - cx) / fx
    us, qs, ws = xt[sel], qv[sel], wc[sel]
    n = len(us)
    splits = np.unique(np.linspace(0, n, steps).astype(int))
    left = np.arange(n)[None, :] < splits[:, None]                      # (splits, columns)
    best = (np.inf, None)
    for th in np.radians(np.arange(-max_yaw_deg, max_yaw_deg + 1e-6, yaw_step_deg)):
        sn, cs = np.sin(th), np.cos(th)
        ha, hb = sn * us + cs, cs * us - sn
        ka_all, kb_all = qs / ha, qs / np.where(np.abs(hb) > 1e-6, hb, np.nan)
        for amask in (left, ~left):
            with np.errstate(all="ignore"):
                ka = _masked_median(ka_all, amask)
                kb = _masked_median(kb_all, ~amask)
                qa = np.where(np.isfinite(ka)[:, None], ka[:, None] * ha[None, :], np.inf)
                qb = ka_b = np.where(np.isfinite(kb)[:, None], kb[:, None] * hb[None, :], np.inf)
                qa = np.where(qa > 0, qa, np.inf)
                qb = np.where(ka_b > 0, qb, np.inf)
                qm = np.minimum(qa, qb)
                r = np.minimum(np.abs(qm - qs[None, :]) / qs[None, :], 0.05)
                r = np.where(np.isfinite(r), r, 0.05)
                cost = (r * ws[None, :]).sum(1) / ws.sum()
            j = int(np.argmin(cost))
            if cost[j] < best[0]:
                best = (float(cost[j]), (sn, cs, ka[j], kb[j]))
    if best[1] is None:
        return None
    sn, cs, ka, kb = best[1]
    ha, hb = sn * xt + cs, cs * xt - sn
    qa = ka * ha if np.isfinite(ka) else np.full_like(xt, np.inf)
    qb = kb * hb if np.isfinite(kb) else np.full_like(xt, np.inf)
    qa, qb = np.where(qa > 0, qa, np.inf), np.where(qb > 0, qb, np.inf)
    on_a = qa <= qb
    qh = np.where(on_a, qa, qb)
    if not np.isfinite(qh).all():
        return None
    b = np.where(on_a, ka * sn, kb * cs) / fx
    return qh, b, best[0], on_a


def _box_within(q_local: np.ndarray, b_local: np.ndarray, box: tuple, sel: np.ndarray, min_face: float,
                had: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A vehicle's column profile from the box ``box`` (:func:`_two_faces`) and the local line.

    Every face the box puts on the supported columns ``sel`` must be seen over at least
    ``min_face`` columns, else the local line is kept whole (a corner a few tens of columns from
    the end of the stereo is more likely SGM's error there -- next to its unmatched left border,
    seed 1 -- than a face). Beyond the supported columns, columns that had stereo (``had``: dropped
    as a nearer neighbour's band) take the box's face, which goes on as a plane; columns that never
    had any (the border SGM cannot match) take the local line, shifted to meet the box.
    """
    qh, b, _, on_a = box
    idx = np.flatnonzero(sel)
    f = on_a[idx]
    for face in (True, False):
        cols = idx[f == face]
        if cols.size and cols[-1] - cols[0] + 1 < min_face:
            return q_local, b_local
    qh, b = qh.copy(), b.copy()
    i0, i1 = int(idx[0]), int(idx[-1])
    for end, rng in ((i0, slice(0, i0)), (i1, slice(i1 + 1, len(qh)))):
        if rng.stop > rng.start and had is not None and float(had[rng].mean()) < 0.5:
            qh[rng] = q_local[rng] - q_local[end] + qh[end]
            b[rng] = b_local[rng]
    return qh, b


def _masked_median(v: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Median of ``v`` (n,) over each row's ``mask`` (k, n) (NaN in ``v`` ignored; NaN for none)."""
    vv = np.where(mask & np.isfinite(v)[None, :], v[None, :], np.inf)
    srt = np.sort(vv, axis=1)
    cnt = np.isfinite(srt).sum(1)
    lo = np.take_along_axis(srt, np.maximum((cnt - 1) // 2, 0)[:, None], 1)[:, 0]
    hi = np.take_along_axis(srt, np.maximum(cnt // 2, 0)[:, None], 1)[:, 0]
    return np.where(cnt >= 3, 0.5 * (lo + hi), np.nan)


def _kerbs(out_q: np.ndarray, coef: np.ndarray, labels: np.ndarray, intrinsics: Intrinsics,
           max_height: float) -> int:
    """Give the sidewalks' kerbs their vertical faces, in place; returns the kerb pixels set.

    The fitted sidewalk plane has no kerb: its road-side face (15 cm, labelled sidewalk, several
    pixels tall near the camera) was a slope, and the lamps' bright line along it was missing
    from the night (2048x1024 fixture: sidewalk structure ratio 0.71 of the exact night's). The
    kerb is the vertical plane through the road/sidewalk border (on the fitted road surface)
    along the border's 3-D direction; a ray below the kerb's top hits it before the sidewalk's
    plane, a ray above it hits the sidewalk's plane behind it, so the depth of a sidewalk pixel
    above a road border in its column is the farther of the two (at most ``max_height`` metres
    above the border: a sidewalk fitted too high does not grow a wall).
    """
    H, W = labels.shape
    fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
    top = (labels == 8) & np.isfinite(out_q)
    base = np.isin(labels, (7, 9)) & np.isfinite(out_q)
    if not top.any() or not base.any():
        return 0
    rows = np.arange(H)[:, None]
    # The first row below each pixel that is not sidewalk (H = none), per column.
    nb = np.minimum.accumulate(np.where(labels == 8, H, np.broadcast_to(rows, (H, W)))[::-1], axis=0)[::-1]
    cols = np.broadcast_to(np.arange(W)[None, :], (H, W))
    vb = np.minimum(nb, H - 1)
    cand = top & (nb < H) & base[vb, cols]
    if not cand.any():
        return 0
    # Border points (each run of sidewalk pixels: the road pixel below it) on the fitted road surface, in 3-D.
    bc = coef[vb, cols]
    vbord = vb - 0.5
    qb = bc[..., 0] + bc[..., 1] * cols + bc[..., 2] * vbord
    cand &= qb > 1e-4
    bu, bv = cols[cand], vbord[cand]
    zb = 1.0 / qb[cand]
    B = np.stack([zb * (bu - cx) / fx, zb * (bv - cy) / fy, zb], -1)
    road = bc[cand]
    up = -np.stack([road[:, 1] * fx, road[:, 2] * fy, road[:, 0] + road[:, 1] * cx + road[:, 2] * cy], -1)
    up /= np.linalg.norm(up, axis=-1, keepdims=True) + 1e-30
    # Per sidewalk component: the kerb's direction along the border is the principal direction of
    # its border points in the ground plane (one per column), robust to outliers; the kerb is one
    # vertical plane through their robust centre line (per-column planes followed the label
    # border's 1-px steps: a zigzag face, striped in the night).
    ncomp, comp = cv2.connectedComponents((labels == 8).astype(np.uint8), connectivity=4)
    cc = comp[cand]
    delta = np.full(len(B), np.nan)
    m = np.zeros_like(B)
    for k in np.unique(cc):
        sel = cc == k
        _, first = np.unique(bu[sel], return_index=True)
        P = B[sel][first]
        if len(P) < 8:
            continue
        n_up = np.median(up[sel], axis=0)
        n_up /= np.linalg.norm(n_up)
        w = np.ones(len(P))
        for _ in range(3):
            c0 = (w[:, None] * P).sum(0) / w.sum()
            D = P - c0
            D -= (D @ n_up)[:, None] * n_up[None, :]
            _, _, vt = np.linalg.svd(D * np.sqrt(w)[:, None], full_matrices=False)
            t = vt[0] - (vt[0] @ n_up) * n_up
            t /= np.linalg.norm(t)
            mk = np.cross(n_up, t)
            perp = D @ mk
            w = 1.0 / (1.0 + (perp / max(3 * np.median(np.abs(perp)), 0.02)) ** 2)
        if (mk @ c0) > 0:  # facing the camera
            mk = -mk
        m[sel] = mk
        delta[sel] = mk @ c0
    ok = np.isfinite(delta) & (delta < 0)
    delta = np.where(ok, delta, -1.0)
    N = m / delta[:, None]
    kb, kc = N[:, 0] / fx, N[:, 1] / fy
    ka = N[:, 2] - kb * cx - kc * cy
    uu, vv = cols[cand], rows.repeat(W, 1)[cand]
    qk = ka + kb * uu + kc * vv
    qt = out_q[cand]
    # Within max_height above the border (rows), the kerb where it is farther than the sidewalk plane.
    near = (vb[cand] - vv) <= max_height * fy * qb[cand] + 1
    use = ok & near & (qk > 1e-4) & (qk < qt)
    idx = np.nonzero(cand)
    iy, ix = idx[0][use], idx[1][use]
    out_q[iy, ix] = qk[use]
    coef[iy, ix] = np.stack([ka[use], kb[use], kc[use]], -1)
    return int(use.sum())


def _neighbour_matched(seg: np.ndarray, qs: np.ndarray, qfit: np.ndarray, own: np.ndarray, radius: int,
                       margin: float, tol: float = 0.05) -> np.ndarray:
    """Pixels within ``radius`` along their row of another segment nearer (its fitted inverse depth
    ``qfit`` at the border larger than the pixel's segment's robust inverse depth ``own``, per pixel,
    by more than ``margin``) whose own stereo ``qs`` equals that neighbour's within ``tol``
    (relative): the neighbour's disparity spread into them. Unlike :func:`_fattened` this does not
    trust the first fit of the pixel's own segment, which follows a band of fattened stereo wider than
    its window (a car beside a nearer one: 45 px at 2048 px wide, its rear turned 80° sideways)."""
    H, W = seg.shape
    cols = np.arange(W)[None, :]
    out = np.zeros((H, W), bool)
    for flip in (False, True):
        s = seg[:, ::-1] if flip else seg
        qf_all = np.nan_to_num(qfit[:, ::-1] if flip else qfit, nan=0.0)
        qq = np.nan_to_num(qs[:, ::-1] if flip else qs, nan=0.0)
        ow = own[:, ::-1] if flip else own
        start = np.ones((H, W), bool)
        start[:, 1:] = s[:, 1:] != s[:, :-1]
        st = np.maximum.accumulate(np.where(start, cols, 0), axis=1)
        j = st - 1
        jj = np.clip(j, 0, W - 1)
        qf = np.take_along_axis(qf_all, jj, 1)
        sf = np.take_along_axis(s, jj, 1)
        m = ((j >= 0) & (sf > 0) & (cols - j <= radius) & (ow > 0) & (qf > ow * (1.0 + margin))
             & (qq > 0) & (np.abs(qq - qf) <= tol * qf))
        out |= m[:, ::-1] if flip else m
    return out


def fit_surfaces(depth: np.ndarray, valid: np.ndarray, filled: np.ndarray, labels: np.ndarray,
                 intrinsics: Intrinsics, instances: np.ndarray | None = None,
                 params: SurfaceParams | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """Robust per-segment surface fits of stereo depth (module docstring).

    Parameters
    ----------
    depth : (H, W) float
        Stereo z-depth (m); used only where ``valid``.
    valid : (H, W) bool
        Usable stereo pixels.
    filled : (H, W) float32
        The depth used where the fit has no support (the stereo with its holes filled), NaN = none.
    labels : (H, W) uint8 labelIds; instances : (H, W) Cityscapes instanceIds or None.

    Returns
    -------
    (depth, normals, info)
        float32 z-depth (m; NaN where ``filled`` is NaN and nothing was fitted), (H, W, 3)
        float32 unit normals toward the camera (NaN where none), and counts of what was done.
    """
    p = params or SurfaceParams()
    t0 = time.perf_counter()
    H, W = labels.shape
    scale = W / 2048.0
    depth = np.asarray(depth, np.float64)
    valid = np.asarray(valid, bool) & np.isfinite(depth) & (depth > 0)
    speckle = _speckle_mask(depth, valid, intrinsics.fx, W, p)
    use = valid & ~speckle
    seg, n_seg = _segments(labels, instances)
    # Edge fattening: no stereo within edge_px of a segment border.
    border = np.zeros((H, W), bool)
    border[:, 1:] |= seg[:, 1:] != seg[:, :-1]
    border[:, :-1] |= seg[:, 1:] != seg[:, :-1]
    border[1:] |= seg[1:] != seg[:-1]
    border[:-1] |= seg[1:] != seg[:-1]
    r = max(1, int(round(p.edge_px * scale)))
    near_edge = cv2.dilate(border.astype(np.uint8), np.ones((2 * r - 1, 2 * r - 1), np.uint8)).astype(bool) \
        if r > 1 else border
    use &= ~near_edge

    base_f = max(1, int(round(W / _WORK_WIDTH)))
    out_q = np.full((H, W), np.nan)
    coef_full = np.full((H, W, 3), np.nan)
    label_of_seg = np.zeros(n_seg + 1, np.int32)
    label_of_seg[seg.ravel()] = labels.ravel()
    counts = {"segments": int(n_seg), "fitted": 0, "thin": 0, "unsupported": 0}
    # Bounding boxes of all segments at once.
    rows, cols = np.nonzero(seg)
    ids = seg[rows, cols]
    y0, x0 = np.full(n_seg + 1, H), np.full(n_seg + 1, W)
    y1, x1 = np.full(n_seg + 1, -1), np.full(n_seg + 1, -1)
    np.minimum.at(y0, ids, rows)
    np.maximum.at(y1, ids, rows)
    np.minimum.at(x0, ids, cols)
    np.maximum.at(x1, ids, cols)
    fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
    def fit_pass(segments, use: np.ndarray, cnt: dict) -> None:
        """Fit ``segments`` to the stereo pixels ``use`` (writes out_q, coef_full)."""
        qfull = np.where(use, 1.0 / np.where(use, depth, 1.0), 0.0)
        nvalid = np.bincount(seg[use], minlength=n_seg + 1)
        for s in segments:
            lab = int(label_of_seg[s])
            if y1[s] < 0:
                continue
            if lab in THIN_CLASSES:
                sl = (slice(y0[s], y1[s] + 1), slice(x0[s], x1[s] + 1))
                ms = (seg[sl] == s)
                # All of its stereo, not only what the edge trimming left (a pole a few pixels wide is
                # all edge); and, if it has none within the stereo's range, its stereo beyond it: a
                # lamp pole at the street's end (101 m) otherwise took the hole filling's 53-62 m
                # and its lamp lit the near road white (2048x1024 fixture, docs/relight.md).
                raw = ms & np.isfinite(depth[sl]) & (depth[sl] > 0) & ~speckle[sl]
                ok_t = raw & valid[sl]
                if ok_t.sum() < max(3, 0.05 * ms.sum()):
                    ok_t = raw
                qs = 1.0 / depth[sl][ok_t]
                if qs.size >= max(3, 0.05 * ms.sum()):
                    qm = float(np.median(qs))
                    blk = out_q[sl]
                    blk[ms] = qm
                    cb = coef_full[sl]
                    cb[ms] = (qm, 0.0, 0.0)
                    cnt["thin"] += 1
                else:
                    cnt["unsupported"] += 1
                continue
            if nvalid[s] < 12:
                cnt["unsupported"] += 1
                continue
            if lab in VEHICLE_CLASSES and p.vehicle_upright:
                sl = (slice(y0[s], y1[s] + 1), slice(x0[s], x1[s] + 1))
                ms = seg[sl] == s
                box = (float(x0[s]), fx, cx, p.vehicle_box_disparity * scale, p.vehicle_box_min_face * scale,
                       p.vehicle_box_tolerance) if p.vehicle_box else None
                qc = _upright_columns(qfull[sl], ms & use[sl], p.vehicle_column_sigma * scale, p.iterations,
                                      p.vehicle_noise_px, box, ms & valid[sl])
                if qc is None:
                    cnt["unsupported"] += 1
                    continue
                q_col, b_col = qc
                U = np.arange(x0[s], x1[s] + 1, dtype=np.float64)
                blk = out_q[sl]
                blk[ms] = np.broadcast_to(q_col[None, :], ms.shape)[ms]
                cb = coef_full[sl]
                cf = np.stack([q_col - b_col * U, b_col, np.zeros_like(b_col)], -1)
                cb[ms] = np.broadcast_to(cf[None], ms.shape + (3,))[ms]
                cnt["fitted"] += 1
                continue
            sigma_full = (p.plane_sigma if lab in PLANE_CLASSES else p.vehicle_sigma if lab in VEHICLE_CLASSES
                          else p.vegetation_sigma if lab in VEGETATION_CLASSES else p.detail_sigma) * scale
            # Work on a grid about sigma/6 coarser (at least 512 px wide): the coefficients are smooth.
            f = max(base_f, int(sigma_full // 6))
            pad = int(3 * sigma_full) + f
            ya, yb = max(0, y0[s] - pad), min(H, y1[s] + 1 + pad)
            xa, xb = max(0, x0[s] - pad), min(W, x1[s] + 1 + pad)
            # Crop aligned to the working grid.
            ya, xa = (ya // f) * f, (xa // f) * f
            yb, xb = min(H, -(-yb // f) * f), min(W, -(-xb // f) * f)
            ms = seg[ya:yb, xa:xb] == s
            wq = (ms & use[ya:yb, xa:xb]).astype(np.float32)
            qq = qfull[ya:yb, xa:xb].astype(np.float32)
            hw, ww = -(-(yb - ya) // f), -(-(xb - xa) // f)
            if f > 1:
                wsum = cv2.resize(wq, (ww, hw), interpolation=cv2.INTER_AREA)
                qsum = cv2.resize(wq * qq, (ww, hw), interpolation=cv2.INTER_AREA)
                qw = np.where(wsum > 0, qsum / np.maximum(wsum, 1e-12), 0.0)
            else:
                wsum, qw = wq, qq
            # Working pixel centres in full-resolution pixel coordinates, normalised for conditioning.
            u = xa + (np.arange(ww) + 0.5) * f - 0.5
            v = ya + (np.arange(hw) + 0.5) * f - 0.5
            uc, vc, L = 0.5 * (xa + xb), 0.5 * (ya + yb), float(W)
            uu = np.broadcast_to(((u - uc) / L)[None, :], (hw, ww)).astype(np.float64)
            vv = np.broadcast_to(((v - vc) / L)[:, None], (hw, ww)).astype(np.float64)
            sig_w = max(0.5, sigma_full / f)
            sig_v = None
            if lab in VEGETATION_CLASSES and p.vegetation_upright:
                # Crowns locally upright: inverse depth a function of the column within a window
                # taller than wide (no slope along the rows; docs/relight.md "Nights of real frames").
                vv = np.zeros_like(vv)
                sig_v = sig_w * p.vegetation_v_factor
            coef, support = _local_planes(qw.astype(np.float64), wsum.astype(np.float64), uu, vv, sig_w,
                                          p.iterations, ridge=1e-4 * (sig_w * f / L) ** 2, sigma_v=sig_v)
            # Coefficients in full-resolution pixel units: q = a + b u + c v.
            b = coef[..., 1] / L
            c = coef[..., 2] / L
            a = coef[..., 0] - b * uc - c * vc
            full = np.stack([a, b, c], -1).astype(np.float32)
            if f > 1:
                full = cv2.resize(full, (xb - xa, yb - ya), interpolation=cv2.INTER_LINEAR)
                support = cv2.resize(support.astype(np.float32), (xb - xa, yb - ya), interpolation=cv2.INTER_LINEAR)
            full = full.astype(np.float64)
            U = np.arange(xa, xb)[None, :].astype(np.float64)
            V = np.arange(ya, yb)[:, None].astype(np.float64)
            if lab in PLANE_CLASSES:
                # A façade or the ground goes on where the stereo has none (the left border SGM cannot
                # match, occlusions): far from support the local fit hands over to the segment's
                # robust plane, blended in the coefficients so the surface stays smooth.
                glob = _segment_plane(qfull[ya:yb, xa:xb], ms & use[ya:yb, xa:xb], xa, ya)
                if glob is not None:
                    alpha = np.clip(support / p.handover, 0.0, 1.0)
                    full = alpha[..., None] * full + (1 - alpha[..., None]) * glob[None, None, :]
                    # ... but only where the hole filling agrees that it is the same surface (a far
                    # façade beyond the stereo's range joined to a near one is not). On the ground,
                    # where the pixel had stereo, the filling is that stereo, dropped as speckle or a
                    # fattened edge (a pole's or a car's disparity spread onto the sidewalk beside it):
                    # the fit goes on there. Left as it was, those pixels stood 10-50 % in front of
                    # the sidewalk and the night drew dark bands across it (docs/geometry.md,
                    # "Sidewalks beside poles and cars"); on façades the same rule made them worse.
                    qb = full[..., 0] + full[..., 1] * U + full[..., 2] * V
                    fz = filled[ya:yb, xa:xb]
                    with np.errstate(invalid="ignore", divide="ignore"):
                        agree = ~np.isfinite(fz) | (np.abs(1.0 / qb - fz) <= p.handover_agreement * fz)
                    if p.fit_over_dropped and lab in GROUND_CLASSES:
                        agree |= valid[ya:yb, xa:xb]
                    support = np.where(ms & (alpha < 1) & agree, 1.0, np.where(alpha < 1, 0.0, support))
            qh = full[..., 0] + full[..., 1] * U + full[..., 2] * V
            ok = ms & (support >= p.min_support) & (qh > 1e-4)
            if not ok.any():
                cnt["unsupported"] += 1
                continue
            blk = out_q[ya:yb, xa:xb]
            blk[ok] = qh[ok]
            cb = coef_full[ya:yb, xa:xb]
            cb[ok] = full[ok]
            cnt["fitted"] += 1

    fit_pass(range(1, n_seg + 1), use, counts)
    # Edge fattening toward the background is wider than edge_px (SGM's block and path costs spread
    # the nearer object's disparity 10-20 px at 1024 px wide into the farther one): a pixel within
    # fattening_px along its row of a nearer segment (by the first fit, > fattening_margin) is
    # dropped and its segment refitted. A car seen beside a nearer one leaned toward it (a lamp
    # on it then threw its light sideways along a facade, docs/relight.md).
    counts["fattening_refit"] = 0
    if p.fattening_px > 0:
        fat = _fattened(seg, out_q, max(1, int(round(p.fattening_px * scale))), p.fattening_margin)
        fat &= use & ~np.isin(label_of_seg[seg], THIN_CLASSES)
        if p.vehicle_matched_px > 0:
            # Vehicles: stereo that took a nearer neighbour's depth, whatever their own first fit says.
            qs = np.where(use, 1.0 / np.where(use, depth, 1.0), np.nan)
            own = np.zeros(n_seg + 1)
            for sv in np.unique(seg[np.isin(label_of_seg[seg], VEHICLE_CLASSES) & use]):
                own[sv] = float(np.median(qs[(seg == sv) & use]))
            veh = np.isin(label_of_seg[seg], VEHICLE_CLASSES)
            radius = max(1, int(round(p.vehicle_matched_px * scale)))
            fat |= use & veh & _neighbour_matched(seg, qs, out_q, own[seg], radius, p.fattening_margin)
        counts["fattening_dropped_fraction"] = round(float(fat.mean()), 4)
        if fat.any():
            redo = np.unique(seg[fat])
            fit_pass(redo[redo > 0], use & ~fat, {"fitted": 0, "thin": 0, "unsupported": 0})
            counts["fattening_refit"] = int((redo > 0).sum())
    counts["kerb_pixels"] = _kerbs(out_q, coef_full, labels, intrinsics, p.kerb_max_m) if p.kerb_max_m > 0 else 0
    fitted = np.isfinite(out_q)
    z = np.where(fitted, 1.0 / np.where(fitted, out_q, 1.0), filled).astype(np.float32)
    a, b, c = coef_full[..., 0], coef_full[..., 1], coef_full[..., 2]
    n = -np.stack([b * fx, c * fy, a + b * cx + c * cy], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True) + 1e-30
    normals = np.where(fitted[..., None], n, np.nan).astype(np.float32)
    info = {**counts, "fitted_fraction": round(float(fitted.mean()), 4),
            "speckle_fraction": round(float(speckle.mean()), 4),
            "edge_trimmed_fraction": round(float((valid & near_edge).mean()), 4),
            "time_s": round(time.perf_counter() - t0, 3)}
    return z, normals, info
