"""A proposed window's confidence: how sure the proposer is that it is a window the annotator
keeps (docs/proposals.md, "Seventh pass: confidence", "Tenth pass: window confidence from the
façade grid").

Kept apart from :mod:`.windows` (which finds the panes) so the score can be refitted without
touching the detection: :func:`rescore_windows` runs on the final window groups.
"""

from __future__ import annotations

import numpy as np

from .core import Context, Group, Light
from .windows import _median_depth, _ring_contrast

#: Row-mates (:func:`grid_mates`): like size -- height within this ratio, width within ``ROW_WIDTH_RATIO``
#: (a receding wall foreshortens widths more than heights) --, top and bottom edges each within
#: ``ROW_EDGE_TOL`` of the taller one's height (+ half a pixel), beside it (no common column) and
#: at most ``ROW_REACH`` of the wider one's widths (+ 2 px) away along the row.
ROW_HEIGHT_RATIO = 1.5
ROW_WIDTH_RATIO = 2.0
ROW_EDGE_TOL = 1.0 / 3.0
ROW_REACH = 10.0
#: Column-mates: width within ``ROW_HEIGHT_RATIO``, height within ``ROW_WIDTH_RATIO``, sharing at least
#: half the narrower one's columns, one to five floors away: centres 0.8 to 5 of the taller one's heights apart.
COL_MIN_OVERLAP = 0.5
COL_SPAN = (0.8, 5.0)
#: Mates lie on one wall: median depths within this share of the window's own (no test without depth).
MATE_DEPTH_TOL = 0.15


def grid_mates(boxes: np.ndarray, depth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per window, its support from the façade grid (docs/proposals.md "Tenth pass").

    Parameters
    ----------
    boxes : (n, 4) float
        Each window's bounding box ``y0, x0, height, width`` in pixels.
    depth : (n,) float
        Each window's median depth in metres, NaN when unknown.

    Returns
    -------
    row, col, adjacent : (n,) int
        The number of *row-mates* (windows of like size beside it on the same floor, top and bottom
        aligned), of *column-mates* (windows of like size in the same bay one to five floors up or
        down) and of other windows whose box is within one pixel of its box (a fragment beside a
        pane, or a pane cut in pieces). Windows come in floors and bays of like panes; a fleck of
        wall, a balcony slab's edge or a piece of a split pane has no such mates.
    """
    b = np.asarray(boxes, float).reshape(-1, 4)
    z = np.asarray(depth, float).reshape(-1)
    n = b.shape[0]
    if n == 0:
        e = np.zeros(0, int)
        return e, e, e
    y0, x0, h, w = (b[:, k] for k in range(4))
    y1, x1 = y0 + h, x0 + w
    hr, wr = h[None, :] / h[:, None], w[None, :] / w[:, None]  # [i, j]: j against i
    th = np.maximum(h[:, None], h[None, :])
    h_ov = (np.minimum(x1[:, None], x1[None, :]) - np.maximum(x0[:, None], x0[None, :])) \
        / np.minimum(w[:, None], w[None, :])
    with np.errstate(invalid="ignore"):
        same_wall = ~np.isfinite(z[:, None]) | ~np.isfinite(z[None, :]) \
            | (np.abs(z[None, :] - z[:, None]) <= MATE_DEPTH_TOL * z[:, None])
    tol = ROW_EDGE_TOL * th + 0.5
    row = ((hr >= 1 / ROW_HEIGHT_RATIO) & (hr <= ROW_HEIGHT_RATIO) & (wr >= 1 / ROW_WIDTH_RATIO) & (wr <= ROW_WIDTH_RATIO)
           & (np.abs(y0[:, None] - y0[None, :]) <= tol) & (np.abs(y1[:, None] - y1[None, :]) <= tol)
           & (h_ov <= 0) & (np.abs((x0 + x1)[:, None] - (x0 + x1)[None, :]) / 2
                            <= ROW_REACH * np.maximum(w[:, None], w[None, :]) + 2) & same_wall)
    dy = np.abs((y0 + y1)[:, None] - (y0 + y1)[None, :]) / 2
    col = ((wr >= 1 / ROW_HEIGHT_RATIO) & (wr <= ROW_HEIGHT_RATIO) & (hr >= 1 / ROW_WIDTH_RATIO) & (hr <= ROW_WIDTH_RATIO)
           & (h_ov >= COL_MIN_OVERLAP) & (dy >= COL_SPAN[0] * th) & (dy <= COL_SPAN[1] * th) & same_wall)
    gap = np.maximum(np.maximum(y0[None, :] - y1[:, None], y0[:, None] - y1[None, :]),
                     np.maximum(x0[None, :] - x1[:, None], x0[:, None] - x1[None, :]))
    adj = gap <= 1
    eye = np.eye(n, dtype=bool)
    return ((row & ~eye).sum(1), (col & ~eye).sum(1), (adj & ~eye).sum(1))


def confidence_features(ctx: Context, feat: np.ndarray, B: np.ndarray, li: Light, n_group: int) -> dict:
    """What a window's final confidence is judged on (:func:`window_confidence`): the contrast to
    the building pixels in a ring around it (:func:`windows._ring_contrast`, 0 without a ring), its area and
    box (px), height (m; NaN without depth), median depth (m; NaN without), the size of its windows_group;
    kind, cut and position are there to be logged beside it (docs/proposals.md "Seventh pass" was fitted
    on them). The grid terms (``row_mates``, ``col_mates``, ``adjacent``) need every window of the frame:
    :func:`window_features` adds them."""
    d = _ring_contrast(feat, B, li.y0, li.x0, li.mask, max(2, ctx.params.window_ring_px), ctx.params)
    z = _median_depth(ctx, li)
    h, w = li.mask.shape
    return {"ring_lum": d[0] if d else 0.0, "ring_chroma": d[1] if d else 0.0, "area_px": float(li.mask.sum()),
            "h_px": float(h), "w_px": float(w),
            "h_m": h * z / float(ctx.intrinsics.fy) if z is not None else float("nan"),
            "z_m": float(z) if z is not None else float("nan"),
            "n_group": float(n_group), "kind": li.kind or "window", "cut": bool(li.cut),
            "y0": li.y0, "x0": li.x0}


def window_features(ctx: Context, groups: list[Group], feat: np.ndarray, B: np.ndarray) -> list[list[dict]]:
    """:func:`confidence_features` of every window of ``groups`` (per group, per member) with its
    façade-grid support (:func:`grid_mates` over all the frame's windows) as ``row_mates``,
    ``col_mates`` and ``adjacent``."""
    out = [[confidence_features(ctx, feat, B, li, len(g.members)) for li in g.members] for g in groups]
    flat = [x for xs in out for x in xs]
    boxes = np.array([[x["y0"], x["x0"], x["h_px"], x["w_px"]] for x in flat], float).reshape(-1, 4)
    row, col, adj = grid_mates(boxes, np.array([x["z_m"] for x in flat], float))
    for x, r, c, a in zip(flat, row, col, adj):
        x.update(row_mates=int(r), col_mates=int(c), adjacent=int(a))
    return out


def window_confidence(p, conf: float, x: dict) -> float:
    """A window's final confidence from its first one ``conf`` and its features ``x``
    (:func:`window_features`; docs/proposals.md "Seventh pass", "Tenth pass").

    The first confidence (fill, contrast to the wall reference, a floor of three) hardly told a
    true window from a false one (most false windows cover no true light at all: flecks of wall,
    balcony slabs, edges between wall colours). What does is how much the window differs from the
    wall right around it, how tall it is, and whether the façade grid backs it: like windows beside
    it on its floor (row-mates) and above or below it in its bay (column-mates), and no other window
    touching its box (a fragment). A logistic score ``window_conf_bias + w . (conf, ring
    log-luminance contrast, ring chroma contrast, height m, ln pixels, ln(1 + row-mates),
    ln(1 + column-mates), touched)`` (``window_conf_weights``; contrasts over the window thresholds,
    clipped at 3; height clipped at 2.5 m, 1 m without depth) mapped to 0.5 + 0.5 sigmoid(score).
    Only windows at least 0.5 confident are rescored, into [0.5, 1): the set kept at 0.5 does not
    change, only its order. A window of fewer than ``window_tiny_px`` pixels stays at most
    ``window_tiny_max_confidence``. Weights shorter than 8 leave the grid terms out (the seventh
    pass's five).
    """
    wts = tuple(p.window_conf_weights)
    if conf < 0.5 or not any(wts):
        return conf
    h = x["h_m"] if np.isfinite(x["h_m"]) else 1.0
    v = [conf, min(x["ring_lum"], 3.0), min(x["ring_chroma"], 3.0), min(h, 2.5), np.log(max(x["area_px"], 1.0))]
    if len(wts) > 5:
        v += [np.log1p(x["row_mates"]), np.log1p(x["col_mates"]), float(x["adjacent"] > 0)]
    z = p.window_conf_bias + float(np.dot(wts, v[:len(wts)]))
    out = 0.5 + 0.5 / (1.0 + np.exp(-z))
    if x["area_px"] < p.window_tiny_px:
        out = min(out, p.window_tiny_max_confidence)
    return float(out)


def rescore_windows(ctx: Context, groups: list[Group], feat: np.ndarray, B: np.ndarray) -> list[Group]:
    """Set every window's final confidence (:func:`window_confidence`) and each group's as the mean
    of its members'. ``feat``: the windows proposer's per-pixel features; ``B``: its building mask."""
    p = ctx.params
    for g, xs in zip(groups, window_features(ctx, groups, feat, B)):
        for li, x in zip(g.members, xs):
            li.confidence = window_confidence(p, li.confidence, x)
        g.confidence = float(np.mean([li.confidence for li in g.members])) if g.members else g.confidence
    return groups
