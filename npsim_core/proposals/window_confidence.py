"""A proposed window's confidence: how sure the proposer is that it is a window the annotator
keeps (docs/proposals.md, "Seventh pass: confidence", "Tenth pass: window confidence from the
façade grid", "Eleventh pass: the slider").

Kept apart from :mod:`.windows` (which finds the panes) so the score can be refitted without
touching the detection: :func:`rescore_windows` runs on the final window groups.
"""

from __future__ import annotations

import cv2
import numpy as np

from .core import Context, Group, Light, median
from .windows import BUILDING, SKY, _median_depth, _ring_contrast

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
#: The neighbourhood whose share of things in front of the wall is ``front_near`` (:func:`front_shares`):
#: the pane's box grown by this many pane widths to each side and pane heights up and down (where its
#: row- and column-mates would be), + 1 px.
NEAR_WIDTHS = 3.0
NEAR_HEIGHTS = 1.5
#: A pane whose bottom is lower than this (m above the ground) is on the ground floor (``ground_floor``).
GROUND_FLOOR_M = 3.0
#: Panes taller than this (m) lose confidence per metre over it (``tall_m``, clipped at 2 m over).
TALL_M = 2.0


def front_shares(front: np.ndarray, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per window, how much of its surroundings is something in front of the wall (docs/proposals.md
    "Eleventh pass: the slider").

    Parameters
    ----------
    front : (H, W) bool
        Pixels labelled in front of the wall: neither building nor sky (a tree, a pole, a car, a person).
    boxes : (n, 4) float
        Each window's box ``y0, x0, height, width`` in pixels.

    Returns
    -------
    near, touch : (n,) float
        The share of ``front`` pixels in the pane's neighbourhood (its box grown by ``NEAR_WIDTHS`` widths
        left and right and ``NEAR_HEIGHTS`` heights up and down, + 1 px; clipped at the image) -- where
        its mates would be: a pane without mates among trees is not an isolated fleck --, and on the
        one-pixel ring around its box (something in front touches it: the pane may be one piece of a
        light cut in two). 0 where the region is empty. One summed-area table: O(H W + n).
    """
    H, W = front.shape
    b = np.asarray(boxes, float).reshape(-1, 4)
    if b.shape[0] == 0:
        return np.zeros(0), np.zeros(0)
    S = cv2.integral(front.view(np.uint8) if front.dtype == bool else front.astype(np.uint8))  # (H+1, W+1)

    def total(ya, yb, xa, xb):
        ya, yb = np.clip(ya, 0, H).astype(int), np.clip(yb, 0, H).astype(int)
        xa, xb = np.clip(xa, 0, W).astype(int), np.clip(xb, 0, W).astype(int)
        yb, xb = np.maximum(yb, ya), np.maximum(xb, xa)
        return S[yb, xb] - S[ya, xb] - S[yb, xa] + S[ya, xa], (yb - ya) * (xb - xa)

    y0, x0, h, w = (np.round(b[:, k]) for k in range(4))
    s, n = total(y0 - np.floor(NEAR_HEIGHTS * h) - 1, y0 + h + np.floor(NEAR_HEIGHTS * h) + 1,
                 x0 - np.floor(NEAR_WIDTHS * w) - 2, x0 + w + np.floor(NEAR_WIDTHS * w) + 2)
    near = np.where(n > 0, s / np.maximum(n, 1), 0.0)
    s_out, n_out = total(y0 - 1, y0 + h + 1, x0 - 1, x0 + w + 1)
    s_in, n_in = total(y0, y0 + h, x0, x0 + w)
    ring = n_out - n_in
    touch = np.where(ring > 0, (s_out - s_in) / np.maximum(ring, 1), 0.0)
    return near, touch


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
    # Each window is compared only with those near enough for a test (a textured wall without depth
    # gives ten thousand windows: the dense n x n arrays took 40 s at 2048x1024): row-mates by their
    # top rows (within ROW_EDGE_TOL x the taller height + 0.5, the taller at most ROW_HEIGHT_RATIO x
    # its own), column-mates by their centre columns (overlapping: within half the two widths, the
    # other at most ROW_HEIGHT_RATIO x its own), touching windows by centre column or row, whichever
    # extent is smaller (within half the two extents + 1 px); in blocks of 256 windows.
    block = 256
    b = np.asarray(boxes, float).reshape(-1, 4)
    z = np.asarray(depth, float).reshape(-1)
    n = b.shape[0]
    row, col, adj = np.zeros(n, int), np.zeros(n, int), np.zeros(n, int)
    if n == 0:
        return row, col, adj
    y0, x0, h, w = (b[:, k] for k in range(4))
    y1, x1 = y0 + h, x0 + w

    def common(I, J):
        hr, wr = h[J][None, :] / h[I][:, None], w[J][None, :] / w[I][:, None]
        th = np.maximum(h[I][:, None], h[J][None, :])
        h_ov = (np.minimum(x1[I][:, None], x1[J][None, :]) - np.maximum(x0[I][:, None], x0[J][None, :])) \
            / np.minimum(w[I][:, None], w[J][None, :])
        with np.errstate(invalid="ignore"):
            same_wall = ~np.isfinite(z[I][:, None]) | ~np.isfinite(z[J][None, :]) \
                | (np.abs(z[J][None, :] - z[I][:, None]) <= MATE_DEPTH_TOL * z[I][:, None])
        return hr, wr, th, h_ov, same_wall, I[:, None] == J[None, :]

    def sweep(key, reach, test, out):
        order = np.argsort(key, kind="stable")
        ks = key[order]
        for s in range(0, n, block):
            I = order[s:s + block]
            r = float(np.max(reach[I])) + 1e-6
            J = order[np.searchsorted(ks, ks[s] - r, "left"):np.searchsorted(ks, ks[min(s + block, n) - 1] + r, "right")]
            out[I] = test(I, J).sum(1)

    def row_test(I, J):
        hr, wr, th, h_ov, same_wall, eye = common(I, J)
        tol = ROW_EDGE_TOL * th + 0.5
        return ((hr >= 1 / ROW_HEIGHT_RATIO) & (hr <= ROW_HEIGHT_RATIO) & (wr >= 1 / ROW_WIDTH_RATIO) & (wr <= ROW_WIDTH_RATIO)
                & (np.abs(y0[I][:, None] - y0[J][None, :]) <= tol) & (np.abs(y1[I][:, None] - y1[J][None, :]) <= tol)
                & (h_ov <= 0) & (np.abs((x0 + x1)[I][:, None] - (x0 + x1)[J][None, :]) / 2
                                 <= ROW_REACH * np.maximum(w[I][:, None], w[J][None, :]) + 2) & same_wall & ~eye)

    def col_test(I, J):
        hr, wr, th, h_ov, same_wall, eye = common(I, J)
        dy = np.abs((y0 + y1)[I][:, None] - (y0 + y1)[J][None, :]) / 2
        return ((wr >= 1 / ROW_HEIGHT_RATIO) & (wr <= ROW_HEIGHT_RATIO) & (hr >= 1 / ROW_WIDTH_RATIO) & (hr <= ROW_WIDTH_RATIO)
                & (h_ov >= COL_MIN_OVERLAP) & (dy >= COL_SPAN[0] * th) & (dy <= COL_SPAN[1] * th) & same_wall & ~eye)

    def adj_test(I, J):
        gap = np.maximum(np.maximum(y0[J][None, :] - y1[I][:, None], y0[I][:, None] - y1[J][None, :]),
                         np.maximum(x0[J][None, :] - x1[I][:, None], x0[I][:, None] - x1[J][None, :]))
        return (gap <= 1) & (I[:, None] != J[None, :])

    sweep(y0, ROW_EDGE_TOL * ROW_HEIGHT_RATIO * h + 0.5, row_test, row)
    sweep((x0 + x1) / 2, 0.5 * (1 + ROW_HEIGHT_RATIO) * w, col_test, col)
    if w.max() <= h.max():
        sweep((x0 + x1) / 2, 0.5 * (w + w.max()) + 1, adj_test, adj)
    else:
        sweep((y0 + y1) / 2, 0.5 * (h + h.max()) + 1, adj_test, adj)
    return row, col, adj


def _side_pairs(feat: np.ndarray, y0: int, x0: int, h: int, w: int, mask: np.ndarray | None, p) -> list:
    """A window's four sides as (inside, outside) pairs of feature rows: along the mask's own edge
    (:func:`_mask_edge_pairs`) when ``mask`` fills at least ``window_edge_mask_min_fill`` of its h x w box,
    else the box's outermost rows and columns and the ones just outside (a side outside the image is left
    out)."""
    if mask is not None and mask.shape == (h, w) and mask.any() \
            and mask.sum() >= p.window_edge_mask_min_fill * h * w:
        return _mask_edge_pairs(feat, y0, x0, mask)
    H, W = feat.shape[:2]
    y1, x1 = y0 + h, x0 + w
    pairs = []
    if y0 >= 1:
        pairs.append((feat[y0, x0:x1], feat[y0 - 1, x0:x1]))
    if y1 < H:
        pairs.append((feat[y1 - 1, x0:x1], feat[y1, x0:x1]))
    if x0 >= 1:
        pairs.append((feat[y0:y1, x0], feat[y0:y1, x0 - 1]))
    if x1 < W:
        pairs.append((feat[y0:y1, x1 - 1], feat[y0:y1, x1]))
    return pairs


def edge_contrast(feat: np.ndarray, y0: int, x0: int, h: int, w: int, p, mask: np.ndarray | None = None) -> float:
    """How well the weakest side of a window's box stands out (docs/proposals.md "Eleventh pass: the
    slider"): per side of the box ``y0, x0, h, w`` (px) inside the image, the medians of the proposer's
    features (``feat``: log luminance, Lab a, b) along its outermost row (column) inside and the one just
    outside, their log-luminance difference over the window threshold (-ln ``window_dark_ratio``) or
    their chroma distance over ``window_chroma_delta``, whichever is larger; the smallest over the sides,
    0 when no side lies inside the image. A pane traced whole stands out on all four sides; one traced
    short (half a pane, its glass continuing past the cut) or long (its frame and a strip of wall) has a
    side inside glass or wall of its own colour. With ``mask`` (the window's mask in its box) filling at
    least ``window_edge_mask_min_fill`` of its box, each side is read along the mask's own edge
    (:func:`_mask_edge_pairs`): a receding pane is a parallelogram, and its box's outer rows are mostly
    wall on both sides of them; a ragged blob's edge is where the thresholds cut it, which says nothing."""
    pairs = _side_pairs(feat, y0, x0, h, w, mask, p)
    t = -np.log(p.window_dark_ratio)
    out = []
    for a, b in pairs:
        if a.size == 0 or b.size == 0:
            continue
        ma, mb = median(a, axis=0), median(b, axis=0)
        out.append(max(abs(float(ma[0] - mb[0])) / t,
                       float(np.hypot(ma[1] - mb[1], ma[2] - mb[2])) / p.window_chroma_delta))
    return float(min(out)) if out else 0.0


def edge_contrasts(feat: np.ndarray, lights: list, p) -> list[float]:
    """:func:`edge_contrast` of each window (a Light: its box and mask), the same floats: every side's two
    medians of all the windows by one sort per feature (per window they took a dozen small sorts). A
    feature image holding a NaN is left to :func:`edge_contrast` per window."""
    ins, outs, owner = [], [], []
    for k, li in enumerate(lights):
        pairs = _side_pairs(feat, li.y0, li.x0, *li.mask.shape, li.mask, p)
        for a, b in pairs:
            if a.size and b.size:
                ins.append(a)
                outs.append(b)
                owner.append(k)
    out = [0.0] * len(lights)
    if not owner:
        return out
    segs = ins + outs
    n = np.array([len(a) for a in segs])
    v = np.concatenate(segs)
    if v.dtype.kind != "f" or v.ndim != 2 or np.isnan(v).any():
        return [edge_contrast(feat, li.y0, li.x0, li.mask.shape[0], li.mask.shape[1], p, li.mask) for li in lights]
    seg = np.repeat(np.arange(n.size), n)
    st = np.concatenate(([0], np.cumsum(n)[:-1]))
    med = np.empty((n.size, v.shape[1]), v.dtype)
    odd = n % 2 == 1
    for c in range(v.shape[1]):  # core.median's values: the middle one, or the two middle ones' mean
        s = v[np.lexsort((v[:, c], seg)), c]
        lo, hi = s[st + (n - 1) // 2], s[st + n // 2]
        med[:, c] = np.where(odd, hi + 0.0, (lo + hi + 0.0) / 2)
    ma, mb = med[:len(ins)], med[len(ins):]
    t = -np.log(p.window_dark_ratio)
    d = np.maximum(np.abs((ma[:, 0] - mb[:, 0]).astype(np.float64)) / t,
                   np.hypot(ma[:, 1] - mb[:, 1], ma[:, 2] - mb[:, 2]).astype(np.float64) / p.window_chroma_delta)
    best = np.full(len(lights), np.inf)
    np.minimum.at(best, np.array(owner), d)
    return [float(b) if np.isfinite(b) else 0.0 for b in best]


def _mask_edge_pairs(feat: np.ndarray, y0: int, x0: int, mask: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per side of a window (top, bottom, left, right), its mask's edge pixels and the pixels just outside
    them (docs/proposals.md "Sixteenth pass: windows at 512x256"): per column its first (last) mask row
    and the row above (below), per row its first (last) mask column and the column left (right) of it,
    where that lies inside the image. A side with none is left out. ``feat`` (H, W, 3); ``mask`` (h, w)
    bool at (``y0``, ``x0``)."""
    H, W = feat.shape[:2]
    h, w = mask.shape
    pairs = []
    cols = np.flatnonzero(mask.any(0))
    rows = np.flatnonzero(mask.any(1))
    # (the first and last mask pixel of every column and row, then those that hold one: no copies of the mask)
    top = np.argmax(mask, axis=0)[cols]
    bot = h - 1 - np.argmax(mask[::-1], axis=0)[cols]
    left = np.argmax(mask, axis=1)[rows]
    right = w - 1 - np.argmax(mask[:, ::-1], axis=1)[rows]
    for ins_y, ins_x, dy, dx in ((y0 + top, x0 + cols, -1, 0), (y0 + bot, x0 + cols, 1, 0),
                                 (y0 + rows, x0 + left, 0, -1), (y0 + rows, x0 + right, 0, 1)):
        oy, ox = ins_y + dy, ins_x + dx
        ok = (oy >= 0) & (oy < H) & (ox >= 0) & (ox < W)
        if ok.any():
            pairs.append((feat[ins_y[ok], ins_x[ok]], feat[oy[ok], ox[ok]]))
    return pairs


def frame_cut_fill(mask: np.ndarray, y0: int, H: int, min_h_px: float) -> float:
    """The fill of a pane's box, judged beyond the frame where the image's top or bottom edge cuts it
    (docs/proposals.md "Twelfth pass: panes the frame cuts").

    Parameters
    ----------
    mask : (h, w) bool
        The window's mask in its box, whose top row is image row ``y0``.
    y0 : int
        The box's top row (px).
    H : int
        The image's height (px).
    min_h_px : float
        The least height of a pane at the window's depth (px; ``window_height_m[0]``); NaN or 0: unknown.

    Returns
    -------
    float
        ``mask.sum() / (h w)``, except when the box lies on the image's top (bottom) edge and the mask holds
        at least half the box's columns on that edge row: the frame cut the pane there, and a receding pane
        cut short shows mostly its slanted other end (a trapezoid of fill 0.7 where its whole is a
        parallelogram of 0.9). It goes on beyond the frame for at least the rows a pane needs: the box is
        grown by ``ceil(min_h_px) - h`` rows (none when the box is that tall already) beyond the cut edge,
        filled there as the edge row shows (its mask pixels), and the fill is taken over the grown box.
    """
    h, w = mask.shape
    a = float(mask.sum())
    fill = a / float(h * w)
    if not (np.isfinite(min_h_px) and min_h_px > h):
        return fill
    e = int(np.ceil(min_h_px)) - h
    for on_edge, row in ((y0 <= 0, mask[0]), (y0 + h >= H, mask[-1])):
        if on_edge and row.sum() >= 0.5 * w:
            return max(fill, (a + e * float(row.sum())) / float((h + e) * w))
    return fill


def confidence_features(ctx: Context, feat: np.ndarray, B: np.ndarray, li: Light, n_group: int,
                        edge: float | None = None) -> dict:
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
            # the pane's bottom edge (the row below its last), m above the ground
            "bottom_m": float(ctx.height_above_ground(li.y0 + h, z)) if z is not None else float("nan"),
            # a pane the frame's top or bottom cuts: its fill judged beyond the frame (frame_cut_fill);
            # "fill_seen" as the box shows it (the proposer's first confidence read that)
            "fill": frame_cut_fill(li.mask, li.y0, ctx.shape[0], ctx.params.window_height_m[0]
                                   * float(ctx.intrinsics.fy) / z if z else float("nan")),
            "fill_seen": float(li.mask.sum()) / float(h * w),
            "edge": edge_contrast(feat, li.y0, li.x0, h, w, ctx.params, li.mask) if edge is None else edge,
            "n_group": float(n_group), "kind": li.kind or "window", "cut": bool(li.cut),
            "y0": li.y0, "x0": li.x0}


def window_features(ctx: Context, groups: list[Group], feat: np.ndarray, B: np.ndarray) -> list[list[dict]]:
    """:func:`confidence_features` of every window of ``groups`` (per group, per member) with its
    façade-grid support (:func:`grid_mates` over all the frame's windows) as ``row_mates``,
    ``col_mates`` and ``adjacent``."""
    edges = iter(edge_contrasts(feat, [li for g in groups for li in g.members], ctx.params))  # (all at once)
    out = [[confidence_features(ctx, feat, B, li, len(g.members), next(edges)) for li in g.members] for g in groups]
    flat = [x for xs in out for x in xs]
    boxes = np.array([[x["y0"], x["x0"], x["h_px"], x["w_px"]] for x in flat], float).reshape(-1, 4)
    row, col, adj = grid_mates(boxes, np.array([x["z_m"] for x in flat], float))
    near, touch = front_shares((ctx.labels != BUILDING) & (ctx.labels != SKY), boxes)
    for x, r, c, a, fn, ft in zip(flat, row, col, adj, near, touch):
        x.update(row_mates=int(r), col_mates=int(c), adjacent=int(a), front_near=float(fn), front_touch=float(ft))
    return out


def score_terms(conf: float, x: dict) -> list[float]:
    """The terms of :func:`window_confidence`'s logistic score, in ``window_conf_weights`` order (the
    fit tool, ``benchmarks.window_confidence.design``, reads the same): the first confidence, ring
    log-luminance and chroma contrasts (clipped at 3), height (m, clipped at 2.5; 1 without depth),
    ln pixels; the façade grid (tenth pass): ln(1 + row-mates), ln(1 + column-mates), touched by another
    window; the eleventh pass: fill of its box (clipped at 0.9), metres over ``TALL_M`` (clipped at 2),
    ground floor (bottom under ``GROUND_FLOOR_M``; 0 without depth), the share of things in front around
    it and on the ring of its box (:func:`front_shares`), the contrast of its box's weakest side
    (:func:`edge_contrast`, clipped at 3)."""
    h = x["h_m"] if np.isfinite(x["h_m"]) else 1.0
    hm = x["h_m"] if np.isfinite(x["h_m"]) else 0.0
    return [conf, min(x["ring_lum"], 3.0), min(x["ring_chroma"], 3.0), min(h, 2.5),
            float(np.log(max(x["area_px"], 1.0))),
            float(np.log1p(x["row_mates"])), float(np.log1p(x["col_mates"])), float(x["adjacent"] > 0),
            min(x["fill"], 0.9), min(max(hm - TALL_M, 0.0), 2.0),
            float(np.isfinite(x["bottom_m"]) and x["bottom_m"] < GROUND_FLOOR_M), x["front_near"], x["front_touch"],
            min(x.get("edge", 0.0), 3.0)]


def first_confidence(p, conf: float, x: dict) -> float:
    """The proposer's first confidence ``conf`` of a window with features ``x`` (:func:`window_features`),
    its fill term read on the fill :func:`frame_cut_fill` judges (``x["fill"]``) instead of its box's
    (``x["fill_seen"]``): ``windows.propose`` adds 0.25 x (fill - ``window_min_fill``) / (1 -
    ``window_min_fill``) (at most 0.25). Unchanged for a window the frame does not cut (docs/proposals.md
    "Twelfth pass: panes the frame cuts")."""
    if "fill_seen" not in x or x["fill"] == x["fill_seen"]:
        return conf

    def term(f):
        return min(1.0, (f - p.window_min_fill) / (1 - p.window_min_fill + 1e-6))
    out = float(np.clip(conf + 0.25 * (term(x["fill"]) - term(x["fill_seen"])), 0.0, 1.0))
    return min(out, p.window_tiny_max_confidence) if x["area_px"] < p.window_tiny_px else out


def window_confidence(p, conf: float, x: dict) -> float:
    """A window's final confidence from its first one ``conf`` and its features ``x``
    (:func:`window_features`; docs/proposals.md "Seventh pass", "Tenth pass", "Eleventh pass: the slider").

    The first confidence (fill, contrast to the wall reference, a floor of three) hardly told a
    true window from a false one (most false windows cover no true light at all: flecks of wall,
    balcony slabs, edges between wall colours). What does is how much the window differs from the
    wall right around it, how tall it is, and whether the façade grid backs it: like windows beside
    it on its floor (row-mates) and above or below it in its bay (column-mates), and no other window
    touching its box (a fragment). And where it is (eleventh pass): a mask that fills its box (a pane
    is a rectangle; a ragged blob is traced off), not over 2 m tall (a shop front, two panes run
    together), not on the ground floor (cars, people, signs and doors in front of and around its
    panes), among things in front of the wall (a tree hiding its mates: no mates is then no evidence
    against it) but not touched by one (a pane cut by a trunk or a post: one piece of a light). A
    logistic score ``window_conf_bias + window_conf_weights . score_terms(conf, x)``
    (:func:`score_terms`) mapped to 0.5 + 0.5 sigmoid(score). Only windows at least 0.5 confident are
    rescored, into [0.5, 1): the set kept at 0.5 does not change, only its order. A window of fewer
    than ``window_tiny_px`` pixels stays at most ``window_tiny_max_confidence``. Fewer weights leave the
    later terms out (5: the seventh pass's rule, 8: the tenth pass's). A pane the frame's top or bottom cuts
    has its first confidence's fill read beyond the frame first (:func:`first_confidence`, twelfth pass):
    the only windows that may cross 0.5 here.
    """
    conf = first_confidence(p, conf, x)
    wts = tuple(p.window_conf_weights)
    if conf < 0.5 or not any(wts):
        return conf
    v = score_terms(conf, x)
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
