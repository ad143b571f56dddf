"""Building windows: façade regions that differ from the local wall and are regular in floors
(docs/proposals.md)."""

from __future__ import annotations

import dataclasses
import warnings

import cv2
import numpy as np

from .ads import _union
from .core import Context, Group, Light, components, median, nanmedian, pixels

BUILDING, VEGETATION, SKY = 11, 21, 23
GROUND = (6, 7, 8, 9, 22)  # ground, road, sidewalk, parking, terrain
WINDOW_BUILDING, WINDOWS_GROUP = 1, 13
_Z8 = np.zeros(1, np.int8)  # a run's border for np.diff (np.concatenate: np.r_ costs ~10 us a call)


def _in_front(ctx: Context) -> np.ndarray:
    """HxW bool, read-only: pixels labelled neither building nor sky (something in front of a wall),
    once per context (two passes read it; the labels do not change during a proposal)."""
    front = ctx.__dict__.get("_window_front")
    if front is None:
        front = ~_in_labels(ctx.labels, (BUILDING, SKY))
        front.flags.writeable = False
        ctx.__dict__["_window_front"] = front
    return front


_LABEL_SETS: dict[tuple[int, ...], np.ndarray] = {}


def _in_labels(labels: np.ndarray, classes: tuple[int, ...]) -> np.ndarray:
    """``np.isin(labels, classes)`` for uint8 labelIds by a 256-entry lookup table (np.isin sorts or
    builds a table on every call: thousands of calls a frame on a blob's box)."""
    if labels.dtype != np.uint8:
        return np.isin(labels, classes)
    lut = _LABEL_SETS.get(classes)
    if lut is None:
        lut = np.zeros(256, bool)
        lut[list(classes)] = True
        _LABEL_SETS[classes] = lut
    return lut[labels]


def _masked_mean(val: np.ndarray, w: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Box-filtered mean of ``val`` weighted by ``w`` (k x k), and the weight's box mean."""
    num = cv2.blur(val * w, (k, k), borderType=cv2.BORDER_REPLICATE)
    den = cv2.blur(w, (k, k), borderType=cv2.BORDER_REPLICATE)
    return num / np.maximum(den, 1e-6), den


def wall_reference(feat: np.ndarray, building: np.ndarray, params) -> np.ndarray:
    """Local wall appearance (HxWxC float32) of features ``feat`` (HxWxC: log luminance, Lab a, b).

    Masked box means over building pixels that look like wall, at about 512 px wide: a coarse
    estimate (all building pixels, then those within the window thresholds of it), then a fine one
    over the pixels the coarse estimate calls wall; the coarse one stands where the fine box
    holds too little wall (``window_wall_min_share``).
    """
    H, W = building.shape
    f = max(1, W // 512)  # about 512 px wide: fast at 2048, no detail lost at 512
    h, w = max(1, H // f), max(1, W // f)
    small = cv2.resize(feat, (w, h), interpolation=cv2.INTER_AREA)
    wb = cv2.resize(building.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    wb = (wb > 0.99).astype(np.float32)
    C = feat.shape[2]

    def mean(mask: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        r = np.stack([_masked_mean(small[..., c], mask, k)[0] for c in range(C)], -1)
        return r, cv2.blur(mask, (k, k), borderType=cv2.BORDER_REPLICATE)

    def wall_like(ref: np.ndarray) -> np.ndarray:
        odd = _differs(small, ref, params)
        if params.window_wall_rim:
            odd = cv2.dilate(odd.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
        return wb * ~odd

    k_fine = max(3, int(round(params.window_wall_kernel_frac * W / f)) | 1)
    k_coarse = max(3, int(round(4 * params.window_wall_kernel_frac * W / f)) | 1)
    # Coarse first (panes are a minority of any large box), then fine over what the coarse estimate
    # calls wall, so a pane larger than the fine box cannot become its own reference.
    r0, _ = mean(wb, k_coarse)
    coarse, den_c = mean(wall_like(r0), k_coarse)
    fine, den_f = mean(wall_like(coarse), k_fine)
    ref = np.where((den_f > params.window_wall_min_share)[..., None], fine, coarse)
    if (den_c <= 1e-3).any():  # nothing nearby looks like wall: the building's overall median
        vals = small[wb > 0]
        ref[den_c <= 1e-3] = median(vals, axis=0) if len(vals) else 0.0
    return cv2.resize(ref, (W, H), interpolation=cv2.INTER_LINEAR)


def rereference_walls(feat: np.ndarray, walls: np.ndarray, cand: np.ndarray, ref: np.ndarray,
                      params, boxes: list | None = None) -> np.ndarray:
    """The wall reference (HxWxC, as :func:`wall_reference`) redone on walls it calls mostly not wall.

    The local box estimate mixes neighbouring walls: a narrow building of its own colour between
    two wider ones takes theirs, and then all of it "differs from the wall" (one blob over its
    whole facade, rejected as too large, and its panes are lost). A wall (``walls``: HxW int ids,
    :func:`facades`) of which more than ``window_rereference_share`` is candidate (``cand``) -- no
    facade is mostly panes; the lit cap is 40 % -- and whose colour (below) departs from the reference
    by the window thresholds gets its own reference: the mode of its log
    luminance (panes vary, the wall is one colour), its chroma the median of the pixels near that
    mode, refined by a box mean (``window_wall_kernel_frac``) over its pixels within the window
    thresholds of the mode, and over candidate pixels of that colour up to a quarter box beyond it
    (the wall pieces at a depth step are ragged); kept where the share of the wall that differs
    drops to ``window_rereference_keep`` of what it was or less (dense panes or glass can be the
    mode of a wall). Returns ``ref`` itself when no wall
    is redone.
    """
    share = float(params.window_rereference_share)
    if share >= 1.0:
        return ref
    from scipy import ndimage

    n = int(walls.max())
    if n == 0:
        return ref
    area = np.bincount(walls.ravel(), minlength=n + 1)
    odd = np.bincount(walls[cand], minlength=n + 1).astype(np.float64)  # counts: as the 0/1-weighted sums
    bad = np.flatnonzero((odd > share * np.maximum(area, 1)) & (area >= 64))
    bad = bad[bad > 0]
    if bad.size == 0:
        return ref
    t = -np.log(params.window_dark_ratio)
    H, W = walls.shape
    k = max(3, int(round(params.window_wall_kernel_frac * W)) | 1)
    out = None
    if boxes is None:  # (``boxes``: ndimage.find_objects(walls), when the caller has them)
        boxes = ndimage.find_objects(walls)
    pad = max(1, k // 4)  # the wall pieces at a depth step are ragged: its colour a few px beyond
    for w_id in bad.tolist():
        sl = boxes[w_id - 1]
        if sl is None:
            continue
        sl = (slice(max(0, sl[0].start - pad), min(H, sl[0].stop + pad)),
              slice(max(0, sl[1].start - pad), min(W, sl[1].stop + pad)))
        wm = walls[sl] == w_id
        f = feat[sl]
        lum = f[..., 0][wm]
        step = t / 4.0
        lo = float(lum.min())
        hist = np.bincount(((lum - lo) / step).astype(np.int64))
        hist = np.convolve(hist, [1, 2, 1], mode="same")
        mode = lo + (int(hist.argmax()) + 0.5) * step
        near = np.abs(lum - mode) < 0.5 * t
        ab = median(f[..., 1:][wm][near], axis=0)
        r0 = median(ref[sl][wm], axis=0)
        if abs(float(r0[0]) - mode) <= t and float(np.hypot(r0[1] - ab[0], r0[2] - ab[1])) <= params.window_chroma_delta:
            continue  # the wall's own colour is its reference: dense panes, not a wrong reference
        # its colour: on the wall, and next to it on candidate pixels of neighbouring pieces
        like = (wm | (cand[sl] & (walls[sl] > 0))) & (np.abs(f[..., 0] - mode) < t) & \
            (np.hypot(f[..., 1] - ab[0], f[..., 2] - ab[1]) < params.window_chroma_delta)
        wl = like.astype(np.float32)
        den = cv2.blur(wl, (k, k), borderType=cv2.BORDER_REPLICATE)
        base = np.array([mode, ab[0], ab[1]], np.float32)
        loc = np.stack([cv2.blur(f[..., c] * wl, (k, k), borderType=cv2.BORDER_REPLICATE) for c in range(3)], -1)
        loc = np.where((den > params.window_wall_min_share)[..., None], loc / np.maximum(den, 1e-6)[..., None], base)
        # kept only when it makes the wall clearly less "different" (where dense panes or glass are
        # the mode, both references leave about as much of it different)
        if _differs(f, loc, params)[wm].mean() > params.window_rereference_keep * odd[w_id] / area[w_id]:
            continue
        if out is None:
            out = ref.copy()
        o = out[sl]
        tgt = wm | like
        o[tgt] = loc[tgt]
    return ref if out is None else out


def _differs(feat: np.ndarray, ref: np.ndarray, params) -> np.ndarray:
    """Pixels whose luminance ratio or chromaticity departs from the wall reference."""
    t = -np.log(params.window_dark_ratio)
    d_lum = np.abs(feat[..., 0] - ref[..., 0])
    d_chroma = np.hypot(feat[..., 1] - ref[..., 1], feat[..., 2] - ref[..., 2])
    return (d_lum > t) | (d_chroma > params.window_chroma_delta)


def _robust_sigma(val: np.ndarray, ids: np.ndarray, n: int) -> np.ndarray:
    """1.4826 x the median absolute deviation of ``val`` per id 1..n of ``ids`` (0: none); index 0 unused."""
    out = np.zeros(n + 1, np.float64)
    order = np.argsort(ids, kind="stable")
    iv, vv = ids[order], val[order]
    cuts = np.searchsorted(iv, np.arange(n + 2))
    for i in range(1, n + 1):
        v = vv[cuts[i]:cuts[i + 1]]
        if v.size:
            out[i] = 1.4826 * float(median(np.abs(v - median(v))))
    return out


def _texture_walls(feat: np.ndarray, B: np.ndarray, params) -> tuple[np.ndarray, np.ndarray | None]:
    """Without depth: the building regions of strong texture (brick, stone), their features averaged.

    A region (connected building pixels, :func:`facades` without depth, of at least
    ``window_texture_min_share`` of the image) whose log luminance relative to its wall reference
    (:func:`wall_reference`) departs from its own 3x3 mean by a robust spread (1.4826 x the median
    absolute deviation) above ``window_texture_mad`` x the window threshold is textured: most of its
    pixels would differ from the wall and each brick course become a "window". There the features are
    averaged (box mean over building pixels) over the rows the texture repeats in
    (:func:`_texture_period`): a brick course repeats every few pixels, a pane is a cell of metres.
    Returns the features (``feat`` itself when no region is textured) and the textured pixels (HxW
    bool, None when none).
    """
    if params.window_texture_mad <= 0:
        return feat, None
    n, reg = cv2.connectedComponents(B.astype(np.uint8), connectivity=4)
    if n <= 1:
        return feat, None
    ref = wall_reference(feat, B, params)
    r = feat[..., 0] - ref[..., 0]
    w = B.astype(np.float32)
    # the texture: what departs from a 3x3 mean (a plain wall's pixels match their neighbours; a pane's
    # edges are a minority of its wall's pixels)
    hp = r - _masked_mean(r, w, 3)[0]
    s = max(1, int(np.sqrt(B.sum() / 20000.0)))  # a subsample of ~20 k pixels is enough for a spread
    sub = reg[::s, ::s]
    sel = sub > 0
    sig = _robust_sigma(hp[::s, ::s][sel], sub[sel], n - 1)
    t = -np.log(params.window_dark_ratio)
    area = np.bincount(reg.ravel(), minlength=n)
    # a small piece of building (a gable beside a tree, a wall strip between poles) is mostly edges
    bad = (sig > params.window_texture_mad * t) & (area >= params.window_texture_min_share * B.size)
    bad[0] = False
    if not bad.any():
        return feat, None
    tex = bad[reg]
    k = _texture_period(hp, tex, params)
    # the channels' masked means at once (one weight blur; OpenCV blurs each channel as alone)
    den = np.maximum(cv2.blur(w, (k, k), borderType=cv2.BORDER_REPLICATE), 1e-6)
    sm = cv2.blur(feat * w[..., None], (k, k), borderType=cv2.BORDER_REPLICATE) / den[..., None]
    return np.where(tex[..., None], sm, feat).astype(np.float32, copy=False), tex


def _texture_period(hp: np.ndarray, tex: np.ndarray, params) -> int:
    """The rows over which a textured wall repeats: the lag (2 .. ``window_texture_cell_px``) of the
    highest autocorrelation of its high-passed luminance ``hp`` down the columns of ``tex`` (brick
    courses repeat every few rows); ``window_texture_cell_px`` when nothing repeats (noise, plaster)."""
    kmax = max(2, int(params.window_texture_cell_px))
    v = np.where(tex, hp, 0.0)[:, ::2].astype(np.float64)
    c0 = float((v * v).sum())
    if c0 <= 0 or v.shape[0] <= kmax:
        return kmax
    corr = np.array([float((v[:-L] * v[L:]).sum()) / c0 for L in range(2, kmax + 1)])
    return int(np.argmax(corr)) + 2 if corr.max() > 0.2 else kmax


def _open2(m: np.ndarray) -> np.ndarray:
    """Morphological opening of ``m`` (HxW bool) by a 2x2 square, in place: OpenCV's MORPH_OPEN with
    an even kernel erodes and dilates about the same anchor, which moves the result one pixel right
    and down (every window proposed at 2048x1024 was: mask IoU 0.67-0.74 median, docs/proposals.md
    "Sixth pass"); the dilation here takes the reflected anchor."""
    k = np.ones((2, 2), np.uint8)
    return cv2.dilate(cv2.erode(m.astype(np.uint8), k, anchor=(0, 0)), k, anchor=(1, 1)).astype(bool)


def _features(ctx: Context) -> np.ndarray:
    """HxWx3 float32: log linear luminance, Lab a and b (OpenCV 8-bit Lab, centred)."""
    lab = cv2.cvtColor(ctx.image, cv2.COLOR_RGB2Lab).astype(np.float32)
    return np.dstack([np.log(np.maximum(ctx.lum, 1e-4)), lab[..., 1] - 128.0, lab[..., 2] - 128.0])


def _gap_split(m: np.ndarray, dev: np.ndarray, contrast: float,
               axis: int | None = None, min_len: int = 5) -> list[tuple[int, int, np.ndarray]]:
    """Cut a blob along its longer axis (``axis`` 0: across its columns, 1: across its rows, when
    given) where the wall shows through: the mean departure from the wall (``dev``, in window
    thresholds) over each column (row for a tall blob) dips below ``contrast`` times the lower of the
    peaks on either side; blobs shorter than ``min_len`` along that axis are not cut. Returns (y, x,
    mask) pieces, local."""
    h, w = m.shape
    if axis is None:
        axis = 0 if w >= h else 1                  # 0: profile over columns
    cnt = m.sum(axis)
    prof = np.where(cnt > 0, (dev * m).sum(axis) / np.maximum(cnt, 1), 0.0)
    n = prof.size
    if n < max(min_len, 3):
        return [(0, 0, m)]
    left = np.maximum.accumulate(prof)
    right = np.maximum.accumulate(prof[::-1])[::-1]
    gap = np.zeros(n, bool)
    for j in range(1, n - 1):
        if prof[j] <= prof[j - 1] and prof[j] <= prof[j + 1] and prof[j] < contrast * min(left[j - 1], right[j + 1]):
            gap[j] = True
    if not gap.any():
        return [(0, 0, m)]
    out = []
    d = np.diff(np.concatenate((_Z8, (~gap).astype(np.int8), _Z8)))
    for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
        sub = m[:, a:b] if axis == 0 else m[a:b, :]
        if not sub.any():
            continue
        ys, xs = np.nonzero(sub)
        piece = sub[ys.min():ys.max() + 1, xs.min():xs.max() + 1]
        out.append((int(ys.min()) + (0 if axis == 0 else int(a)), int(xs.min()) + (int(a) if axis == 0 else 0), piece))
    return out


def _extent_m(ctx: Context, y: int, x: int, m: np.ndarray) -> tuple[float, float] | None:
    """(Length in metres along its wall, median depth) of a blob (``m`` at (y, x)) from the depth across
    it: down a receding wall a blob's image width is foreshortened, its depth is not (a row of panes
    1 px wide each spans metres of depth). The depth per column is the median over the blob's pixels
    there; its slope the median of the pairwise slopes (Theil-Sen) over the columns without the
    outermost two (their depth bleeds into what stands beside the blob); the length is the distance
    between the 3-D points of the blob's first and last columns on that line. None without depth."""
    if ctx.depth is None:
        return None
    h, w = m.shape
    d = np.where(m, ctx.depth[y:y + h, x:x + w], np.nan)
    has = np.isfinite(d).any(0)
    cols = np.flatnonzero(has)
    if cols.size < 2:
        return None
    zc = nanmedian(d[:, cols], axis=0)
    z_med = float(nanmedian(d))
    ci, zi = (cols[1:-1], zc[1:-1]) if cols.size >= 5 else (cols, zc)
    i, j = _triu(ci.size)
    slope = float(median((zi[j] - zi[i]) / (ci[j] - ci[i])))
    K = ctx.intrinsics
    c0, c1 = float(cols[0]), float(cols[-1])
    mid = float(median(ci))
    z0 = z_med + slope * (c0 - mid)
    z1 = z_med + slope * (c1 - mid)
    p0 = ((x + c0 - K.cx) * z0 / K.fx, z0)
    p1 = ((x + c1 - K.cx) * z1 / K.fx, z1)
    return float(np.hypot(p1[0] - p0[0], p1[1] - p0[1])), z_med


def _row_split(m: np.ndarray, dev: np.ndarray, p, min_h: float) -> list[tuple[int, int, np.ndarray]]:
    """The panes of a receding row merged into one blob (``m``, local; ``dev``: departure from the
    wall in window thresholds): down a receding wall panes are 1-3 px wide a pixel apart, and a lit
    pane's blur makes the pixel of wall between them a candidate too, so the row is one blob -- on a
    wall of its own too few windows for the 1.5x rule to cut it (:func:`_split_oversized`), it covers
    its wall piece (docs/proposals.md "Ninth pass"). Cut across its columns where the departure dips
    below ``window_row_gap_contrast`` x the peaks beside (:func:`_gap_split`) when that gives at least
    ``window_row_min_panes`` pieces, each at most ``window_row_pane_max_px`` wide, ``min_h`` (a pane's
    least height) to ``window_row_pane_max_h_px`` rows tall and at most 2 px apart; else [] (a pane
    split by one mullion gives two pieces; a nearer pane shows its own frame, mullions and curtain
    as dips)."""
    c = float(p.window_row_gap_contrast)
    if c <= 0 or m.shape[1] < 3:
        return []
    pieces = _gap_split(m, dev, c, axis=0, min_len=3)
    if len(pieces) < p.window_row_min_panes:
        return []
    r = float(p.window_unblur_ratio)
    judged = []
    for py, px, pm in pieces:  # (one at a time: the first that is no far pane ends it)
        q = _faint_sides_off(py, px, pm, dev, r, 0) if p.window_row_trim_faint else (py, px, pm)
        if q[2].shape[1] > p.window_row_pane_max_px or not min_h <= q[2].shape[0] <= p.window_row_pane_max_h_px:
            return []  # not far panes: a pane taller than that shows its own frame and mullions as dips
        judged.append(q)
    # the wall between two such panes is a pixel or two: a wider dip is the inside of one pane (a
    # curtain, a dark middle between a light frame's sides)
    xs = sorted((px, px + pm.shape[1]) for _, px, pm in judged)
    if any(b[0] - a[1] > 2 for a, b in zip(xs, xs[1:])):
        return []
    if p.window_row_trim_faint:
        # one faint column a side stays for _unblur to take off after the grid: left free, the lattice
        # would propose a cell on that blur
        pieces = [_faint_sides_off(py, px, pm, dev, r, 1) for py, px, pm in pieces]
    return pieces


def _faint_sides_off(py: int, px: int, pm: np.ndarray, dev: np.ndarray, r: float,
                     keep: int = 0) -> tuple[int, int, np.ndarray]:
    """A piece (``pm`` at (py, px) in ``dev``'s frame; ``dev``: departure from the wall in window
    thresholds) without its edge columns whose mean departure is under ``r`` x its strongest column's,
    taken off from either side while they are, but for the ``keep`` nearest its strong columns on each
    side: what a pane's blur or a dark pane's dim glass adds to a lit 1-2 px pane beside it
    (docs/proposals.md "Fifteenth pass: windows at 512x256"). At least the strongest column stays."""
    h, w = pm.shape
    if w < 2 or r <= 0:
        return py, px, pm
    cnt = pm.sum(0)
    prof = np.where(cnt > 0, (dev[py:py + h, px:px + w] * pm).sum(0) / np.maximum(cnt, 1), 0.0)
    strong = np.flatnonzero(prof >= r * float(prof.max()))
    a, b = max(int(strong[0]) - keep, 0), min(int(strong[-1]) + keep, w - 1)
    if a == 0 and b == w - 1:
        return py, px, pm
    sub = pm[:, a:b + 1]
    ys = np.flatnonzero(sub.any(1))
    return py + int(ys[0]), px + a, sub[ys[0]:ys[-1] + 1]


def _unblur(li: Light, dev: np.ndarray, p) -> None:
    """Take off a narrow window's (at most ``window_row_pane_max_px`` wide) edge column that its pane's
    colour only bled into, in place: a pane 1 px wide shows in 2 (the render's and a camera's blur),
    the convex hull keeps both, and half the proposal is wall (mask IoU 0.5: an editor touch-up;
    docs/proposals.md "Ninth pass"). An edge column whose mean departure from the wall (``dev`` over
    the window's box, in window thresholds) is under ``window_unblur_ratio`` of the strongest
    column's goes, one a side. With ``window_unblur_any_width`` a wider window too: a pane's edge
    blurs a third of its colour into the wall's next column, which still passes the thresholds (at
    2048x1024 the commonest touch-up, a 4-8 px pane proposed 2 px wider; docs/proposals.md "Ninth
    pass: window masks")."""
    r = float(p.window_unblur_ratio)
    h, w = li.mask.shape
    if r <= 0 or w < 2 or (w > p.window_row_pane_max_px and not p.window_unblur_any_width):
        return
    cnt = li.mask.sum(0)
    prof = np.where(cnt > 0, (dev * li.mask).sum(0) / np.maximum(cnt, 1), 0.0)
    keep = np.ones(w, bool)
    for j in (0, w - 1):
        if prof[j] < r * float(prof.max()):
            keep[j] = False
    m = li.mask & keep[None, :]
    if keep.all() or not m.any():
        return
    ys, xs = np.nonzero(m)
    li.y0, li.x0 = li.y0 + int(ys.min()), li.x0 + int(xs.min())
    li.mask = m[ys.min():ys.max() + 1, xs.min():xs.max() + 1]


def _extend_ends(li: Light, dev: np.ndarray, free: np.ndarray, max_h: int, p) -> None:
    """Give a window the rows of its pane that its top or bottom left out, in place: a pane shows in
    parts that depart from the wall differently (a bright curtain band or reflection over glass of
    nearly the wall's colour), the thresholds find the strong part and the hull stops there, while an
    annotator draws the whole pane. A row above the top (below the bottom) joins when its mean
    departure from the wall (``dev``, HxW, in window thresholds) is at least ``window_extend_dev`` over
    two thirds of the window's columns (a pane's width, not a downpipe under it), and its mean over them
    ``window_extend_side_ratio`` x the mean of the columns just left and right of it (the pane is
    bounded by wall on both sides; a row of wall between two floors is not),
    all of it on ``free`` pixels (building, no other window); row by row, stopping at the first that
    fails, the window at most ``max_h`` rows tall. The new rows copy the columns of the end row."""
    a, k = float(p.window_extend_dev), float(p.window_extend_side_ratio)
    if a <= 0:
        return
    H, W = dev.shape
    h, w = li.mask.shape
    x0, x1 = li.x0, li.x0 + w  # columns [x0, x1)
    if x0 < 1 or x1 > W - 1:
        return  # no wall column on both sides to compare with

    def joins(y: int) -> bool:
        if y < 0 or y >= H or not free[y, x0:x1].all() or not free[y, x0 - 1] or not free[y, x1]:
            return False
        row = dev[y, x0:x1]
        side = 0.5 * float(dev[y, x0 - 1] + dev[y, x1])
        # across the pane's width, not a downpipe or a crack under it
        return (row >= a).mean() >= 2.0 / 3.0 and float(row.mean()) >= k * side

    top, bot = li.y0, li.y0 + h - 1
    up = 0
    while bot - (top - up - 1) + 1 <= max_h and joins(top - up - 1):
        up += 1
    down = 0
    while (bot + down + 1) - (top - up) + 1 <= max_h and joins(bot + down + 1):
        down += 1
    if not (up or down):
        return
    m = np.concatenate([np.repeat(li.mask[:1], up, 0), li.mask, np.repeat(li.mask[-1:], down, 0)], 0)
    li.y0 -= up
    li.mask = m


def _extend_sides(found: list, dev: np.ndarray, free: np.ndarray, p) -> None:
    """Give a thin window the columns of its pane that its sides left out, in place: on a wall that
    recedes, a pane a few pixels wide is often found by one column-wise part alone -- its frame's near
    or far side, or a sky-reflecting strip -- the rest of its glass departing from the wall by less than
    the thresholds (docs/proposals.md "Eleventh pass: a receding pane found as its strip"). Judged
    against its mates, the windows of the same wall (``found`` rows [wall id, level, tolerance, Light])
    on its floor (rows overlapping its own by ``window_side_overlap``) or in its column (sharing its
    left or right edge within a pixel): a window at most ``window_side_thin`` x the median width of its (up to four) nearest
    mates and at least ``window_side_tall`` x their median height (or twice their width) grows column by column, the stronger
    side first, while the next column departs from the wall (``dev``, HxW, in window thresholds) by a
    mean of ``window_extend_dev`` over the window's rows, by that much on half of them and under the
    thresholds, evenly (each column ``window_side_flat`` x the last taken, the first one the next
    beyond it: not the fading blur of a narrow pane into the wall), all on
    ``free`` pixels (building, no other window; updated), up to ``window_side_cap`` x the mates'
    median width; a window at least ``window_side_min_px`` wide. The new columns copy the rows of
    the end column."""
    thin, tall, ov = float(p.window_side_thin), float(p.window_side_tall), float(p.window_side_overlap)
    a, cap, flat = float(p.window_extend_dev), float(p.window_side_cap), float(p.window_side_flat)
    if thin <= 0 or a <= 0 or len(found) < 2:
        return
    H, W = dev.shape
    box = np.array([[f[3].y0, f[3].x0, f[3].mask.shape[0], f[3].mask.shape[1]] for f in found], float)
    bid = np.array([f[0] for f in found])
    lev = np.array([f[1] for f in found], float)
    idx = np.arange(len(found))
    for i, f in enumerate(found):
        li = f[3]
        y0, x0, h, w = (int(v) for v in box[i])
        if w < p.window_side_min_px:
            continue  # a 1-px pane is at the blur's scale: its own blur beside it looks like faint glass
        rows = np.minimum(box[:, 0] + box[:, 2], y0 + h) - np.maximum(box[:, 0], y0)
        cols = np.minimum(box[:, 1] + box[:, 3], x0 + w) - np.maximum(box[:, 1], x0)
        floor = (np.abs(lev - f[1]) <= f[2]) & (rows >= ov * np.minimum(box[:, 2], h))
        # a pane above or below counts when it shares the window's near or far edge: a strip is one side
        # of its pane, and the panes of a column of a facade line up
        edge = (np.abs(box[:, 1] - x0) <= 1) | (np.abs(box[:, 1] + box[:, 3] - (x0 + w)) <= 1)
        mate = (bid == f[0]) & (idx != i) & (floor | ((cols > 0) & edge))
        if not mate.any():
            continue
        j = np.nonzero(mate)[0]
        j = j[np.argsort(np.hypot(box[j, 1] + box[j, 3] / 2 - (x0 + w / 2), box[j, 0] + box[j, 2] / 2 - (y0 + h / 2)))[:4]]
        mw, mh = float(median(box[j, 3])), float(median(box[j, 2]))
        # as tall as its pane: as its mates, or at least twice their width (a column mate may be a
        # taller pane of another floor)
        if w > thin * mw or h < min(tall * mh, 2.0 * mw):
            continue

        def score(x: int) -> float:
            """Mean departure of column ``x`` over the window's rows when it is faint glass: at least
            ``a`` on half of them, under the thresholds on mean (a column over them would be in the
            window's blob already: it is a neighbour's edge or the blur of a pane's own); else -1."""
            if x < 0 or x >= W or not free[y0:y0 + h, x].all():
                return -1.0
            col = dev[y0:y0 + h, x]
            s_ = float(col.mean())
            return s_ if (col >= a).mean() >= 0.5 and s_ < 1.0 else -1.0

        def step(x: int, dx: int, prev: float | None) -> float:
            """Column ``x``'s score when it joins: glass departs from the wall evenly across the pane,
            while the blur of a narrow pane into the wall fades from one column to the next -- so the
            column beyond (the first step) or the last one taken keeps ``flat`` of it."""
            s_ = score(x)
            if s_ < a:
                return -1.0
            if prev is None:
                s2 = score(x + dx)
                return s_ if s2 >= flat * s_ else -1.0
            return s_ if s_ >= flat * prev else -1.0

        left = right = 0
        pl = pr_ = None
        while w + left + right + 1 <= cap * mw:
            sl, sr = step(x0 - left - 1, -1, pl), step(x0 + w + right, 1, pr_)
            if max(sl, sr) < a:
                break
            if sl >= sr:
                left, pl = left + 1, sl
            else:
                right, pr_ = right + 1, sr
        if not (left or right):
            continue
        m = np.concatenate([np.repeat(li.mask[:, :1], left, 1), li.mask, np.repeat(li.mask[:, -1:], right, 1)], 1)
        li.x0 -= left
        li.mask = m
        free[li.y0:li.y0 + h, li.x0:li.x0 + m.shape[1]] &= ~m
        box[i, 1], box[i, 3] = li.x0, m.shape[1]


def _join_across_occluders(ctx: Context, found: list, p, rescan: bool = False) -> list:
    """Join the two parts of a pane that something in front cuts in two, side by side: a pole, a sign's
    post, a trunk or a person across a pane leaves its glass either side, each part a blob and a window
    of its own, while an annotator outlines one pane, its visible parts (docs/proposals.md "Tenth pass:
    half-panes"). Two windows of one floor (``found`` rows ``[wall id, level, tol, Light]``; not one
    wall id: :func:`facades` cuts the wall at the post too), each at least 3 px wide, join when their
    rows overlap by ``window_join_min_overlap`` of the taller one's height, the columns between them --
    no wider than both parts together -- are covered by a label in front of the wall (not building or
    sky) over those rows from at most one column beside each part (the blur ``_unblur`` takes off): no
    wall shows between a part and the occluder, which two panes with their wall between would. With
    depth their median depths agree within 5 %, the joined box is no wider than a window
    (``window_height_m[1]``) nor ``window_join_max_width`` x the median width of its walls' other
    windows on that floor near its depth (a post over the wall between two whole panes); without,
    no wider than twice the wider part plus the gap. The joined mask is the union (the occluder's
    pixels stay out, as in an annotator's pane), its first confidence the larger one; repeated so a
    pane cut by two posts becomes one. Then the same one above the other: a lamp's arm, a sign or a
    wire across a pane (columns overlapping, rows between covered), the joined pane no taller than
    ``window_tall_keep_m`` with depth. Last (``window_join_sash``) two windows touching end to end with
    their left and right edges in line within a pixel, whatever lies between: a receding pane's
    sky-reflecting upper sash and its darker lower part (their boxes overlap on a slanted pane, their
    masks do not), the joined pane held to the same height caps and its floor's other panes' height.
    ``rescan``: redo every window's scan after each join (the same joins, slowly; for tests)."""
    ov = float(p.window_join_min_overlap)
    if ov <= 0 or len(found) < 2:
        return found
    fy = float(ctx.intrinsics.fy)
    front = _in_front(ctx)
    zc: dict[int, float | None] = {}  # median depth per window, until it is joined
    for ax in (1, 0):  # side by side (a post), then one above the other (an arm, a sign across)
        _join_pass(ctx, found, p, ax, ov, fy, front, zc, rescan=rescan)
    if p.window_join_sash:  # an upper sash over its lower part, touching
        _join_pass(ctx, found, p, 0, ov, fy, front, zc, sash=True, rescan=rescan)
    return found


def _join_pass(ctx: Context, found: list, p, ax: int, ov: float, fy: float, front: np.ndarray,
               zc: dict, sash: bool = False, rescan: bool = False) -> None:
    """The joins of :func:`_join_across_occluders` along image axis ``ax`` (1: columns, two parts side
    by side; 0: rows, one above the other; ``sash``: rows, touching, no occluder), in place, until none
    is left. Each join is the first pair, in the order of the windows along the axis, that passes the
    tests, as if the pairs were rescanned from the start after every join; but a window's scan (its
    pairs with the windows after it) is redone only when a join changed what it read -- the windows
    up to the first one too far away along the axis, and the widths of the walls whose other panes
    it compared with -- so a textured wall's thousand candidates are scanned about once, not once per
    join (docs/proposals.md "Eleventh pass: one pass over the occluder joins")."""
    co = 1 - ax  # the other axis
    found.sort(key=lambda f: (f[3].y0, f[3].x0)[ax])  # a join keeps the first part's key: stays sorted
    box = np.array([(f[3].y0, f[3].x0, f[3].y0 + f[3].mask.shape[0], f[3].x0 + f[3].mask.shape[1])
                    for f in found], np.int64).reshape(-1, 4)
    level = np.array([f[1] for f in found], float)
    tol = np.array([f[2] for f in found], float)
    z = [zc[id(f[3])] if id(f[3]) in zc else zc.setdefault(id(f[3]), _median_depth(ctx, f[3])) for f in found]
    zs = np.array([np.nan if v is None else v for v in z], float)
    wall = np.array([f[0] for f in found])
    n = len(found)
    dirty = np.ones(n, bool)  # the window's scan is to be (re)done
    reach = np.zeros(n, np.int64)  # the last window its scan read
    walls_read: dict[int, set] = {}  # id of a window's Light -> walls whose panes its scan compared with, if any

    def box_ok(i, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The box tests of windows ``i`` (one, or one per ``J``) and ``J`` after them: which pass, and
        their gaps along the axis."""
        ext_i, ext_j = box[i, 2 + ax] - box[i, ax], box[J, 2 + ax] - box[J, ax]  # along the join
        gap = box[J, ax] - box[i, 2 + ax]
        small = np.minimum(ext_i, ext_j)
        # side by side on one floor (a post in front splits the wall plane too: facades() cuts
        # at it, so not one wall id); apart along the axis (a sash's parts on a slanted receding
        # pane: boxes overlapping, masks not)
        ok = gap >= (-0.5 * small if sash else 1)
        if ax == 1:
            ok &= np.abs(level[i] - level[J]) <= tol[i]
        if sash:
            ok &= (gap <= 1) & (np.abs(box[i, 1] - box[J, 1]) <= 1) & (np.abs(box[i, 3] - box[J, 3]) <= 1) \
                & (np.minimum(box[i, 3] - box[i, 1], box[J, 3] - box[J, 1]) >= 2)
        # a 1-2 px part beside a post (its blur, or a far pane of its own); a post hiding more of the
        # pane than shows of it: two panes with the post on the wall between
        ok &= (small >= 3) & (gap <= ext_i + ext_j)
        ok &= np.minimum(box[i, 2 + co], box[J, 2 + co]) - np.maximum(box[i, co], box[J, co]) \
            >= ov * np.maximum(box[i, 2 + co] - box[i, co], box[J, 2 + co] - box[J, co])
        return ok, gap

    def scan(i: int) -> int | None:
        """The first window after ``i`` that joins it; records what the scan read."""
        read: set = set()
        walls_read.pop(id(found[i][3]), None)
        # the windows after i up to the first one too far away along the axis (sorted: every later
        # one is farther), looked for in chunks doubling in size
        ext_i, lo, step, end = box[i, 2 + ax] - box[i, ax], i + 1, 64, n
        while lo < n:
            hi = min(n, lo + step)
            far = np.flatnonzero(box[lo:hi, ax] - box[i, 2 + ax]
                                 > 2 * np.maximum(ext_i, box[lo:hi, 2 + ax] - box[lo:hi, ax]) + 8)
            if far.size:
                end = lo + int(far[0])
                break
            lo, step = hi, 2 * step
        reach[i] = min(end, n - 1)
        J = np.arange(i + 1, end)
        ok, gap = box_ok(i, J)
        for j, g in zip(J[ok].tolist(), gap[ok].tolist()):
            a0, a1 = max(box[i, co], box[j, co]), min(box[i, 2 + co], box[j, 2 + co])
            sl = [slice(a0, a1), slice(a0, a1)]
            sl[ax] = slice(box[i, 2 + ax], box[j, ax])
            if not sash:
                cover = front[tuple(sl)].mean(co) >= 0.9
                c = np.flatnonzero(cover)
                if c.size == 0 or c[0] > 1 or c[-1] < cover.size - 2 or not cover[c[0]:c[-1] + 1].all():
                    continue  # wall shows between a part and the occluder: two panes
            span = (max(box[i, 2], box[j, 2]) - min(box[i, 0], box[j, 0]),
                    max(box[i, 3], box[j, 3]) - min(box[i, 1], box[j, 1]))[ax]
            if z[i] is not None and z[j] is not None:
                zm = max(z[i], z[j])
                # the joined pane no taller than a pane without floors (window_tall_keep_m), no wider
                # than a window
                cap = p.window_height_m[1] if ax == 1 or p.window_tall_keep_m <= 0 else p.window_tall_keep_m
                if span * zm / fy > cap:
                    continue
                if abs(z[i] - z[j]) > 0.05 * zm:
                    # a post between them pulls the glass next to it towards its own depth: compare
                    # the wall on the parts' far sides
                    zi = _wall_beyond(ctx, found[i][3], ax, False) if p.window_join_facing and not sash else None
                    zj = _wall_beyond(ctx, found[j][3], ax, True) if zi is not None else None
                    if zj is None or abs(zi - zj) > 0.05 * max(zi, zj):
                        continue
                if ax == 1 or sash:
                    # two whole panes with a post over the wall between them: the joined box would be
                    # wider than its wall's other panes on the floor near that depth
                    read.update((wall[i].item(), wall[j].item()))
                    mates = np.isin(wall, (wall[i], wall[j])) & (np.abs(level - level[i]) <= tol[i]) \
                        & (np.abs(zs - z[i]) <= 0.15 * z[i])
                    mates[[i, j]] = False
                    ext = box[mates, 2 + ax] - box[mates, ax]
                    if ext.size >= 2 and span > p.window_join_max_width * median(ext):
                        continue
            elif span > 2 * max(box[i, 2 + ax] - box[i, ax], box[j, 2 + ax] - box[j, ax]) + g:
                continue
            break
        else:
            j = None
        if read:
            walls_read[id(found[i][3])] = read
        return j

    i = 0
    while i < n:
        if not dirty[i]:
            i += 1
            continue
        dirty[i] = False
        j = scan(i)
        if j is None:
            i += 1
            continue
        a, b = found[i][3], found[j][3]
        y0, x0 = box[[i, j], 0].min(), box[[i, j], 1].min()
        y1, x1 = box[[i, j], 2].max(), box[[i, j], 3].max()
        m = np.zeros((y1 - y0, x1 - x0), bool)
        m[a.y0 - y0:a.y0 - y0 + a.mask.shape[0], a.x0 - x0:a.x0 - x0 + a.mask.shape[1]] |= a.mask
        m[b.y0 - y0:b.y0 - y0 + b.mask.shape[0], b.x0 - x0:b.x0 - x0 + b.mask.shape[1]] |= b.mask
        a.y0, a.x0, a.mask = int(y0), int(x0), m
        a.confidence = max(a.confidence, b.confidence)
        a.cut = a.cut and b.cut
        zc.pop(id(a), None)
        if ax == 0 and z[i] is not None:
            found[i][1] = fl_level(ctx, a)
        else:
            found[i][1] = 0.5 * (found[i][1] + found[j][1])
        # what changed: window i (box, level, depth) and j (gone). Redo the scans that stopped at
        # either (the first one too far away: i may no longer be, j is gone), those before i that
        # read it and whose box tests it now passes (it failed the others before, or they would have
        # joined it), and those that compared with the panes of their walls; j failed every scan
        # that read it, so its going changes no other
        idx = np.arange(n)
        hit = {wall[i].item(), wall[j].item()}
        box[i] = (y0, x0, y1, x1)
        level[i] = found[i][1]
        redo = ((idx < i) & (reach == i)) | ((idx < j) & (reach == j))
        before = np.flatnonzero((idx < i) & (reach > i))
        if before.size:
            redo[before[box_ok(before, np.full(before.size, i))[0]]] = True
        if any(r & hit for r in walls_read.values()):
            redo |= np.array([bool(walls_read.get(id(f[3]), set()) & hit) for f in found])
        redo[i] = True
        if rescan:
            redo[:] = True
        walls_read.pop(id(b), None)
        del found[j]
        z[i] = zc.setdefault(id(a), _median_depth(ctx, a))
        zs[i] = np.nan if z[i] is None else z[i]
        del z[j]
        box, level, tol, zs, wall = (np.delete(v, j, 0) for v in (box, level, tol, zs, wall))
        dirty = np.delete(dirty | redo, j)
        reach = np.delete(np.where(reach > j, reach - 1, reach), j)
        n -= 1
        i = int(np.argmax(dirty))  # the first scan to redo (i's own at the latest)


def _occupancy_split(m: np.ndarray, gap: float) -> list[tuple[int, int, np.ndarray]]:
    """Cut a blob where a run of its columns (then rows) is nearly empty -- under ``gap`` of the
    blob's height (width) -- with fuller columns (rows, over twice that) on both sides: the wall
    between two panes that a frame, a sill line or a car's roof joins into one blob, which the convex
    hull would fill into one window over both. Returns (y, x, mask) pieces, local; one when uncut."""
    if gap <= 0:
        return [(0, 0, m)]
    for axis in (0, 1):  # 0: columns
        occ = m.mean(axis)
        n = occ.size
        if n < 5:
            continue
        low = occ < gap
        full = occ >= 2 * gap
        left = np.maximum.accumulate(full)
        right = np.maximum.accumulate(full[::-1])[::-1]
        cut = low & left & right
        if not cut.any():
            continue
        out = []
        keep = ~cut
        d = np.diff(np.concatenate((_Z8, keep.astype(np.int8), _Z8)))
        for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)):
            sub = m[:, a:b] if axis == 0 else m[a:b, :]
            if not sub.any():
                continue
            # (each part cut out by its box: a textured blob's run holds dozens of parts)
            _, lab, st, _ = cv2.connectedComponentsWithStats(sub.astype(np.uint8), connectivity=4)
            for c, (ox, oy, cw, ch) in enumerate(st[1:, :4].tolist(), 1):
                piece = lab[oy:oy + ch, ox:ox + cw] == c
                out.append((oy + (0 if axis == 0 else int(a)), ox + (int(a) if axis == 0 else 0), piece))
        if len(out) > 1:
            return out
    return [(0, 0, m)]


def _band_split(m: np.ndarray, share: float, min_area: int,
                max_ratio: float = 4.0) -> list[tuple[int, int, np.ndarray]]:
    """The parts of a blob too large or ragged for one window (``m``) below (above) the rows at its top
    (bottom) that it fills across -- at least ``share`` of its width each, a band: a fascia, a cornice or a
    lintel strip of another shade than the wall reference, with a floor's panes hanging from it (the 512x256
    streets' facing facades at 100-125 m; docs/proposals.md "Eighteenth pass: windows at 512x256"): the
    4-connected components of what is left (``min_area`` pixels at least), as (y, x, mask), local; none
    unless there are two at least, within ``max_ratio`` of each other in area
    (``window_band_part_ratio``) (no band, one pane
    under it, or flecks beside a wedge of wall: the blob's other tests judge it)."""
    if m.shape[1] < 5 or share <= 0:
        return []
    full = m.mean(1) >= share
    if full.all():
        return []
    top, bot = int(np.argmin(full)), int(np.argmin(full[::-1]))
    if not (top or bot):
        return []
    rest = m[top:m.shape[0] - bot]
    parts = [(top + py, px, pm) for py, px, pm, _ in components(rest, min_area, connectivity=4)]
    if len(parts) < 2:
        return []
    # a floor's panes are alike in size (the streets' splits: parts within 2.1x of each other): parts of
    # unlike sizes are no row of panes but a wedge of wall or shade the band ran over beside a pane's
    # flecks (a ground floor under a shop sign on a real-layout frame: 122 px beside 4 and 6)
    areas = [int(pm.sum()) for _, _, pm in parts]
    return parts if max_ratio <= 0 or max(areas) <= max_ratio * min(areas) else []


def _stands_out(feat: np.ndarray, B: np.ndarray, y: int, x: int, sub: np.ndarray, p) -> bool:
    """Whether a blob differs from the building pixels in a ring ``window_ring_px`` wide around it by
    at least half the window thresholds (log luminance or Lab chroma). The wall reference is a
    smoothed estimate; at the edge between two wall colours (a gable of other brick, a plinth) it
    calls a strip of plain wall different, but the ring around that strip is the same wall."""
    d = _ring_contrast(feat, B, y, x, sub, p.window_ring_px, p)
    return d is None or bool(max(d) > 0.5)


def _ring_contrast(feat: np.ndarray, B: np.ndarray, y: int, x: int, sub: np.ndarray, r: int,
                   p) -> tuple[float, float] | None:
    """How much a blob (``sub`` at (y, x)) differs from the building pixels (``B``) in a ring ``r`` px
    wide around it: the medians' log-luminance difference over the window threshold
    (-ln ``window_dark_ratio``) and their Lab chroma distance over ``window_chroma_delta`` (1: as
    different as a window pixel must be from the wall reference); None when the ring holds fewer
    than 3 building pixels."""
    H, W = B.shape
    h, w = sub.shape
    ya, yb, xa, xb = max(0, y - r), min(H, y + h + r), max(0, x - r), min(W, x + w + r)
    blob = np.zeros((yb - ya, xb - xa), np.uint8)
    blob[y - ya:y - ya + h, x - xa:x - xa + w] = sub
    ring = (cv2.dilate(blob, np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0) & (blob == 0) & B[ya:yb, xa:xb]
    if ring.sum() < 3 or not blob.any():
        return None
    f = feat[ya:yb, xa:xb]
    inner, outer = median(pixels(f, blob > 0), axis=0), median(pixels(f, ring), axis=0)
    t = -np.log(p.window_dark_ratio)
    return (abs(float(inner[0] - outer[0])) / t,
            float(np.hypot(inner[1] - outer[1], inner[2] - outer[2])) / p.window_chroma_delta)


def _hull_fill(m: np.ndarray) -> float:
    """The share of a blob's box (``m``, local bool) that its convex hull fills (a pane's rectangle: 1;
    its interior may match a reference the glass pulled, the hull fills it as :func:`propose` does)."""
    if min(m.shape) < 2:
        return 1.0
    hull = cv2.convexHull(cv2.findNonZero(m.astype(np.uint8)))
    filled = np.zeros(m.shape, np.uint8)
    cv2.fillConvexPoly(filled, hull, 1)
    return float(filled.mean())


def _on_ground_floor(ctx: Context, y: int, x: int, m: np.ndarray) -> bool:
    """Whether a blob (``m`` at (y, x)) reaches into the ground floor: its bottom row at most
    ``window_shop_max_top_m`` above the ground at its median depth (False without depth)."""
    d = ctx.depths_in(y, y + m.shape[0], x, x + m.shape[1], m)
    if d is None:
        return False
    return float(ctx.height_above_ground(y + m.shape[0] - 0.5, float(median(d)))) <= ctx.params.window_shop_max_top_m


def _fill_holes(m: np.ndarray) -> np.ndarray:
    """``scipy.ndimage.binary_fill_holes(m)`` (2-D bool; holes: background not 4-connected to the border),
    the same mask by one flood fill from a 1-px frame around it (scipy's dilates until nothing changes:
    ~20x slower on a shop front's blob)."""
    h, w = m.shape
    bg = np.ones((h + 2, w + 2), np.uint8)
    bg[1:-1, 1:-1] = ~m
    cv2.floodFill(bg, None, (0, 0), 2, flags=4)
    return bg[1:-1, 1:-1] != 2


def _hypot_le(a: np.ndarray, b: np.ndarray, d: float) -> np.ndarray:
    """``np.hypot(a, b) <= d``, the same bools, by the square sum (hypot costs ~12 ns an element): a
    square sum within 1e-5 of ``d``'s square either way is decided by hypot itself, as before (the
    square sum's rounding is ~1e-7 of it)."""
    s = np.square(a)
    s += np.square(b)
    out = s <= (d * (1 - 1e-5)) ** 2
    near = ~out & (s < (d * (1 + 1e-5)) ** 2)
    if near.any():
        out[near] = np.hypot(a[near], b[near]) <= d
    return out


def _alike_counts(bu: np.ndarray, ru: np.ndarray, cnt: np.ndarray, t: float, d: float) -> np.ndarray:
    """For each colour (row: log luminance, Lab a, b) of ``bu``: the sum of ``cnt`` over the colours of
    ``ru`` within ``t`` in log luminance and ``d`` in chroma (``(np.abs(dl) <= t) & (np.hypot(da, db)
    <= d)`` per pair, the same sums). A textured wall's blob holds thousands of distinct colours
    against its ring's 256 (docs/proposals.md "Twenty-first pass: the textured street's time"): both
    sorted by luminance, a block of the blob's is compared only with the ring's within ``t`` (and a
    hair) of the block's range, about a third of the pairs."""
    o = np.argsort(ru[:, 0], kind="stable")
    rl, ra, rb = (np.ascontiguousarray(ru[o, k]) for k in range(3))
    # the sums by a float32 product: counts of at most 2^24 add exactly
    cf = cnt[o].astype(np.float32)
    assert cf.sum() < 2 ** 24
    r64 = rl.astype(np.float64)
    ob = np.argsort(bu[:, 0], kind="stable")
    bl, ba, bb = (np.ascontiguousarray(bu[ob, k]) for k in range(3))
    out = np.zeros(len(bu), cnt.dtype)
    step = 256
    for i in range(0, len(bl), step):
        j = min(i + step, len(bl))
        lo = int(np.searchsorted(r64, float(bl[i]) - t - 1e-3, "left"))
        hi = int(np.searchsorted(r64, float(bl[j - 1]) + t + 1e-3, "right"))
        if hi <= lo:
            continue
        same = np.abs(bl[i:j, None] - rl[None, lo:hi]) <= t
        same &= _hypot_le(ba[i:j, None] - ra[None, lo:hi], bb[i:j, None] - rb[None, lo:hi], d)
        out[ob[i:j]] = same.astype(np.float32) @ cf[lo:hi]
    return out


def _row_groups(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct rows of an (n, 3) float32 array (compared bitwise: a -0.0 and a 0.0 stay apart), each row's
    index among them and their counts, by one sort of integer keys (numpy's unique over 12-byte rows
    compares them one by one). Their order is the keys' (not ``np.unique``'s): for a test per row."""
    u = np.ascontiguousarray(a).view(np.uint32)
    hi = (u[:, 0].astype(np.uint64) << np.uint64(32)) | u[:, 1]
    o = np.lexsort((u[:, 2], hi))
    hi, lo = hi[o], u[o, 2]
    new = np.empty(o.size, bool)
    new[:1] = True
    new[1:] = (hi[1:] != hi[:-1]) | (lo[1:] != lo[:-1])
    inv = np.empty(o.size, np.intp)
    inv[o] = np.cumsum(new) - 1
    first = np.flatnonzero(new)
    return a[o[first]], inv, np.diff(np.append(first, o.size))


def _wall_coloured(feat: np.ndarray, B: np.ndarray, y: int, x: int, m: np.ndarray, p,
                   r: int = 3, like: float = 0.1) -> np.ndarray:
    """Pixels of a blob (``m``, local bool, at (y, x)) that have the colour of the wall around it: within
    the window thresholds (log luminance and Lab chroma, :func:`_differs`) of at least ``like`` of the
    building pixels (``B``) in a ring from 2 to ``r`` px around the blob (the pixel right beside it is
    its blurred edge). The smooth wall reference (:func:`wall_reference`) averages a wall's colours and
    its glass; a blob departing from it can hold, besides the glass, a strip of the very wall beside it
    (an awning or a fascia above a shop front, a pier, a pane's wall-coloured reveal). Local bool mask
    of ``m``'s shape; none where the ring holds fewer than 8 building pixels."""
    H, W = B.shape
    h, w = m.shape
    ya, yb, xa, xb = max(0, y - r), min(H, y + h + r), max(0, x - r), min(W, x + w + r)
    blob = np.zeros((yb - ya, xb - xa), np.uint8)
    # around its outline: glass inside it that matches the reference (its holes) is no wall around it
    blob[y - ya:y - ya + h, x - xa:x - xa + w] = _fill_holes(m)
    ring = (cv2.dilate(blob, np.ones((2 * r + 1, 2 * r + 1), np.uint8)) > 0) \
        & ~(cv2.dilate(blob, np.ones((3, 3), np.uint8)) > 0) & B[ya:yb, xa:xb]
    out = np.zeros(m.shape, bool)
    if ring.sum() < 8:
        return out
    rs = pixels(feat[ya:yb, xa:xb], ring)
    if len(rs) > 256:  # a sample of the ring is enough to say which colours it has
        rs = rs[np.linspace(0, len(rs) - 1, 256).astype(np.int64)]
    bf = pixels(feat[y:y + h, x:x + w], m)
    t = -np.log(p.window_dark_ratio)
    # features come from 8-bit colours: a blob and its ring hold few distinct ones, so each distinct
    # pair is compared once (the share of ring samples alike: a count over the same total)
    bu, inv, _ = _row_groups(bf)
    ru, _, cnt = _row_groups(rs)
    out[m] = (_alike_counts(bu, ru, cnt, t, p.window_chroma_delta) / len(rs))[inv.ravel()] >= like
    return out


def _blob_panes(feat: np.ndarray, y: int, x: int, m: np.ndarray, p,
                colour: list | None = None) -> list[tuple[int, int, np.ndarray]]:
    """The panes inside a blob (``m`` at (y, x)) that is mostly wall: a wall piece whose colour the
    smooth wall reference missed (a narrow building of its own colour, a shaded face) is one blob
    with its panes, too large for a window. The blob's own wall colour is the mode of its log
    luminance (the chroma of the pixels near it); when at least ``window_blob_wall_share`` of the
    blob is within the window thresholds of that colour, the blob's pixels that differ from it are
    the candidates (their 4-connected components, local (y, x, mask); each is then judged as any
    blob); else, where a second colour of wall lies on the piece (:func:`_shadow_colour`: a cast
    shadow), the pixels that differ from both when the two fill that share, two parts at least and
    ``window_blob_second_pane_share`` of the blob; else none (no colour fills that much of it: panes
    of several colours merged). ``colour``: when given and panes are found, the blob's own wall colour
    (log luminance, Lab a, b) is appended to it (the first colour's, with a shadow's too)."""
    h, w = m.shape
    if m.sum() < 8 * p.window_min_area_px:
        return []
    f = feat[y:y + h, x:x + w]
    lum = f[..., 0][m]
    t = -np.log(p.window_dark_ratio)
    # bins as wide as the "near the mode" window below: a wall's shading along a receding face spreads
    # its luminance over several quarter-threshold bins, none of which then holds its mode
    step = float(p.window_blob_mode_step) * t
    lo = float(lum.min())
    hist = np.convolve(np.bincount(((lum - lo) / step).astype(np.int64)), [1, 2, 1], mode="same")
    mode = lo + (int(hist.argmax()) + 0.5) * step
    near = np.abs(lum - mode) < 0.5 * t
    if not near.any():
        return []  # the smoothed mode fell between two colours, neither near it
    ab = median(f[..., 1:][m][near], axis=0)
    base = np.array([mode, ab[0], ab[1]], np.float32)
    odd = _differs(f, np.broadcast_to(base, f.shape), p) & m
    if (m & ~odd).sum() >= p.window_blob_wall_share * m.sum():
        parts = [(py, px, pm) for py, px, pm, _ in components(odd, p.window_min_area_px, connectivity=4)]
        if colour is not None and parts:
            colour.append(base)
        return parts
    base2 = _shadow_colour(f, m, lum, hist, lo, step, mode, ab, p)
    if base2 is None:
        return []
    odd &= _differs(f, np.broadcast_to(base2, f.shape), p)
    if (m & ~odd).sum() < p.window_blob_wall_share * m.sum():
        return []
    parts = [(py, px, pm) for py, px, pm, _ in components(odd, p.window_min_area_px, connectivity=4)]
    if len(parts) < 2 or sum(int(pm.sum()) for _, _, pm in parts) < p.window_blob_second_pane_share * m.sum():
        return []  # a few flecks: the two colours were the panes' and the wall's (a lit street's panes)
    if colour is not None:
        colour.append(base)
    return parts


def _panes_side_by_side(ctx: Context, feat: np.ndarray, y: int, x: int, m: np.ndarray,
                        p, colour: list | None = None) -> list[tuple[int, int, np.ndarray]]:
    """The panes of a blob kept as one window (``m`` at (y, x)) that is a row of them on a face of its own
    colour: a narrow sunlit face the wall reference missed is candidate all over, so its panes and the
    face between them pass as one window (512x256 default street seed 1: four 1-2 px panes at 80-90 m in
    one 8 x 9 px window; docs/proposals.md "Nineteenth pass: windows at 512x256"). The parts of it that
    differ from its own colour (:func:`_blob_panes`), when at least ``window_blob_row_min_panes`` of them
    are far panes, each at least half its height and at most ``window_row_pane_max_px`` wide, on a blob
    that spans at least ``window_row_min_m_per_px`` of wall per pixel column (:func:`_extent_m`: a far
    receding row; a single framed pane leaves two sides of its frame, a pane with a curtain or a
    reflection band one part, a near window's lights between its mullions and stripes of its reflection
    span a few centimetres a pixel); else []. ``colour``: as :func:`_blob_panes`'s, when the parts are returned."""
    n = int(p.window_blob_row_min_panes)
    if n <= 0 or m.shape[1] < n or m.sum() < 8 * p.window_min_area_px:
        return []
    ext = _extent_m(ctx, y, x, m)
    if ext is None or ext[0] < p.window_row_min_m_per_px * (m.shape[1] - 1):
        return []  # not a far receding row: a near window's lights between its mullions, its frame
    got: list = []
    parts = _blob_panes(feat, y, x, m, p, got)
    if sum(pm.shape[0] >= 0.5 * m.shape[0] and pm.shape[1] <= p.window_row_pane_max_px for _, _, pm in parts) < n:
        return []
    if colour is not None:
        colour.extend(got)
    return parts


def _shadow_colour(f: np.ndarray, m: np.ndarray, lum: np.ndarray, hist: np.ndarray, lo: float, step: float,
                   mode: float, ab: np.ndarray, p) -> np.ndarray | None:
    """A second colour of wall on a blob (``m``; ``f`` its features, ``lum`` its log luminance, ``hist``
    the smoothed histogram :func:`_blob_panes` took its ``mode`` from, bins ``step`` wide from ``lo``,
    ``ab`` the mode's chroma): a cast shadow over a sunlit piece (or sun over a shaded one) -- the
    fullest bin a window threshold or more darker (else lighter) than the mode, holding at least
    ``window_blob_second_share`` of the blob near it, of the wall's hue (its chroma within
    ``window_chroma_delta`` of the mode's: dark glass or a sign is no shadow). (log luminance, a, b) or
    None (``window_blob_second_share`` 0: never)."""
    share = float(p.window_blob_second_share)
    if share <= 0:
        return None
    t = -np.log(p.window_dark_ratio)
    bins = lo + (np.arange(hist.size) + 0.5) * step
    for side in (bins <= mode - t, bins >= mode + t):
        if not (side & (hist > 0)).any():
            continue
        c = float(bins[int(np.where(side, hist, -1).argmax())])
        near = np.abs(lum - c) < 0.5 * t
        if near.sum() < share * m.sum():
            continue
        ab2 = median(f[..., 1:][m][near], axis=0)
        if float(np.hypot(*(ab2 - ab))) < p.window_chroma_delta:
            return np.array([c, ab2[0], ab2[1]], np.float32)
    return None


def _ledge_split(depth: np.ndarray | None, labels: np.ndarray, fy: float, y: int, x: int, m: np.ndarray,
                 p) -> list[tuple[int, int, np.ndarray]]:
    """A candidate blob (``m`` at (y, x)) without what juts out of the wall: awnings, balcony slabs
    and their shaded undersides are building-labelled and dark like glass, but nearer than the wall
    (a pane is flush with it or recessed). On a vertical wall the depth along an image column is
    constant, so the wall's depth in a column is read 2 px above the blob's top and below its bottom
    there, linearly between the two down the column (columns with anything but building or ground on
    either side are not judged, nor reads and blob pixels within ``window_ledge_bleed_frac`` of the
    image width of anything in front, when that is over 2 px: a tree, a pole, a car -- the depth map
    bleeds their depth over that width, which reads nearer than the wall). Blob pixels nearer
    than that by ``window_ledge_step_m`` (and ``window_ledge_rel`` x depth) are a ledge: dropped, and
    the rest's 4-connected components returned (local (y, x, mask)); a blob mostly ledge and lower
    than ``window_ledge_keep_m`` is dropped whole (a dormer's pane stands in front of its roof, but
    is a pane's height). The blob unchanged when nothing is nearer or no depth is given."""
    if depth is None or p.window_ledge_step_m <= 0:
        return [(0, 0, m)]
    H, W = labels.shape
    h, w = m.shape
    has = m.any(0)
    if not has.any():
        return [(0, 0, m)]
    cols = x + np.arange(w)
    top = y + np.argmax(m, axis=0) - 2
    bot = y + h - 1 - np.argmax(m[::-1], axis=0) + 2
    b = int(p.window_ledge_bleed_frac * W)  # the bleed's width (below)
    d = depth[y:y + h, x:x + w]

    def nearer(bleed: np.ndarray | None) -> np.ndarray | None:
        """The blob's pixels nearer than the wall (None: no column judged), reads within ``bleed``
        (local, at (y - b, x - b)) not taken."""
        sides = []
        for rows in (top, bot):
            ok = has & (rows >= 0) & (rows < H)
            v = np.full(w, np.nan)
            v[ok] = np.where(_in_labels(labels[rows[ok], cols[ok]], (BUILDING,) + GROUND), depth[rows[ok], cols[ok]],
                             np.nan)
            if bleed is not None:
                v[ok & bleed[np.clip(rows - y + b, 0, h + 2 * b - 1), np.arange(w) + b]] = np.nan
            sides.append(v)
        # Judged only in columns with wall (or the ground at its foot) on both sides: beside a car, a
        # pole or the frame the edge pixels mix the depths of both and look nearer.
        seen = np.isfinite(sides[0]) & np.isfinite(sides[1])
        if not seen.any():
            return None
        # the wall between the two readings, row by row: a pitched camera's column is not vertical, and a
        # steeply receding wall's depth then changes down the column
        frac = (np.arange(h)[:, None] + y - top[None, :]) / np.maximum(bot - top, 1)[None, :]
        ref = np.where(seen[None, :], sides[0][None, :] + frac * (sides[1] - sides[0])[None, :], -np.inf)
        with np.errstate(invalid="ignore"):  # -inf in columns not judged: never near
            gap = np.maximum(p.window_ledge_step_m, p.window_ledge_rel * ref)
            near = m & np.isfinite(d) & (d < ref - gap)
            if bleed is not None:
                near &= ~bleed[b:b + h, b:b + w]
        return near

    # First without the bleed: it only takes reads and pixels away, so a blob with too few pixels
    # nearer without it (most blobs: a pane is flush with its wall) has too few with it.
    near = nearer(None)
    if near is None or int(near.sum()) < p.window_ledge_min_share * m.sum():
        return [(0, 0, m)]
    # The bleed of what is in front (not sky: no depth): a pane beside a tree or under a pole's arm
    # reads nearer than its wall over the bleed's width, and was cut there as a ledge (docs/proposals.md
    # "Fourteenth pass: the ledge test and the depth's bleed"). Outside the frame: as if in it. The
    # reads 2 px off stand clear of a bleed that narrow (512x256: 2 px).
    if b > 2:
        ya, yb, xa, xb = max(y - b, 0), min(y + h + b, H), max(x - b, 0), min(x + w + b, W)
        front = (~_in_labels(labels[ya:yb, xa:xb], (BUILDING, SKY) + GROUND)).astype(np.uint8)
        bleed = np.ones((h + 2 * b, w + 2 * b), bool)  # local, at (y - b, x - b)
        # (nothing in front, the usual case: no dilation of an empty box)
        bleed[ya - y + b:yb - y + b, xa - x + b:xb - x + b] = (cv2.dilate(front, np.ones((2 * b + 1, 2 * b + 1),
                                                                                        np.uint8)) > 0) \
            if front.any() else False
        near = nearer(bleed)
        if near is None:
            return [(0, 0, m)]
    n = int(near.sum())
    if n < p.window_ledge_min_share * m.sum():  # a few pixels nearer are depth noise, not a ledge
        return [(0, 0, m)]
    if n >= 0.5 * m.sum():
        rows = np.flatnonzero(near.any(1))
        if (rows[-1] - rows[0] + 1) * float(median(d[near])) / fy >= p.window_ledge_keep_m:
            return [(0, 0, m)]  # a pane's height standing before the wall: a dormer, not a ledge
    rest = m & ~near
    return [(py, px, pm) for py, px, pm, _ in components(rest, p.window_min_area_px, connectivity=4)]


def _blob_columns(lab: np.ndarray, keep: np.ndarray, ya: int, xa: int) -> dict:
    """The pixels of the kept labels of ``lab`` (a label image at (ya, xa)), ordered by label, column,
    row: their image rows Y, columns X, labels L, and per (label, column) group (index G per pixel)
    its label, column, top and bottom row and count."""
    ys, xs = np.nonzero(lab)  # row-major: y ascending within a (label, column)
    ls = lab[ys, xs]
    sel = keep[ls]
    ys, xs, ls = ys[sel], xs[sel], ls[sel].astype(np.int64)
    key = ls * lab.shape[1] + xs
    o = np.argsort(key, kind="stable")
    key, Y, X, ls = key[o], ys[o] + ya, xs[o] + xa, ls[o]
    first = np.concatenate(([True], key[1:] != key[:-1]))  # (np.r_ costs more than the rest here)
    gs = np.flatnonzero(first)
    ge = np.concatenate((gs[1:], [key.size])) - 1
    return dict(Y=Y, X=X, L=ls, G=np.cumsum(first) - 1, lab=ls[gs], col=X[gs], top=Y[gs], bot=Y[ge],
                cnt=ge - gs + 1, ya=ya, Hs=lab.shape[0])


def _never_windows(ctx: Context, c: dict, n: int, bw: np.ndarray, bh: np.ndarray, area: np.ndarray, fy: float,
                   p) -> np.ndarray:
    """Per label 0..n-1 of :func:`_blob_columns`' table ``c`` (boxes ``bw`` x ``bh``, ``area`` px): whether
    the blob can give nothing in :func:`propose`'s loop -- :func:`accept <propose>` calls it "small"
    (under ``window_min_area_px`` or two rows; or, with depth, lower than ``window_height_m[0]`` at its
    median depth and not cut off, :func:`_cut_off`) and :func:`_occupancy_split` does not cut it (a
    "small" blob changes nothing and nothing of it is pushed again). Judged with a margin that only
    ever keeps a blob for the per-blob tests."""
    H, W = ctx.shape
    dead = (area < p.window_min_area_px) | (bh < 2)
    depth, labels = ctx.depth, ctx.labels
    if depth is None or c["Y"].size == 0:
        return dead
    Y, X, L = c["Y"], c["X"], c["L"]
    d = depth[Y, X]
    fin = np.isfinite(d)
    lf, df = L[fin], d[fin].astype(np.float64)
    o = np.lexsort((df, lf))
    lf, df = lf[o], df[o]
    nf = np.bincount(lf, minlength=n)
    st = np.concatenate(([0], np.cumsum(nf)[:-1]))
    has = nf > 0
    zmed = np.full(n, np.nan)
    zmed[has] = (df[(st + (nf - 1) // 2)[has]] + df[(st + nf // 2)[has]]) / 2
    with np.errstate(invalid="ignore"):
        low = has & (bh * zmed / fy < p.window_height_m[0] * (1 - 1e-6))
    g_lab, g_col = c["lab"], c["col"]
    if p.window_cut_any_height and low.any():
        def front(rows: np.ndarray) -> np.ndarray:
            out = (rows < 0) | (rows >= H)
            ok = ~out
            out[ok] = ~_in_labels(labels[rows[ok], g_col[ok]], (BUILDING, SKY))
            return out

        fc = np.bincount(g_lab, weights=front(c["top"] - 1) | front(c["bot"] + 1), minlength=n)
        nc = np.bincount(g_lab, minlength=n)
        low &= ~((np.minimum(bh, bw) >= 3) & (fc >= 0.5 * nc - 1e-9))
    gap = float(p.window_gap_occupancy)
    if gap > 0 and low.any():
        def splits(g_l: np.ndarray, g_pos: np.ndarray, occ: np.ndarray, length: np.ndarray) -> np.ndarray:
            """A nearly empty column (row) with fuller ones on both sides, per label (``g_l`` sorted, and
            ``g_pos`` ascending within a label)."""
            lo_, full = occ < gap * (1 + 1e-9), occ >= 2 * gap * (1 - 1e-9)
            cf = np.cumsum(full)
            tot = np.bincount(g_l, weights=full, minlength=n)
            s0 = np.concatenate(([0], np.cumsum(np.bincount(g_l, minlength=n))[:-1]))[g_l]  # its label's first group
            before = cf - cf[s0] + full[s0]  # full ones up to here within the label
            inside = lo_ & (before > 0) & (tot[g_l] - before > 0)
            # (a blob's box column (row) without pixels: empty, to be cut -- a piece of _gap_split)
            return ((np.bincount(g_l[inside], minlength=n) > 0) | (np.bincount(g_l, minlength=n) < length)) \
                & (length >= 5)

        Hs = c["Hs"]
        low &= ~splits(g_lab, g_col, c["cnt"] / bh[g_lab], bw)
        rkey = L * Hs + (Y - c["ya"])
        if n * Hs <= 1 << 20:
            rc = np.bincount(rkey, minlength=n * Hs)
            rk = np.flatnonzero(rc)
            rc = rc[rk]
        else:
            rk, rc = np.unique(rkey, return_counts=True)
        r_lab = rk // Hs
        low &= ~splits(r_lab, rk % Hs, rc / bw[r_lab], bh)
    return dead | low


def _may_ledge(ctx: Context, c: dict, n: int, area: np.ndarray, p) -> np.ndarray:
    """Per label 0..n-1 of :func:`_blob_columns`' table ``c`` (``area`` px, with depth): whether
    :func:`_ledge_split` may cut the blob -- its first test (enough pixels nearer than the wall read above
    and below it, without the bleed), with a margin of a pixel more; a blob it says no to is itself."""
    H, W = ctx.shape
    depth, labels = ctx.depth, ctx.labels
    g_col, G, Y, X = c["col"], c["G"], c["Y"], c["X"]

    def read(rows_: np.ndarray) -> np.ndarray:
        v = np.full(rows_.size, np.nan)
        ok = (rows_ >= 0) & (rows_ < H)
        v[ok] = np.where(_in_labels(labels[rows_[ok], g_col[ok]], (BUILDING,) + GROUND),
                         depth[rows_[ok], g_col[ok]], np.nan)
        return v

    t2, b2 = c["top"] - 2, c["bot"] + 2
    s0, s1 = read(t2), read(b2)
    seen = np.isfinite(s0) & np.isfinite(s1)
    d = depth[Y, X]
    with np.errstate(invalid="ignore"):
        frac = (Y - t2[G]) / np.maximum(b2 - t2, 1)[G]
        ref = s0[G] + frac * (s1 - s0)[G]
        gap = np.maximum(p.window_ledge_step_m, p.window_ledge_rel * ref)
        near = seen[G] & np.isfinite(d) & (d < ref - gap + 1e-6)  # the margin: a pixel more, never less
    return np.bincount(c["L"][near], minlength=n) >= p.window_ledge_min_share * area * (1 - 1e-9)


def _first_blobs(ctx: Context, cand: np.ndarray, fy: float, p) -> list[tuple[int, int, np.ndarray, int]]:
    """The blobs :func:`propose` starts from: ``components(cand, window_min_area_px, connectivity=4)``,
    each without its ledges (:func:`_ledge_split`), as (y, x, mask, 0) in the same order -- less those
    that cannot give a window (:func:`_never_windows`). A textured facade makes thousands of blobs,
    most a few pixels below a pane's height, and the per-blob tests took seconds (docs/proposals.md
    "Seventeenth pass: the textured facade's time"); here all are judged at once from one labelling.
    :func:`_ledge_split` is called only for a blob of which enough pixels may be nearer than the wall
    read above and below it (its first test, without the bleed, with a margin of a pixel more); else
    the blob is itself."""
    H, W = ctx.shape
    rows = np.flatnonzero(cand.any(1))
    if rows.size == 0:
        return []
    cols = np.flatnonzero(cand.any(0))
    ya, xa = int(rows[0]) & ~1, int(cols[0]) & ~1  # as core.components: the same labels, the same order
    sub = cand[ya:int(rows[-1]) + 1, xa:int(cols[-1]) + 1]
    n, lab, stats, _ = cv2.connectedComponentsWithStats(sub.astype(np.uint8), connectivity=4)
    bx, by, bw, bh, area = (stats[:, i].astype(np.int64) for i in range(5))
    keep = area >= p.window_min_area_px
    keep[0] = False
    if not keep.any():
        return []
    depth, labels = ctx.depth, ctx.labels
    ledge = depth is not None and p.window_ledge_step_m > 0
    may_ledge = np.full(n, ledge)  # (window_ledge_min_share <= 0: every blob to _ledge_split)
    if depth is None:  # (the table only serves the tests with depth)
        dead = (area < p.window_min_area_px) | (bh < 2)
    else:
        c = _blob_columns(lab, keep, ya, xa)
        dead = _never_windows(ctx, c, n, bw, bh, area, fy, p)
    if ledge and p.window_ledge_min_share > 0:
        may_ledge = _may_ledge(ctx, c, n, area, p)
    out = []
    for k in np.flatnonzero(keep).tolist():
        if dead[k] and not may_ledge[k]:
            continue
        x, y, w, h = int(bx[k]), int(by[k]), int(bw[k]), int(bh[k])
        m = lab[y:y + h, x:x + w] == k
        if may_ledge[k]:
            out.extend((ya + y + ly, xa + x + lx, lm, 0)
                       for ly, lx, lm in _ledge_split(depth, labels, fy, ya + y, xa + x, m, p))
        else:
            out.append((ya + y, xa + x, m, 0))
    return out


def _dead_pieces(ctx: Context, pieces: list, fy: float, p) -> np.ndarray:
    """Per piece (y, x, mask) in the image -- :func:`propose`'s blobs cut by :func:`_occupancy_split`,
    :func:`_gap_split` or eroded and grown back, of any blobs --: whether it can give nothing
    (:func:`_never_windows`), all judged at once from one table of their pixels. Each piece is judged on
    its own pixels (pieces may overlap: grown parts share pixels). Without depth none."""
    n = len(pieces)
    if ctx.depth is None or n == 0:
        return np.zeros(n, bool)
    c, bw, bh, area = _pieces_columns(ctx, pieces)
    return _never_windows(ctx, c, n + 1, bw, bh, area, fy, p)[1:]


def _pieces_columns(ctx: Context, pieces: list) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_blob_columns`' table of pieces (y, x, mask) in the image (one or more), piece k labelled
    k + 1 (each on its own pixels: pieces may overlap), and per label its box's width, height and area."""
    H, W = ctx.shape
    n = len(pieces)
    bw, bh, area = np.zeros(n + 1, np.int64), np.zeros(n + 1, np.int64), np.zeros(n + 1, np.int64)
    Ys, Xs = [], []
    for k, (y, x, m) in enumerate(pieces, 1):
        xs, ys = np.nonzero(m.T)  # by column, then row
        Ys.append(ys + y)
        Xs.append(xs + x)
        bh[k], bw[k] = m.shape
        area[k] = xs.size
    Y, X = np.concatenate(Ys), np.concatenate(Xs)
    L = np.repeat(np.arange(1, n + 1, dtype=np.int64), area[1:])
    key = L * W + X
    first = np.concatenate(([True], key[1:] != key[:-1]))
    gs = np.flatnonzero(first)
    ge = np.concatenate((gs[1:], [key.size])) - 1
    c = dict(Y=Y, X=X, L=L, G=np.cumsum(first) - 1, lab=L[gs], col=X[gs], top=Y[gs], bot=Y[ge],
             cnt=ge - gs + 1, ya=0, Hs=H)  # as _blob_columns' table over the whole frame
    return c, bw, bh, area


def _juts_out(ctx: Context, li: Light) -> bool:
    """Whether most of a proposed window is a ledge (:func:`_ledge_split`): an awning's valance or a
    balcony slab the facade lattice took for a cell."""
    if ctx.depth is None or ctx.params.window_ledge_step_m <= 0:
        return False
    rest = _ledge_split(ctx.depth, ctx.labels, float(ctx.intrinsics.fy), li.y0, li.x0, li.mask, ctx.params)
    return sum(int(pm.sum()) for _, _, pm in rest) < 0.5 * li.mask.sum()


def _strip_width_m(ctx: Context, li: Light) -> float | None:
    """Width along its wall (m) of a thin upright window (at most ``window_strip_max_px`` wide and three
    times as tall): its pixel width times the wall's metres per pixel column there, from the wall's depth
    over its rows in the 5 columns either side (2 px off its box: its own depth bleeds; a plane's depth
    is linear in the column, x = (u - cx) z / fx). None for any other window, without depth, when
    neither side has 3 columns of mostly wall, or when something in front (neither building nor
    sky) lies within 2 px of either side on half its rows: a pane's visible part beside a pole or a
    sign is as narrow as what is left of it. Each side's wall gives a width, the larger is returned
    (at a building's corner the wall beyond the strip is another plane)."""
    p = ctx.params
    h, w = li.mask.shape
    if ctx.depth is None or w > p.window_strip_max_px or h < 3 * w:
        return None
    W = ctx.shape[1]
    rows = np.arange(li.y0, li.y0 + h)
    has = li.mask.any(1)
    left = li.x0 + np.argmax(li.mask, axis=1)[has]
    right = li.x0 + w - 1 - np.argmax(li.mask[:, ::-1], axis=1)[has]
    r = rows[has]
    for side, step in ((left, -1), (right, 1)):
        front = np.zeros(r.size, bool)
        for k in (1, 2):
            c = side + step * k
            ok = (c >= 0) & (c < W)
            front[ok] |= ~_in_labels(ctx.labels[r[ok], c[ok]], (BUILDING, SKY))
            front[~ok] = True  # the frame's edge cuts it too
        if front.mean() >= 0.5:
            return None
    z = _median_depth(ctx, li)  # (memoised)
    if z is None:
        return None
    K = ctx.intrinsics
    u = li.x0 + (w - 1) / 2.0
    widths = []
    for side in (range(li.x0 - 7, li.x0 - 2), range(li.x0 + w + 2, li.x0 + w + 7)):
        cols, zs = [], []
        for c in side:
            if not 0 <= c < W:
                continue
            ok = ctx.labels[rows, c] == BUILDING
            dc = ctx.depth[rows[ok], c]
            dc = dc[np.isfinite(dc)]
            if dc.size >= 0.5 * h:
                cols.append(c)
                zs.append(float(median(dc)))
        if len(cols) >= 3:
            slope = float(np.polyfit(np.asarray(cols, float), np.asarray(zs), 1)[0])  # m of depth per column
            widths.append(w * float(np.hypot(z / K.fx + (u - K.cx) * slope / K.fx, slope)))
    # each side on its own: at a building's corner the wall beyond the pane is another plane
    return max(widths) if widths else None


def _cut_off(labels: np.ndarray, y: int, x: int, sub: np.ndarray) -> bool:
    """Whether a blob (``sub`` at (y, x)) is cut off at its top or bottom: over at least half its
    columns the pixel just above its top or just below its bottom is the image border or something
    in front of the wall (a label other than building and sky: a car, a tree, a pole). A pane cut
    there shows only its visible part, however low; a sliver beside a pole is cut at its side and
    is not."""
    H, W = labels.shape
    h, w = sub.shape
    has = sub.any(0)
    if min(h, w) < 3:  # a sliver along a car's roof or a pole, not a pane's visible part
        return False
    cols = x + np.flatnonzero(has)
    top = y + np.argmax(sub, axis=0)[has] - 1
    bot = y + h - np.argmax(sub[::-1], axis=0)[has]

    def front(rows: np.ndarray) -> np.ndarray:
        out = (rows < 0) | (rows >= H)
        ok = ~out
        out[ok] = ~_in_labels(labels[rows[ok], cols[ok]], (BUILDING, SKY))
        return out

    return bool((front(top) | front(bot)).mean() >= 0.5)


def _set_back(ctx: Context, li: Light) -> float | None:
    """How far a pane lies behind the plane of the wall below it, as a share of its depth:
    z_pane / z_plane - 1 at the pane's median pixel, the plane 1/z = a u + b v + c (a plane's inverse
    depth is linear in the image; a vertical wall's b follows from a, c and the camera's pitch) fitted
    to the building pixels
    ``window_dormer_below_m`` below the pane's bottom, in its columns widened by its width each side,
    a pixel away from any other label (depth bleeds across an object's outline), then refitted
    without the pixels more than 3 median deviations off. Down a wall seen at an angle a set-back
    of s metres is s / (the wall's distance from the camera's path) of the depth: 0.6 m is 5-10 % on
    a street's side walls. None without depth, or when under half that band is such building pixels
    (a tree, a car, the frame's edge below the pane) or it spans fewer than 2 columns."""
    if ctx.depth is None:
        return None
    p = ctx.params
    H, W = ctx.shape
    h, w = li.mask.shape
    z = _median_depth(ctx, li)  # (memoised)
    if z is None:
        return None
    fy = float(ctx.intrinsics.fy)
    r0 = li.y0 + h + int(round(p.window_dormer_below_m[0] * fy / z))
    r1 = min(H, li.y0 + h + int(round(p.window_dormer_below_m[1] * fy / z)))
    c0, c1 = max(0, li.x0 - w), min(W, li.x0 + 2 * w)
    if r1 - r0 < 2 or c1 - c0 < 2:
        return None
    band = ctx.depth[r0:r1, c0:c1]
    ok = _building_inside(ctx)[r0:r1, c0:c1] & np.isfinite(band) & (band > 0)
    if ok.sum() < max(6, 0.5 * ok.size):
        return None
    vv, uu = np.nonzero(ok)
    if np.ptp(uu) < 1:
        return None
    # A wall is vertical: its normal is level, which fixes b from a and c for the camera's pitch
    # (1/z = a (u + k cx v) + c (1 + k v)); the fit is then sideways only and its extrapolation up
    # to the pane does not hang on the band's few rows.
    K = ctx.intrinsics
    tp = float(np.tan(p.camera_pitch_rad))
    k = -tp / (float(K.fy) + float(K.cy) * tp)

    def design(u, v):
        u, v = np.asarray(u, np.float64), np.asarray(v, np.float64)
        return np.stack([u + k * float(K.cx) * v, 1.0 + k * v], -1)

    A = design(uu + c0, vv + r0)
    inv = 1.0 / band[ok].astype(np.float64)
    coef, *_ = np.linalg.lstsq(A, inv, rcond=None)
    res = np.abs(A @ coef - inv)
    keep = res <= 3.0 * max(float(median(res)), 1e-12)
    if keep.sum() >= 6:
        coef, *_ = np.linalg.lstsq(A[keep], inv[keep], rcond=None)
    ys, xs = np.nonzero(li.mask)
    inv_plane = float(design(li.x0 + median(xs), li.y0 + median(ys)) @ coef)
    return float(z * inv_plane - 1.0) if inv_plane > 0 else None


def _building_inside(ctx: Context) -> np.ndarray:
    """HxW bool, read-only: building pixels a pixel away from any other label (the labels eroded by a 3x3
    square, the frame's edge replicated), once per context (:func:`_set_back` read it per window, each
    eroding its own band)."""
    inside = ctx.__dict__.get("_window_building_inside")
    if inside is None:
        inside = cv2.erode((ctx.labels == BUILDING).astype(np.uint8), np.ones((3, 3), np.uint8),
                           borderType=cv2.BORDER_REPLICATE) > 0
        inside.flags.writeable = False
        ctx.__dict__["_window_building_inside"] = inside
    return inside


def _is_dormer(ctx: Context, li: Light) -> bool:
    """Whether a window lies behind the plane of the wall below it by ``window_dormer_set_back`` of its
    depth (:func:`_set_back`): a dormer's pane over the eaves, which an annotator does not count as a
    window of the facade (on its small face it is over 40 % lit). Judged on the final windows: the
    facade rules (grid, 1.5x, the lit cap) take it as any window of its wall."""
    lo, hi = ctx.params.window_dormer_set_back
    if hi <= 0 or (li.kind or "window") != "window":
        return False
    s = _set_back(ctx, li)
    return s is not None and lo <= s <= hi


def _along_wall_m(ctx: Context, li: Light) -> tuple[float, float] | None:
    """(length along its wall, height) in metres of a window, from its outline and its median depth z. Its top
    and bottom edges are level lines on its wall: a line fitted to each edge's rows (slope s rows a column, over
    the columns where the pixel beyond the edge is building or sky: not the frame's border, nothing in front;
    the first and last columns left out) gives the wall's direction in the level plane, the angle t of
    dz/dx with tan t = s / (s (u - cx) / fx - e), e the edge's elevation below the level, (v - cy) / fy +
    tan(pitch), at the box's middle column u. Directions are taken modulo 180 degrees (the mean of the doubled
    angles when both edges give one); when they differ by more than ``window_band_edge_agree_deg`` (one edge
    flattened by a ledge or a cut) the one nearer the direction from the depth around the window
    (:func:`_wall_direction` on the building pixels within 15 % of z, the box widened by its size) is taken. A
    column at u then spans z / (fx |cos t - sin t (u - cx) / fx|) m along the wall (at most 20 times the face-on
    z / fx). The height is the median column's run of rows times z / fy (a receding band's box is taller than
    the band), over the columns the frame's top and bottom rows do not cut. A window under
    ``window_band_edge_px`` columns, or with no usable edge, is measured face on (w z / fx). None without depth."""
    if ctx.depth is None:
        return None
    z = _median_depth(ctx, li)  # (memoised)
    if z is None:
        return None
    p = ctx.params
    K = ctx.intrinsics
    H, W = ctx.shape
    h, w = li.mask.shape
    cols, gy_t, gy_b, height = _band_rows(ctx, li, z)
    gx = li.x0 + cols
    tp = float(np.tan(p.camera_pitch_rad))
    u = li.x0 + (w - 1) / 2.0
    ang = []  # the wall's direction in the level plane, atan(dz/dx), from each usable edge
    if cols.size >= p.window_band_edge_px:
        for gy, step in ((gy_t, -1), (gy_b, 1)):
            nb = gy + step
            ok = (nb >= 0) & (nb < H)
            ok[ok] = _in_labels(ctx.labels[nb[ok], gx[ok]], (BUILDING, SKY))
            ok[:1] = ok[-1:] = False  # a corner's column is rounded by the outline's quantisation
            if ok.sum() < max(3, p.window_band_edge_px - 2):
                continue
            sl, c0 = np.polyfit(gx[ok].astype(np.float64), gy[ok].astype(np.float64), 1)
            e = (sl * u + c0 - K.cy) / float(K.fy) + tp
            ang.append(float(np.arctan2(sl, sl * (u - K.cx) / float(K.fx) - e)))
    if len(ang) == 2 and abs(np.sin(ang[0] - ang[1])) > np.sin(np.radians(p.window_band_edge_agree_deg)):
        # the edges disagree (one flattened by a ledge, a cut or a blur): the one nearer the wall's
        # direction from the depth around the window (building pixels within 15 % of its depth)
        ya, yb = max(0, li.y0 - h), min(H, li.y0 + 2 * h)
        xa, xb = max(0, li.x0 - 2 * w), min(W, li.x0 + 3 * w)
        fm = np.zeros(ctx.shape, bool)
        dz = ctx.depth[ya:yb, xa:xb]
        with np.errstate(invalid="ignore"):
            fm[ya:yb, xa:xb] = (ctx.labels[ya:yb, xa:xb] == BUILDING) & (np.abs(dz - z) < 0.15 * z)
        t = _wall_direction(ctx, fm, (slice(ya, yb), slice(xa, xb)))
        if t is None:
            ang = []
        else:
            ref = float(np.arctan2(t[1], t[0]))
            ang = [min(ang, key=lambda a_: abs(np.sin(a_ - ref)))]
    if ang:
        # directions are defined modulo pi: the mean of the doubled angles
        th = 0.5 * float(np.arctan2(np.mean(np.sin(2 * np.asarray(ang))), np.mean(np.cos(2 * np.asarray(ang)))))
        d = max(abs(np.cos(th) - np.sin(th) * (u - K.cx) / float(K.fx)), 0.05)
        length = w * z / (float(K.fx) * d)
    else:
        length = w * z / float(K.fx)
    return length, height


def _band_rows(ctx: Context, li: Light, z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """:func:`_along_wall_m`'s columns of a window (local), its top and bottom rows in them (image) and
    its height in metres at depth ``z``: the median column's run of rows over the columns the frame's top
    and bottom rows do not cut."""
    h = li.mask.shape[0]
    has = li.mask.any(0)
    cols = np.flatnonzero(has)
    top = np.argmax(li.mask, axis=0)[has]
    bot = h - 1 - np.argmax(li.mask[::-1], axis=0)[has]
    gy_t, gy_b = li.y0 + top, li.y0 + bot
    run = bot - top + 1
    both = (gy_t > 0) & (gy_b < ctx.shape[0] - 1)
    return cols, gy_t, gy_b, float(median(run[both] if both.any() else run)) * z / float(ctx.intrinsics.fy)


def _kind(ctx: Context, li: Light) -> str:
    """``shop`` (glazing from near the ground, at least ``window_shop_min_h_m`` tall: a shop front),
    ``office_band`` (at least ``window_band_min_aspect`` times wider than tall in metres: a glass
    floor band) or ``window`` (a final window may become a ``dormer``, :func:`_is_dormer`). Ground-floor
    glazing found without the strip of wall over it (``Light.shop_front``, :func:`propose`) is a shop front."""
    p = ctx.params
    h, w = li.mask.shape
    if getattr(li, "shop_front", False):
        return "shop"
    if ctx.depth is None:
        return "window"
    z = _median_depth(ctx, li)  # (memoised)
    if z is None:
        return "window"
    h_m, w_m = h * z / float(ctx.intrinsics.fy), w * z / float(ctx.intrinsics.fx)
    bottom = float(ctx.height_above_ground(li.y0 + h - 0.5, z))
    if bottom <= p.window_shop_max_sill_m and h_m >= p.window_shop_min_h_m:
        return "shop"
    if w_m >= p.window_band_min_aspect * h_m and h_m >= p.window_height_m[0]:
        return "office_band"
    return "window"


def _receding_band(ctx: Context, li: Light) -> bool:
    """Whether a final window is an office floor band seen along its wall (:func:`_along_wall_m`): at
    least ``window_band_wall_aspect`` times longer along its wall than tall, at least
    ``window_band_min_h_m`` tall (``window_band_cut_min_h_m`` when the frame's top or bottom row cuts it) and
    its bottom at least ``window_band_min_sill_m`` above the ground (wide glazing lower down is a shop
    front's). :func:`_kind` measures a window face on (its box's width and height times depth / f), which
    a band receding down the street fails; judged on the final windows, after the facade rules (which
    take it as a window of its wall: its pieces and the panes beside it are cut the same), the kind only."""
    p = ctx.params
    if p.window_band_edge_px <= 0 or (li.kind or "window") != "window" or ctx.depth is None:
        return False
    z = _median_depth(ctx, li)  # (memoised)
    if z is None:
        return False
    h = li.mask.shape[0]
    if float(ctx.height_above_ground(li.y0 + h - 0.5, z)) < p.window_band_min_sill_m:
        return False
    cut = li.y0 == 0 or li.y0 + h == ctx.shape[0]  # the frame cuts it: its height is a part's
    # first the height, and the most a length along its wall can be (a column spans at most 20 times its
    # face-on width, _along_wall_m): most windows are no band by these alone, without the edges' fits
    height = _band_rows(ctx, li, z)[3]
    if height < (p.window_band_cut_min_h_m if cut else p.window_band_min_h_m) or \
            li.mask.shape[1] * z / (float(ctx.intrinsics.fx) * 0.05) < p.window_band_wall_aspect * height:
        return False
    wall = _along_wall_m(ctx, li)
    if wall is None:
        return False
    return wall[0] >= p.window_band_wall_aspect * wall[1] and \
        wall[1] >= (p.window_band_cut_min_h_m if cut else p.window_band_min_h_m)


def _fit_line(x: np.ndarray, y: np.ndarray):
    """y = a + b x by least squares (a constant for fewer than two distinct x)."""
    if x.size >= 2 and np.ptp(x) > 1e-6:
        b, a = np.polyfit(x, y, 1)
        return lambda q: a + b * q
    m = float(np.mean(y))
    return lambda q: m + 0.0 * q


def _paint_boxes(shape: tuple[int, int], boxes: list[tuple[int, int, int, int]]) -> np.ndarray:
    """HxW bool, True on the boxes (y0, y1, x0, x1 inclusive, inside the image): a box (clipped to the
    image) overlaps one of them iff a pixel of it is True."""
    occ = np.zeros(shape, bool)
    for y0, y1, x0, x1 in boxes:
        occ[y0:y1 + 1, x0:x1 + 1] = True
    return occ


def _columns(boxes: list[tuple[int, int, int, int]]) -> list[tuple[float, float, int]]:
    """Bays of a facade from window boxes (y0, y1, x0, x1 inclusive): windows whose column ranges
    overlap by at least half the narrower form one bay; returns (median x0, median x1, count)."""
    cols: list[list[tuple[int, int]]] = []
    meds: list[tuple[float, float]] = []  # per bay its median x0, x1 (changes only when it grows)
    for _, _, x0, x1 in sorted(boxes, key=lambda b: (b[2] + b[3])):
        for k, (c, (a0, a1)) in enumerate(zip(cols, meds)):
            ov = min(a1, x1) - max(a0, x0) + 1
            if ov >= 0.5 * min(a1 - a0 + 1, x1 - x0 + 1):
                c.append((x0, x1))
                meds[k] = (median([q[0] for q in c]), median([q[1] for q in c]))
                break
        else:
            cols.append([(x0, x1)])
            meds.append((median([x0]), median([x1])))
    return [(float(a0), float(a1), len(c)) for c, (a0, a1) in zip(cols, meds)]


def regularise(ctx: Context, found: list, ratio: np.ndarray, chroma: np.ndarray, B: np.ndarray,
               bld: np.ndarray, rejects: list | None = None, boxes: list | None = None) -> list:
    """Windows as a facade grid, per wall (:func:`facades`; docs/proposals.md "Building windows").

    Each window gets a kind (:func:`_kind`: shop front, office floor band or window). The windows
    of a region form floors (centre heights within ``window_floor_tol_m``; the top and bottom rows
    of a floor are lines across the facade, which recedes) and bays (column ranges seen on at least
    two floors). Then:

    * a window spanning two or more cells (bays x floors), and a blob rejected as too large or too
      ragged for one window (``rejects``: (y0, x0, mask)) that spans them, is cut into one window per
      cell (a piece filling ``window_min_fill`` of its cell; grown to the blob's columns of its pane where
      those are wider than the cell, :func:`_cell_grown`); a window
      taller than 1.5x the median window height of its facade and of the windows nearest to it, or
      wider than ``window_wide_ratio`` x the wider of its floor neighbours, is cut along the cells it
      spans; a tall one without floors to cut it along is dropped (a gable or a roof taken for a
      window), a wide one without bays is kept as found (its neighbours may be slivers);
    * every cell of a floor with at least three windows and a bay that holds no window and looks
      faintly like one (``window_cell_min_share`` of its pixels beyond half the window thresholds,
      mostly building pixels) is proposed (confidence 0.55);
    * windows larger than 1.5x the median of their wall and floor are dropped, or on the ground
      floor called shop fronts (:func:`_median_rule`); then every cell of the wall's window lattice
      in view that looks faintly like a window and holds none is proposed (:func:`lattice_cells`,
      confidence 0.55), and windows spanning two or more of its cells are replaced by the cells;
    * the windows of a wall cover at most ``window_max_lit_share`` of it: the least confident
      beyond that are dropped (a lit facade is lit per room, not as a whole); a wall with fewer than
      three windows is capped on its connected building region instead (a piece of a facade cut off
      by a depth step, a tree or a pole: one pane is often over 40 % of such a piece).

    ``found``: [wall id, level, level tolerance, Light] per window; ``bld``: the wall ids
    (:func:`facades`); returns the new list.
    """
    p = ctx.params
    t = -np.log(p.window_dark_ratio)
    H, W = ctx.shape
    out = []
    for f in found:
        f[3].kind = _kind(ctx, f[3])
    from scipy import ndimage

    wall_boxes = ndimage.find_objects(bld) if boxes is None else boxes  # each wall's box
    regs: list = []  # the connected building regions, labelled when first needed

    def wall_mask(b_id: int) -> tuple[np.ndarray, tuple[slice, slice]]:
        """``bld == b_id`` (HxW) compared on the wall's box only, and that box."""
        sl = wall_boxes[b_id - 1] if 0 < b_id <= len(wall_boxes) else None
        if sl is None:
            return bld == b_id, (slice(0, H), slice(0, W))
        fm = np.zeros((H, W), bool)
        fm[sl] = bld[sl] == b_id
        return fm, sl

    def _region_area(b_id: int) -> float:
        """Pixels of the connected building region holding most of the wall ``b_id``."""
        if not regs:
            regs.extend(cv2.connectedComponentsWithStats(B.astype(np.uint8), connectivity=4)[1:3])
        reg_lab, reg_st = regs
        fm, sl = wall_mask(b_id)
        lab = reg_lab[sl][fm[sl]]
        lab = lab[lab > 0]
        return float(reg_st[int(np.bincount(lab).argmax()), cv2.CC_STAT_AREA]) if lab.size else float(fm[sl].sum())

    regions: dict[int, list] = {}
    for f in found:
        regions.setdefault(f[0], []).append(f)
    rejected: dict[int, list] = {}
    for y0, x0, m in rejects or []:
        ids_ = bld[y0:y0 + m.shape[0], x0:x0 + m.shape[1]][m]
        if ids_.size:
            rejected.setdefault(int(np.bincount(ids_).argmax()), []).append((y0, x0, m))
    for b_id, fs in regions.items():
        wins = [f for f in fs if f[3].kind == "window"]
        other = [f for f in fs if f[3].kind != "window"]
        if len(wins) < 3:
            # too few windows to tell a wall from a piece of one (a facade cut by a tree or a depth
            # step): capped on the connected building region around it, not on the piece
            out.extend(_cap_lit(p, wins, _region_area(b_id)) + other)
            continue
        box = {id(f): (f[3].y0, f[3].y0 + f[3].mask.shape[0] - 1, f[3].x0, f[3].x0 + f[3].mask.shape[1] - 1)
               for f in wins}
        heights = np.array([box[id(f)][1] - box[id(f)][0] + 1 for f in wins], float)
        # metric heights where depth is known (pixel heights on one plane otherwise)
        levels = sorted(wins, key=lambda f: f[1])
        floors: list[list] = []
        for f in levels:
            if floors and f[1] - floors[-1][-1][1] <= f[2]:
                floors[-1].append(f)
            else:
                floors.append([f])
        hm = []
        for f in wins:
            y0, y1, x0, x1 = box[id(f)]
            z = ctx.metres_per_px(y0, y1 + 1, x0, x1 + 1, f[3].mask)
            hm.append((y1 - y0 + 1) * z if z is not None else float(y1 - y0 + 1))
        hm = np.array(hm)
        med_h = float(median(hm))
        all_cols = _columns(list(box.values()))
        cols = [c for c in all_cols if c[2] >= 2]  # bays seen on two floors at least
        floor_of = {id(f): fl for fl in floors for f in fl}
        lines = []  # per floor: (top(x), bottom(x), members)
        for fl in floors:
            xs = np.array([(box[id(f)][2] + box[id(f)][3]) / 2.0 for f in fl])
            lines.append((_fit_line(xs, np.array([box[id(f)][0] for f in fl], float)),
                          _fit_line(xs, np.array([box[id(f)][1] for f in fl], float)), fl))
        centres = np.array([(box[id(f)][2] + box[id(f)][3]) / 2.0 for f in wins])
        widths = np.array([box[id(f)][3] - box[id(f)][2] + 1 for f in wins], float)
        kept = []
        taken = list(box.values())
        for y0, x0, m in rejected.get(b_id, []):
            y1, x1 = y0 + m.shape[0] - 1, x0 + m.shape[1] - 1
            if ctx.depth is not None and p.window_pitch_cut_depth_tol > 0:
                # a receding row of far panes a pixel apart, too long for one window: its panes where it
                # dips at its floor's pitch (_pitch_cut), those no window holds yet
                rl = Light(WINDOW_BUILDING, y0, x0, m, 0.6)
                pcs = [q for q in _pitch_cut(ctx, [b_id, fl_level(ctx, rl), p.window_floor_tol_m, rl], wins,
                                             0.0, np.inf, ratio, chroma)
                       if not any(min(q[3].x0 + q[3].mask.shape[1] - 1, b[3]) >= max(q[3].x0, b[2]) and
                                  min(q[3].y0 + q[3].mask.shape[0] - 1, b[1]) >= max(q[3].y0, b[0]) for b in taken)]
                if pcs:
                    for q in pcs:
                        taken.append((q[3].y0, q[3].y0 + q[3].mask.shape[0] - 1, q[3].x0,
                                      q[3].x0 + q[3].mask.shape[1] - 1))
                    kept.extend(pcs)
                    continue
            xc = (x0 + x1) / 2.0
            cs = [c for c in all_cols if min(c[1], x1) - max(c[0], x0) + 1 >= 0.5 * (c[1] - c[0] + 1)]
            rs = [(top(xc), bot(xc)) for top, bot, fl in lines if len(fl) >= 2
                  and min(bot(xc), y1) - max(top(xc), y0) + 1 >= 0.5 * (bot(xc) - top(xc) + 1)]
            if len(cs) * len(rs) < 2:
                continue
            for c0, c1, _ in cs:
                for r0, r1 in rs:
                    a0, a1 = int(round(max(r0, y0))) - y0, int(round(min(r1, y1))) - y0
                    b0, b1 = int(round(max(c0, x0))) - x0, int(round(min(c1, x1))) - x0
                    if a1 < a0 or b1 < b0 or any(min(x0 + b1, q[3]) >= max(x0 + b0, q[2]) and
                                                 min(y0 + a1, q[1]) >= max(y0 + a0, q[0]) for q in taken):
                        continue  # a window holds that cell already
                    piece = np.zeros(m.shape, bool)
                    piece[a0:a1 + 1, b0:b1 + 1] = m[a0:a1 + 1, b0:b1 + 1]
                    cell_area = (int(round(r1)) - int(round(r0)) + 1) * (int(round(c1)) - int(round(c0)) + 1)
                    if piece.sum() < max(p.window_min_area_px, p.window_min_fill * cell_area):
                        continue
                    if p.window_cell_grow > 0:
                        piece = _cell_grown(m, piece, a0, a1, b0, b1, p.window_cell_grow, y0, x0, taken)
                    ys, xs = np.nonzero(piece)
                    sub = piece[ys.min():ys.max() + 1, xs.min():xs.max() + 1]
                    nl = Light(WINDOW_BUILDING, y0 + int(ys.min()), x0 + int(xs.min()), sub, 0.6)
                    nl.kind = "window"
                    taken.append((nl.y0, nl.y0 + sub.shape[0] - 1, nl.x0, nl.x0 + sub.shape[1] - 1))
                    kept.append([b_id, fl_level(ctx, nl), p.window_floor_tol_m if ctx.depth is not None
                                 else max(2.0, sub.shape[0] / 2.0), nl])
        for k, f in enumerate(wins):
            y0, y1, x0, x1 = box[id(f)]
            near = np.argsort(np.abs(centres - centres[k]))[1:5]
            local_h = float(median(hm[near])) if near.size else med_h
            tall = hm[k] > 1.5 * max(med_h, local_h)
            # widths shrink along a receding facade: compare with the next windows of the same floor
            row = sorted(floor_of[id(f)], key=lambda q: box[id(q)][2])
            j = next(i for i, q in enumerate(row) if q is f)
            beside = [box[id(row[i])][3] - box[id(row[i])][2] + 1 for i in (j - 1, j + 1) if 0 <= i < len(row)]
            wide = bool(beside) and widths[k] > p.window_wide_ratio * max(max(beside), 1.0)
            if not (tall or wide):
                kept.append(f)
                continue
            # cut along the cells it spans
            span_cols = [c for c in cols if min(c[1], x1) - max(c[0], x0) + 1 >= 0.5 * (c[1] - c[0] + 1)]
            xc = (x0 + x1) / 2.0
            span_rows = [(top(xc), bot(xc)) for top, bot, _ in lines
                         if min(bot(xc), y1) - max(top(xc), y0) + 1 >= 0.5 * (bot(xc) - top(xc) + 1)]
            if tall and len(span_rows) < 2:
                if not hm[k] <= p.window_tall_keep_m:
                    continue  # taller than a window and no floors to cut it along: not a window
                # a pane's height with no floors to cut it along: its size is the area rule's to
                # judge, against the wall's whole panes (_median_rule) -- the height median of a wall
                # of a few windows is often a fragment's (a curtain band, a pane's part beside a tree)
                tall = False
                if not wide:
                    kept.append(f)
                    continue
            if wide and len(span_cols) < 2:
                if not tall:
                    kept.append(f)  # neighbours may be slivers behind a tree: keep it as found
                continue
            li = f[3]
            for c0, c1, _ in (span_cols if wide else [(x0, x1, 0)]):
                for r0, r1 in (span_rows if tall else [(y0, y1)]):
                    cell = np.zeros(li.mask.shape, bool)
                    a0, a1 = int(round(max(r0, y0))) - y0, int(round(min(r1, y1))) - y0
                    b0, b1 = int(round(max(c0, x0))) - x0, int(round(min(c1, x1))) - x0
                    if a1 < a0 or b1 < b0:
                        continue
                    cell[a0:a1 + 1, b0:b1 + 1] = True
                    piece = cell & li.mask
                    if piece.sum() < p.window_min_area_px:
                        continue
                    ys, xs = np.nonzero(piece)
                    sub = piece[ys.min():ys.max() + 1, xs.min():xs.max() + 1]
                    nl = Light(li.class_id, li.y0 + int(ys.min()), li.x0 + int(xs.min()), sub, li.confidence)
                    nl.kind = "window"
                    kept.append([b_id, fl_level(ctx, nl), f[2], nl])
        # empty cells of regular floors that look faintly like a window
        # boxes of the windows kept, painted: a cell overlaps one iff a pixel of it is painted (a
        # thousand candidates on a textured wall without depth made the pairwise test minutes)
        have = _paint_boxes((H, W), [(f[3].y0, f[3].y0 + f[3].mask.shape[0] - 1, f[3].x0,
                                      f[3].x0 + f[3].mask.shape[1] - 1) for f in kept])
        for top, bot, fl in lines:
            if len(fl) < 3:
                continue
            for c0, c1, _ in cols:
                xc = (c0 + c1) / 2.0
                r0, r1 = int(round(top(xc))), int(round(bot(xc)))
                a0, a1 = int(round(c0)), int(round(c1))
                if r1 - r0 < 1 or a1 - a0 < 0 or r0 < 0 or a0 < 0 or r1 >= H or a1 >= W:
                    continue
                if have[r0:r1 + 1, a0:a1 + 1].any():
                    continue
                inside = (bld[r0:r1 + 1, a0:a1 + 1] == b_id) & B[r0:r1 + 1, a0:a1 + 1]
                if inside.mean() < 0.8:
                    continue  # hidden (a tree, a pole) or off the facade
                odd = (np.abs(ratio[r0:r1 + 1, a0:a1 + 1]) > 0.5 * t) | \
                    (chroma[r0:r1 + 1, a0:a1 + 1] > 0.5 * p.window_chroma_delta)
                if (odd & inside).sum() < p.window_cell_min_share * inside.sum():
                    continue
                nl = Light(WINDOW_BUILDING, r0, a0, inside, 0.55)
                nl.kind = "window"
                kept.append([b_id, fl[0][1], fl[0][2], nl])
                have[r0:r1 + 1, a0:a1 + 1] = True
        fm, fsl = wall_mask(b_id)
        t_wall = _wall_direction(ctx, fm, fsl) if len(kept) >= 3 else None
        # panes merged across a strip of wall: cut there before the rule drops them as too large
        kept = _split_oversized(ctx, kept, fm, t_wall, ratio, chroma)
        n0 = {id(f): f for f in kept}
        # before the grid: the cells stand in for what it drops (a window it cuts into panes, _pitch_cut, too)
        kept = _median_rule(ctx, kept, fm, t_wall, ratio, chroma)
        dropped = [n0[k][3] for k in set(n0) - {id(f) for f in kept}]
        # the lattice from whole panes: a pane's visible part has another centre and width; a piece
        # _pitch_cut made of a dropped window is placed by its floor-mates' pitch, not evidence of it
        fit = [i for i, f in enumerate(kept) if not f[3].cut and id(f) in n0]
        cells, merged = lattice_cells(ctx, fm, [kept[i] for i in fit], ratio, chroma, dropped, t_wall, fsl)
        merged = {fit[j] for j in merged}
        if cells:
            kept = [f for i, f in enumerate(kept) if i not in merged]
            have = _paint_boxes((H, W), [(f[3].y0, f[3].y0 + f[3].mask.shape[0] - 1, f[3].x0,
                                          f[3].x0 + f[3].mask.shape[1] - 1) for f in kept])
            for ya, xa, m in cells:
                yb, xb = ya + m.shape[0] - 1, xa + m.shape[1] - 1
                if have[max(ya, 0):max(yb + 1, 0), max(xa, 0):max(xb + 1, 0)].any():
                    # a pane found as a fragment of its cell (its top rows above a dim lower part, a
                    # fleck): the lattice of its floor-mates says where the whole pane is
                    frag = _cell_fragments(kept, ya, xa, m, p.window_cell_fragment_share)
                    if not frag:
                        continue
                    for j in frag:  # the cell and its fragments (a fragment may reach a pixel past it)
                        ya, xa, m = _union((ya, xa, m), (kept[j][3].y0, kept[j][3].x0, kept[j][3].mask))
                    kept = [f for j, f in enumerate(kept) if j not in frag]
                    have[ya:ya + m.shape[0], xa:xa + m.shape[1]] = True
                nl = Light(WINDOW_BUILDING, ya, xa, m, 0.55)
                nl.kind = "window"
                kept.append([b_id, fl_level(ctx, nl), p.window_floor_tol_m if ctx.depth is not None
                             else max(2.0, m.shape[0] / 2.0), nl])
        kept = _small_rule(ctx, kept, fm, t_wall)
        out.extend(_cap_lit(p, kept, float(fm[fsl].sum())) + other)
    return out


def _cell_grown(m: np.ndarray, piece: np.ndarray, a0: int, a1: int, b0: int, b1: int, grow: float,
                y0: int, x0: int, taken: list) -> np.ndarray:
    """The piece of a blob too large for one window (``m``, local; the piece: its pixels in the cell's rows
    ``a0..a1`` and columns ``b0..b1``) grown to the blob's run of columns that fill at least half of the
    cell's rows and hold the cell's own: the bays come from the wall's other floors, whose panes can be
    narrower than this floor's, so a cell can hold two thirds of its pane (docs/proposals.md "Eighteenth
    pass: windows at 512x256"). Kept as it was unless that run is at most ``grow`` x the cell's width and
    meets no box of ``taken`` (y0, y1, x0, x1 inclusive, image coordinates; the blob at ``y0``, ``x0``)."""
    band = m[a0:a1 + 1]
    full = band.mean(0) >= 0.5  # the blob's columns over half the floor's band (a sill line is one row)
    runs = np.cumsum(np.r_[full[:1], full[1:] & ~full[:-1]]) * full  # runs of such columns, numbered from 1
    ids = np.unique(runs[b0:b1 + 1])
    run = np.isin(runs, ids[ids > 0])  # those holding one of the cell's columns
    cx = np.flatnonzero(run)
    if not cx.size or cx[-1] - cx[0] + 1 > grow * (b1 - b0 + 1) or any(
            min(x0 + int(cx[-1]), q[3]) >= max(x0 + int(cx[0]), q[2]) and min(y0 + a1, q[1]) >= max(y0 + a0, q[0])
            for q in taken):
        return piece
    out = piece.copy()
    out[a0:a1 + 1] |= band & run[None]
    return out


def _cell_fragments(wins: list, ya: int, xa: int, m: np.ndarray, share: float) -> set[int]:
    """Indices of ``wins`` ([wall id, level, tolerance, Light]) that are fragments of the lattice cell
    (``ya``, ``xa``, local mask ``m``): every window whose box meets the cell's box must be a whole
    window (not cut by the frame or something in front) of kind "window" within the cell's columns
    and rows (a pixel either side allowed: the lattice is often a pixel off) and under ``share`` of
    the cell's pixels; else (a window of another size or place holds the cell, or none does) the
    empty set."""
    if share <= 0:
        return set()
    yb, xb = ya + m.shape[0] - 1, xa + m.shape[1] - 1
    out = set()
    for j, f in enumerate(wins):
        li = f[3]
        y1, x1 = li.y0 + li.mask.shape[0] - 1, li.x0 + li.mask.shape[1] - 1
        if y1 < ya or li.y0 > yb or x1 < xa or li.x0 > xb:
            continue
        if (li.cut or (li.kind or "window") != "window" or li.x0 < xa - 1 or x1 > xb + 1
                or li.y0 < ya - 1 or y1 > yb + 1 or li.mask.sum() >= share * m.sum()):
            return set()
        out.add(j)
    return out


def _wall_areas(ctx: Context, wins: list, fm: np.ndarray, t: tuple[float, float] | None,
                shrink: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Areas on the wall (m^2) of windows ``wins`` ([wall id, level, tol, Light]) of one wall
    (``fm``, HxW bool; direction ``t``, :func:`_wall_direction`), and which are whole panes.

    Area: pixels x (z / f)^2 / cos of the incidence on the wall (a pane down a receding wall is
    foreshortened); with ``shrink`` each one pixel smaller across and down than in the image
    (quantisation: a pane 1.4 px wide is 1 or 2 px in the image, not twice the size: the benefit of
    the doubt for a large one; without, a small one's); NaN without depth at the window.
    Whole: its box and a pixel around it all building, inside the frame (a pane cut by a tree, a
    car or the frame's edge shows less than its size).
    """
    K = ctx.intrinsics
    area = []
    for f in wins:
        li = f[3]
        h, w = li.mask.shape
        z = _median_depth(ctx, li)
        if z is None:
            area.append(np.nan)
            continue
        cos = 1.0
        if t is not None:
            rx = (li.x0 + w / 2.0 - 0.5 - K.cx) / K.fx
            cos = max(0.1, abs(t[1] * rx - t[0]) / float(np.hypot(rx, 1.0)))
        n = max(float(li.mask.sum()) * (w - 1) * (h - 1) / float(w * h), 1.0) if shrink else float(li.mask.sum())
        area.append(n * z * z / (float(K.fx) * float(K.fy)) / cos)
    H, W = fm.shape
    lab = ctx.labels  # compared on each box only (a full-image mask per call took ~1 ms)
    whole = np.array([li.y0 > 0 and li.x0 > 0 and li.y0 + li.mask.shape[0] < H and li.x0 + li.mask.shape[1] < W
                      and (lab[li.y0 - 1:li.y0 + li.mask.shape[0] + 1, li.x0 - 1:li.x0 + li.mask.shape[1] + 1]
                           == BUILDING).all()
                      for li in (f[3] for f in wins)], bool)
    return np.asarray(area, float), whole


def _median_rule(ctx: Context, wins: list, fm: np.ndarray, t: tuple[float, float] | None,
                 ratio: np.ndarray | None = None, chroma: np.ndarray | None = None) -> list:
    """Drop the windows larger than ``window_max_median_ratio`` x the median window of their wall
    (``fm``, HxW bool; ``window_median_min_count`` windows at least) and of their floor (three windows
    at least; a window with one or two whole mates on its floor is judged against those mates, not
    itself: a floor of larger panes has mates of its size): a merged
    row, a gable or an awning, never one pane.
    Areas on the wall: :func:`_wall_areas`, the window judged one pixel smaller across and down
    (quantisation), the median over its wall's whole windows at their full pixel area. With ``ratio``
    and ``chroma`` (the window features' departure from the wall) a window dropped is replaced by its
    panes where its floor says it is a row of them (:func:`_pitch_cut`)."""
    p = ctx.params
    if len(wins) < p.window_median_min_count or ctx.depth is None:
        return wins
    a, whole = _wall_areas(ctx, wins, fm, t)
    # The window judged gets the benefit of one pixel of quantisation, the reference does not: a
    # reference shrunk too makes every 1-px-wide pane one pixel, and a 2-px pane of the same row
    # "oversized" (docs/proposals.md, "Sixth pass").
    a_ref, _ = _wall_areas(ctx, wins, fm, t, shrink=False)
    # The reference sizes leave out panes cut by something in front (a tree, a car, the frame's
    # edge): their visible part is smaller than the pane.
    ref_a = np.where(whole, a_ref, np.nan) if (whole & np.isfinite(a_ref)).sum() >= p.window_median_min_count \
        else a_ref
    if np.isfinite(ref_a).sum() < p.window_median_min_count:
        return wins
    med = float(nanmedian(ref_a))
    lev = np.array([f[1] for f in wins])
    out = []
    for k, (f, ai) in enumerate(zip(wins, a)):
        # ... and of its floor (a gable's or a dormer row's windows are smaller than the main floors')
        on_floor = (np.abs(lev - f[1]) <= f[2]) & np.isfinite(ref_a)
        row = ref_a[on_floor]
        if row.size >= 3:
            ref = max(med, float(median(row)))
        else:
            # one or two whole mates on its floor: judged against them, not itself -- a floor of
            # larger panes (a top floor's tall ones) has mates of its size, a merged row does not
            on_floor[k] = False
            ref = max(med, float(median(ref_a[on_floor]))) if on_floor.any() else med
        if not (np.isfinite(ai) and ai > p.window_max_median_ratio * ref):
            out.append(f)
            continue
        li = f[3]
        z = _median_depth(ctx, li)
        if z is not None and float(ctx.height_above_ground(li.y0 - 0.5, z)) <= p.window_shop_max_top_m:
            li.kind = "shop"  # ground-floor glazing larger than the windows above: a shop front
            out.append(f)
        elif ratio is not None and chroma is not None:
            # far panes of the floor merged by their blur: its panes, where its dips fall at the floor's pitch
            out.extend(_pitch_cut(ctx, f, wins, float(ai), p.window_max_median_ratio * ref, ratio, chroma))
    return out


def _neighbour_ratios(ctx: Context, found: list, k: int = 6, min_n: int = 3, heights: bool = False) -> tuple:
    """Each window's size over its neighbours': its pixels x z^2 (its median depth z) over the median of
    that of its ``k`` nearest windows (centre distance in the image) of kind ``window`` at its depth
    (within ``window_pitch_cut_depth_tol``) on any wall, ``min_n`` of them at least -- what a window is
    against the panes around it where its own wall has too few windows to say (:func:`_median_rule`
    needs ``window_median_min_count``; a far facade's walls are pieces of a few windows each).
    ``found``: [wall id, level, tol, Light]; NaN for other kinds, without depth or neighbours. And the
    median width (px) of those neighbours; with ``heights``, their median height (px) too."""
    n = len(found)
    out, mw, mh = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    if ctx.depth is None or n <= min_n:
        return (out, mw, mh) if heights else (out, mw)
    tol = float(ctx.params.window_pitch_cut_depth_tol)
    z = np.full(n, np.nan)
    cy, cx, a, wd, ht = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    win = np.zeros(n, bool)
    for i, f in enumerate(found):
        li = f[3]
        zi = _median_depth(ctx, li)
        win[i] = (li.kind or "window") == "window" and zi is not None
        if win[i]:
            z[i] = zi
            cy[i], cx[i] = li.y0 + li.mask.shape[0] / 2.0, li.x0 + li.mask.shape[1] / 2.0
            a[i] = float(li.mask.sum()) * zi * zi
            wd[i], ht[i] = li.mask.shape[1], li.mask.shape[0]
    for i in np.flatnonzero(win):
        j = np.flatnonzero(win & (np.abs(z - z[i]) <= tol * z[i]))
        j = j[j != i]
        if j.size < min_n:
            continue
        j = j[np.argsort(np.hypot(cy[j] - cy[i], cx[j] - cx[i]), kind="stable")[:k]]
        out[i] = a[i] / float(median(a[j]))
        mw[i] = float(median(wd[j]))
        mh[i] = float(median(ht[j]))
    return (out, mw, mh) if heights else (out, mw)


def _window_ids(shape: tuple, found: list) -> np.ndarray:
    """HxW int32: each window's pixels hold its index in ``found`` + 1 (later windows over earlier ones), 0
    elsewhere."""
    ids = np.zeros(shape, np.int32)
    for i, f in enumerate(found):
        li = f[3]
        ids[li.y0:li.y0 + li.mask.shape[0], li.x0:li.x0 + li.mask.shape[1]][li.mask] = i + 1
    return ids


def _column_departure(li, dev: np.ndarray) -> np.ndarray:
    """A window's mean departure from the wall per column of its mask (``dev``, HxW, in window
    thresholds; 0 where a column holds none of it)."""
    cnt = li.mask.sum(0)
    d = dev[li.y0:li.y0 + li.mask.shape[0], li.x0:li.x0 + li.mask.shape[1]]
    return np.where(cnt > 0, (d * li.mask).sum(0) / np.maximum(cnt, 1), 0.0)


def _faint_ends_off(li, i: int, ids: np.ndarray, dev: np.ndarray, r: float, keep: int) -> None:
    """Take off window ``i``'s edge columns under ``r`` x its strongest column's departure, in place: the
    fainter end first, ``keep`` columns left at least. Not where a window beside the columns kept (``ids``,
    :func:`_window_ids`) is as strong there: the pane's glass goes on into it (split between two
    windows), so this window's width is not its pane's."""
    w = li.mask.shape[1]
    prof = _column_departure(li, dev)
    lim = r * float(prof.max())
    a, b = 0, w - 1
    while b - a + 1 > keep:
        k = a if prof[a] <= prof[b] else b
        if prof[k] >= lim:
            break
        a, b = (a + 1, b) if k == a else (a, b - 1)
    if a == 0 and b == w - 1:
        return
    rs = slice(li.y0, li.y0 + li.mask.shape[0])
    sides = ([li.x0 - 1] if a == 0 and li.x0 > 0 else []) + \
        ([li.x0 + w] if b == w - 1 and li.x0 + w < dev.shape[1] else [])
    if any(((o := (ids[rs, c] > 0) & (ids[rs, c] != i + 1)).any() and float(dev[rs, c][o].mean()) >= lim)
           for c in sides):
        return
    m = li.mask[:, a:b + 1]
    ys = np.flatnonzero(m.any(1))
    li.y0, li.x0, li.mask = li.y0 + int(ys[0]), li.x0 + a, m[ys[0]:ys[-1] + 1]


def _oversized_narrow_off(ctx: Context, found: list, dev: np.ndarray, p) -> None:
    """Take off the faint edge columns of a narrow window larger than the panes around it, in place: a
    window of kind ``window`` 2 to ``window_row_pane_max_px`` wide over ``window_narrow_oversized_ratio``
    x its neighbours' size (:func:`_neighbour_ratios`) loses its edge columns whose mean departure from
    the wall (``dev``, HxW, in window thresholds) is under ``window_unblur_narrow_ratio`` x its strongest
    column's, the fainter end first, down to its neighbours' median width (rounded down, one column at
    least: a near pane is 2-3 px) -- the trim of :func:`_unblur_narrow`, which judges a window against
    its floor-mates' width on its own wall; a far wall is often a piece of a few windows with no
    floor-mates, or mates as blurred. A far pane 1 px wide shows in 2-3 columns, its glass and its blur
    into the wall or the next face, and is then twice its facade's median (docs/proposals.md
    "Twenty-second pass: the 1.5x rule"). Not where a window beside the columns kept is as strong there
    (the glass goes on into it)."""
    g = float(p.window_narrow_oversized_ratio)
    r = float(p.window_unblur_narrow_ratio)
    if g <= 0 or r <= 0 or len(found) < 4:
        return
    nb, nbw = _neighbour_ratios(ctx, found)
    cand = [i for i, f in enumerate(found) if nb[i] > g and 2 <= f[3].mask.shape[1] <= p.window_row_pane_max_px]
    if not cand:
        return
    ids = _window_ids(dev.shape, found)
    for i in cand:  # not below the panes around it: a near pane is 2-3 px
        _faint_ends_off(found[i][3], i, ids, dev, r, max(int(np.floor(nbw[i])), 1))


def _sill_rows_off(ctx: Context, found: list, dev: np.ndarray, p) -> None:
    """Take off the end rows of a window that are a band running on past it, in place: a window of kind
    ``window`` 3 px wide and ``window_sill_rows_min_rows`` tall or more, over ``window_sill_rows_ratio`` x its
    neighbours' size and over that many times their median height but under ``window_sill_rows_max_ratio``
    x it (:func:`_neighbour_ratios`; a quarter of the rows goes at most: far taller is another pane), loses its
    end rows, the bottom first, whose mean departure from the wall (``dev``, HxW, in window thresholds) in
    the two columns either side of it, off every window, is on each side at least
    ``window_sill_rows_side_ratio`` of the row's mean departure in the window -- a quarter of its rows at
    most. A pane's sill or lintel rows that depart across the whole facade row (2048x1024 lights seed 0's
    5x39 pane: two sill rows) make it taller than the panes around it; ungated, the rows under and over a
    good pane often read like a band beside it (docs/proposals.md "Twenty-first pass: the 1.5x rule")."""
    g, r = float(p.window_sill_rows_ratio), float(p.window_sill_rows_side_ratio)
    cap = float(p.window_sill_rows_max_ratio)
    if g <= 0 or r <= 0 or len(found) < 4:
        return
    nb, _, nbh = _neighbour_ratios(ctx, found, heights=True)
    cand = [i for i, f in enumerate(found) if (f[3].kind or "window") == "window" and nb[i] > g
            and f[3].mask.shape[1] >= 3 and f[3].mask.shape[0] >= p.window_sill_rows_min_rows
            and f[3].mask.shape[0] > g * nbh[i] and not 0 < cap * nbh[i] < f[3].mask.shape[0]]
    if not cand:
        return
    H, W = dev.shape
    taken = np.zeros(dev.shape, bool)  # every window's pixels
    for f in found:
        li = f[3]
        taken[li.y0:li.y0 + li.mask.shape[0], li.x0:li.x0 + li.mask.shape[1]] |= li.mask
    trims = []
    for i in cand:
        li = found[i][3]
        h, w = li.mask.shape

        def band(ry: int) -> bool:
            y, m = li.y0 + ry, li.mask[ry]
            if not m.any():
                return True
            lim = r * float(dev[y, li.x0:li.x0 + w][m].mean())
            for cs in ((li.x0 - 2, li.x0 - 1), (li.x0 + w, li.x0 + w + 1)):
                cs = [c for c in cs if 0 <= c < W and not taken[y, c]]
                if not cs or float(dev[y, cs].mean()) < lim:
                    return False
            return True

        a, b, most = 0, h - 1, int(0.25 * h)
        while b > a and a + (h - 1 - b) < most:
            if band(b):
                b -= 1
            elif band(a):
                a += 1
            else:
                break
        if a > 0 or b < h - 1:
            trims.append((i, a, b))
    for i, a, b in trims:  # all judged on the windows as they came
        li = found[i][3]
        m = li.mask[a:b + 1]
        xs, ys = np.flatnonzero(m.any(0)), np.flatnonzero(m.any(1))
        if xs.size:
            li.y0, li.x0 = li.y0 + a + int(ys[0]), li.x0 + int(xs[0])
            li.mask = m[ys[0]:ys[-1] + 1, xs[0]:xs[-1] + 1]


def _split_two_panes(ctx: Context, found: list, dev: np.ndarray, p) -> list:
    """The windows with each merged pair of far panes split into its panes: a window of kind ``window`` 3
    px wide or more over ``window_split_oversized_ratio`` x its neighbours' size (:func:`_neighbour_ratios`),
    those far panes at most 2 px wide, whose column profile (each column's strongest departure from the
    wall, ``dev``: HxW in window thresholds) dips between two peaks to under ``window_split_dip_ratio`` of
    the weaker one, is cut at its weakest inner column (that column goes): each side, ``window_min_area_px``
    and two rows at least and as many rows as columns (a far pane is tall), is a window. Two panes a column
    apart blur into one another at a far facade's top (docs/proposals.md "Twenty-second pass: the 1.5x rule
    -- the merged pair").
    ``found``: [wall id, level, tol, Light]."""
    g, r = float(p.window_split_oversized_ratio), float(p.window_split_dip_ratio)
    if g <= 0 or r <= 0 or len(found) < 4:
        return found
    nb, nbw = _neighbour_ratios(ctx, found)
    out = []
    for i, f in enumerate(found):
        li = f[3]
        h, w = li.mask.shape
        if not (nb[i] > g and nbw[i] <= 2.0 and w >= 3):
            out.append(f)
            continue
        d = dev[li.y0:li.y0 + h, li.x0:li.x0 + w]
        prof = np.where(li.mask, d, -np.inf).max(0)
        lo = np.maximum.accumulate(prof)[:-2]  # the strongest column left of each inner column
        hi = np.maximum.accumulate(prof[::-1])[::-1][2:]  # ... and right of it
        q = prof[1:-1] / np.maximum(np.minimum(lo, hi), 1e-6)
        c = 1 + int(np.argmin(q))
        if not q[c - 1] < r:
            out.append(f)
            continue
        parts = []
        for a, b in ((0, c), (c + 1, w)):
            m = li.mask[:, a:b]
            ys = np.flatnonzero(m.any(1))
            if ys.size < max(2, b - a) or int(m.sum()) < p.window_min_area_px:  # a far pane is tall
                break
            parts.append(f[:3] + [dataclasses.replace(li, y0=li.y0 + int(ys[0]), x0=li.x0 + a,
                                                      mask=m[ys[0]:ys[-1] + 1])])
        out.extend(parts if len(parts) == 2 else [f])
    return out


def _wide_wall_columns_off(ctx: Context, found: list, dev: np.ndarray, p) -> None:
    """Take off the edge columns that read as wall of a window wider than the panes around it, in place:
    a window of kind ``window`` at least 3 px wide, ``window_wall_columns_min_rows`` tall and
    ``window_wall_columns_width_ratio`` x its
    neighbours' median width (:func:`_neighbour_ratios`) loses its edge columns whose mean departure
    from the wall (``dev``, HxW, in window thresholds) is under ``window_wall_columns_dev`` and half its
    strongest column's, the fainter end first, two columns left at least -- when those are at least
    ``window_wall_columns_min_share`` of its width (a wide pane's frame is a column or two of it, and the
    pane holds it). A pane's hull that took in a darker wall stripe beside it or the diagonal steps of its
    sill (2048x1024: hard seed 0's slanted pane, lights seed 0's 3-px pane) is wider than the panes around
    it; a pane whose glass reads as faint as the wall is not, and is left; nor is a window over
    ``window_wall_columns_max_width_ratio`` x their width, a band or a shop front (docs/proposals.md
    "Twenty-second pass: the 1.5x rule at 2048x1024")."""
    g = float(p.window_wall_columns_width_ratio)
    t = float(p.window_wall_columns_dev)
    cap = float(p.window_wall_columns_max_width_ratio)
    if g <= 0 or t <= 0 or len(found) < 4:
        return
    _, nbw = _neighbour_ratios(ctx, found)
    for i, f in enumerate(found):
        li = f[3]
        h, w = li.mask.shape
        if not (w >= 3 and h >= p.window_wall_columns_min_rows and nbw[i] > 0 and w >= g * nbw[i]):
            continue
        if 0 < cap * nbw[i] < w:  # a band or a shop front: not a pane's hull
            continue
        prof = _column_departure(li, dev)
        lim = min(t, 0.5 * float(prof.max()))
        a, b = 0, w - 1
        while b - a + 1 > 2:  # the fainter end first
            if prof[a] < lim and (prof[a] <= prof[b] or prof[b] >= lim):
                a += 1
            elif prof[b] < lim:
                b -= 1
            else:
                break
        if a == 0 and b == w - 1 or w - (b - a + 1) < float(p.window_wall_columns_min_share) * w:
            continue
        m = li.mask[:, a:b + 1]
        ys = np.flatnonzero(m.any(1))
        li.y0, li.x0, li.mask = li.y0 + int(ys[0]), li.x0 + a, m[ys[0]:ys[-1] + 1]


def _shaded_patches(ctx: Context, found: list, ratio: np.ndarray, p) -> list:
    """The windows less the patches of shaded wall among far panes, each replaced by the lit pane in it
    where it holds one: a window of kind ``window`` over ``window_shaded_patch_ratio`` x its neighbours'
    size (:func:`_neighbour_ratios`), those far panes at most 2 px wide and it at least twice as wide and a
    pixel, its bottom over ``window_shop_max_top_m`` above the ground (not a shop front), at least half of
    it darker than the wall by the window threshold (-ln ``window_dark_ratio``) and the median of those
    under twice it (a shadow keeps the wall's colour in less light; dark glass departs by 3-6 thresholds),
    at most 0.35 of it brighter by twice the threshold (lit glass). Its largest 8-connected bright part,
    ``window_min_area_px`` and two rows at least, is the window; without one it goes. A balcony slab's
    shadow on a far facade is one such patch, and the 1-px lit panes in it are its only glass
    (docs/proposals.md "Twenty-second pass: the 1.5x rule"). A window on or touching a patch dropped (or one
    dropped so), ``window_shaded_patch_overlap`` of it darker than the wall by the threshold and none of it
    brighter by twice it, goes with it: the rest of that shadow ("... -- the merged pair ...; the shade under a
    dropped patch"). ``found``: [wall id, level, tol, Light]; ``ratio``: HxW log luminance minus the wall
    reference's."""
    g = float(p.window_shaded_patch_ratio)
    if g <= 0 or len(found) < 4 or ctx.depth is None:
        return found
    t = -np.log(p.window_dark_ratio)
    nb, nbw = _neighbour_ratios(ctx, found)
    out, gone = [], np.zeros(ratio.shape, bool)
    for i, f in enumerate(found):
        li = f[3]
        h, w = li.mask.shape
        if not (nb[i] > g and nbw[i] <= 2.0 and w >= 2 * nbw[i] + 1):
            out.append(f)
            continue
        z = _median_depth(ctx, li)
        if z is None or float(ctx.height_above_ground(li.y0 + h - 0.5, z)) <= p.window_shop_max_top_m:
            out.append(f)
            continue
        r = ratio[li.y0:li.y0 + h, li.x0:li.x0 + w]
        dark = (r < -t) & li.mask
        bright = (r > 2 * t) & li.mask
        n = int(li.mask.sum())
        if dark.sum() < 0.5 * n or float(median(r[dark])) < -2 * t or bright.sum() > 0.35 * n:
            out.append(f)
            continue
        parts = sorted(components(bright, p.window_min_area_px), key=lambda c: -c[3])
        parts = [c for c in parts if c[2].shape[0] >= 2]
        if parts:
            py, px, pm, _ = parts[0]
            li.y0, li.x0, li.mask = li.y0 + py, li.x0 + px, pm
            out.append(f)
        else:
            gone[li.y0:li.y0 + h, li.x0:li.x0 + w] |= li.mask
    share = float(p.window_shaded_patch_overlap)
    if share > 0 and gone.any():
        # the rest of a dropped patch's shade: a window on it or touching it (or one dropped so), at least
        # half of it darker than the wall by the threshold and none of it lit -- the steps above cut the
        # shadow into pieces
        changed = True
        while changed:
            changed, keep = False, []
            near = cv2.dilate(gone.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
            for f in out:
                li = f[3]
                h, w = li.mask.shape
                box = (slice(li.y0, li.y0 + h), slice(li.x0, li.x0 + w))
                r = ratio[box]
                n = int(li.mask.sum())
                if (li.kind or "window") == "window" and near[box][li.mask].any() \
                        and ((r < -t) & li.mask).sum() >= share * n and not ((r > 2 * t) & li.mask).any():
                    gone[box] |= li.mask
                    changed = True
                else:
                    keep.append(f)
            out = keep
    return out


def _pitch_cut(ctx: Context, f: list, wins: list, area: float, limit: float, ratio: np.ndarray,
               chroma: np.ndarray) -> list:
    """The panes of a window ``f`` ([wall id, level, tol, Light]) that the 1.5x rule drops (``area``, m^2 on
    the wall, over ``limit``), or of a blob too large for one window (regularise's rejects; ``limit``
    inf), where its floor says what a pane is: a row of far panes merged by their blur into one blob
    that :func:`_row_split` did not cut (its depth gave too short a length along the wall for a row).
    Its floor-mates -- the windows of ``wins`` (its wall) at its depth (within
    ``window_pitch_cut_depth_tol``) on its floor (levels within its tolerance; where fewer than two of
    its floor were found, the nearest floor's: bays run up a facade), the four nearest it, two at
    least -- give a pane's width (their median, a pixel more: a pane 1.5 px wide shows as 1 or 2 px),
    its floor's band (their tallest) and the bay pitch (their median centre distance between
    neighbours on one side of it). The blob is cut across its columns where its departure from the
    wall (window thresholds, from ``ratio`` and ``chroma``) dips (:func:`_gap_split` at
    ``window_row_gap_contrast``); the pieces are the floor's panes when there are two or more and each,
    without its faint edge columns (:func:`_faint_sides_off`), is no wider than that and narrower than
    the pitch (wall between panes), no taller than 1.5x the band, at least a pane's least height
    (``window_height_m``) and ``window_min_area_px``, under ``limit`` on the wall, its centre 0.5-1.5
    pitches from the next one's. Else [] (dropped): a wall strip or a shop front shows no such dips,
    or its floor no such panes. The pieces keep one faint column a side, as :func:`_row_split`'s, for
    :func:`_unblur` (docs/proposals.md "Fifteenth pass: windows at 512x256 -- far panes merged in one
    blob")."""
    p = ctx.params
    tol = float(p.window_pitch_cut_depth_tol)
    li = f[3]
    h, w = li.mask.shape
    z = _median_depth(ctx, li)
    if tol <= 0 or w < 3 or z is None:
        return []
    cx = li.x0 + (w - 1) / 2.0
    near = []  # the wall's windows at its depth: (level, centre column, width, height)
    for q in wins:
        if q is f or (q[3].kind or "window") != "window":
            continue
        zq = _median_depth(ctx, q[3])
        if zq is not None and abs(zq - z) <= tol * z:
            near.append((q[1], q[3].x0 + (q[3].mask.shape[1] - 1) / 2.0, q[3].mask.shape[1], q[3].mask.shape[0]))
    # its floor's, or where fewer than two of its floor were found (a floor whose panes merged, a floor
    # the frame cuts), the nearest floor's: bays run up the facade, a floor's panes have its neighbours' width
    levels = sorted({m[0] for m in near}, key=lambda v: abs(v - f[1]))
    mates = []
    for v in levels:
        mates = [m[1:] for m in near if abs(m[0] - v) <= f[2]]
        if len(mates) >= 2:
            break
    mates = sorted(mates, key=lambda m: abs(m[0] - cx))[:4]
    if len(mates) < 2:
        return []
    # a pane's width: their median (a mate merged with its neighbour's blur or a strip of wall is not
    # the pane) and a pixel (a pane 1.5 px wide is 1 or 2 px); its floor's band: their tallest (a mate
    # cut by something in front shows less than the pane)
    mw, mh = int(np.ceil(median([m[1] for m in mates]))) + 1, max(m[2] for m in mates)
    sides = ([m[0] for m in mates if m[0] < cx], [m[0] for m in mates if m[0] > cx])
    steps = [b - a for side in sides for a, b in zip(sorted(side), sorted(side)[1:])]
    if not steps:
        return []
    pitch = float(median(steps))
    tl = -np.log(p.window_dark_ratio)
    box = (slice(li.y0, li.y0 + h), slice(li.x0, li.x0 + w))
    dev = np.maximum(np.abs(ratio[box]) / tl, chroma[box] / p.window_chroma_delta)
    pieces = _gap_split(li.mask, dev, float(p.window_row_gap_contrast), axis=0, min_len=3)
    if len(pieces) < 2:
        return []
    r = float(p.window_unblur_ratio)
    min_h = p.window_height_m[0] * float(ctx.intrinsics.fy) / z
    judged = [_faint_sides_off(py, px, pm, dev, r, 0) for py, px, pm in pieces]
    for _, _, pm in judged:
        if pm.shape[1] > mw or pm.shape[1] >= pitch or pm.shape[0] > 1.5 * mh or pm.shape[0] < min_h:
            return []
    centres = sorted(px + (pm.shape[1] - 1) / 2.0 for _, px, pm in judged)
    if any(not 0.5 * pitch <= b - a <= 1.5 * pitch for a, b in zip(centres, centres[1:])):
        return []
    n = float(li.mask.sum())
    out = []
    for py, px, pm in (_faint_sides_off(py, px, pm, dev, r, 1) for py, px, pm in pieces):
        if pm.sum() < p.window_min_area_px or area * pm.sum() / n > limit:
            return []
        nl = Light(li.class_id, li.y0 + py, li.x0 + px, pm, li.confidence)
        nl.kind = "window"
        nl.cut = li.cut
        out.append([f[0], fl_level(ctx, nl), f[2], nl])
    return out


def _split_oversized(ctx: Context, wins: list, fm: np.ndarray, t: tuple[float, float] | None,
                     ratio: np.ndarray, chroma: np.ndarray) -> list:
    """Cut the windows larger than ``window_max_median_ratio`` x the median whole window of their
    wall (``fm``; :func:`_wall_areas`) where the wall shows through them (:func:`_gap_split` at
    ``window_oversized_gap_contrast``): two panes of a row (or a column) merged across a one-pixel
    wall, which the lattice did not cut (too few windows on the wall, or the bays of a receding wall
    a pixel off). One window is one pane: each piece is a window when it passes the size and fill of
    one (``window_min_area_px``, ``window_height_m``, ``window_min_fill`` of its box and of it beyond
    the window thresholds, and those pixels at least 1 / ``window_max_median_ratio`` of the wall's
    median whole window: the hull fill of an L-shaped blob is not a pane); an oversized window
    without such a gap stays as it is (most are whole panes of a wall whose median a row of smaller
    ones lowers)."""
    p = ctx.params
    c = float(p.window_oversized_gap_contrast)
    if c <= 0 or len(wins) < p.window_median_min_count or ctx.depth is None:
        return wins
    a, whole = _wall_areas(ctx, wins, fm, t)
    ok = whole & np.isfinite(a)
    if ok.sum() < p.window_median_min_count:
        return wins
    med = float(median(a[ok]))
    a_px, _ = _wall_areas(ctx, wins, fm, t, shrink=False)
    med_px = float(median(a_px[ok]))
    tl = -np.log(p.window_dark_ratio)
    out = []
    for k, (f, ai) in enumerate(zip(wins, a)):
        li = f[3]
        h, w = li.mask.shape
        if not (np.isfinite(ai) and ai > p.window_max_median_ratio * med) or max(h, w) < 5:
            out.append(f)
            continue
        dev = np.maximum(np.abs(ratio[li.y0:li.y0 + h, li.x0:li.x0 + w]) / tl,
                         chroma[li.y0:li.y0 + h, li.x0:li.x0 + w] / p.window_chroma_delta)
        pieces = _gap_split(li.mask, dev, c)
        z = _median_depth(ctx, li)
        min_h = p.window_height_m[0] * float(ctx.intrinsics.fy) / z if z else 2.0
        # a piece is a pane when its pixels beyond the window thresholds (not the hull fill of an
        # L-shaped blob) make a whole pane: by the rule's own symmetry, over 1/1.5 of the median
        good = []
        for py, px, pm in pieces:
            raw = (dev[py:py + pm.shape[0], px:px + pm.shape[1]] >= 1.0) & pm
            if pm.sum() >= p.window_min_area_px and pm.mean() >= p.window_min_fill and pm.shape[0] >= min_h \
                    and raw.sum() >= p.window_min_fill * pm.sum() \
                    and a_px[k] * raw.sum() / li.mask.sum() >= med_px / p.window_max_median_ratio:
                good.append((py, px, pm))
        if len(good) < 2:
            out.append(f)
            continue
        for py, px, pm in good:
            nl = Light(li.class_id, li.y0 + py, li.x0 + px, pm, li.confidence)
            nl.kind = "window"
            nl.cut = li.cut
            out.append([f[0], fl_level(ctx, nl), f[2], nl])
    return out


def _small_rule(ctx: Context, wins: list, fm: np.ndarray, t: tuple[float, float] | None) -> list:
    """Drop the windows smaller than ``window_min_median_ratio`` x the median whole window of their
    wall (``fm``; :func:`_wall_areas`, ``window_median_min_count`` whole windows at least), unless
    they are a pane's visible part (cut by the frame or something in front, ``Light.cut``) or not
    whole: the wall's windows say what one pane is, and a piece far smaller is a fragment (a pane's
    frame, half a pane split by a mullion, a fleck of the wall), not a window. Such fragments also
    pull the wall's median window down, so that its whole panes look oversized against it
    (docs/proposals.md "Fifth pass"). A window with two whole windows or more on its floor (levels
    within its tolerance), itself at least ``window_resolved_px`` across both ways, is judged against
    their median when that is smaller: a floor of small panes (an attic row), as :func:`_median_rule`
    judges a floor of large ones (docs/proposals.md "Fourteenth pass: the ledge test and the depth's
    bleed")."""
    p = ctx.params
    r = float(p.window_min_median_ratio)
    if r <= 0 or len(wins) < p.window_median_min_count or ctx.depth is None:
        return wins
    a, whole = _wall_areas(ctx, wins, fm, t, shrink=False)
    ok = whole & np.isfinite(a)
    if ok.sum() < p.window_median_min_count:
        return wins
    med = float(median(a[ok]))
    lev = np.array([f[1] for f in wins])
    out = []
    for k, (f, ai, wh) in enumerate(zip(wins, a, whole)):
        if wh and np.isfinite(ai) and ai < r * med and not f[3].cut:
            mates = (np.abs(lev - f[1]) <= f[2]) & ok
            mates[k] = False
            if not (mates.sum() >= 2 and min(f[3].mask.shape) >= p.window_resolved_px
                    and ai >= r * float(median(a[mates]))):
                continue
        out.append(f)
    return out


def _shop_fronts(ctx: Context, found: list, bld: np.ndarray, B: np.ndarray, boxes: list | None = None) -> None:
    """Call ``shop`` (in place) the final windows whose top is at most ``window_shop_max_top_m`` above
    the ground and which are larger than ``window_max_median_ratio`` x the median whole window above
    the ground floor -- of their wall when it has three such windows, else of those over it (two at
    least: above the ground floor, a centre within its columns widened by its width either side, a depth
    within ``window_shop_above_depth_tol`` of its own; a shop's fascia often parts the ground floor's
    wall from the floors above): ground-floor glazing larger than the windows above is a shop front.

    :func:`_median_rule` does so only on walls of ``window_median_min_count`` windows and against the
    floor's own median, which a row of shop fronts sets to a shop front's size; the shop whose sill a car
    hides or the ground's estimate puts above ``window_shop_max_sill_m`` stays a ``window`` with
    :func:`_kind` (docs/proposals.md "Thirteenth pass: the 1.5x rule"). Only the kind changes: which
    lights are proposed does not. Areas: :func:`_wall_areas` on each window's own wall, the window
    judged one pixel smaller across and down, the reference at its pixel area.
    ``found``: [wall id, level, tolerance, Light] rows; ``bld``: the wall ids (:func:`facades`)."""
    p = ctx.params
    r = float(p.window_max_median_ratio)
    wins = [f for f in found if (f[3].kind or "window") == "window"]
    if ctx.depth is None or r <= 0 or len(wins) < 4:
        return
    by_wall: dict[int, list] = {}
    for f in wins:
        by_wall.setdefault(f[0], []).append(f)
    top, depth = {}, {}
    for f in wins:
        li = f[3]
        z = _median_depth(ctx, li)
        depth[id(f)] = z if z is not None else np.nan
        top[id(f)] = float(ctx.height_above_ground(li.y0 - 0.5, z)) if z is not None else np.inf
    cands = [f for f in wins if top[id(f)] <= p.window_shop_max_top_m]
    if not cands:
        return
    from scipy import ndimage

    if boxes is None:
        boxes = ndimage.find_objects(bld)
    a, a_ref, whole = {}, {}, {}

    def measure(b_id: int) -> None:
        """Areas of the wall ``b_id``'s windows (the wall's direction from its pixels, once)."""
        if id(by_wall[b_id][0]) in a:
            return
        fm = np.zeros(bld.shape, bool)
        sl = boxes[b_id - 1] if 0 < b_id <= len(boxes) and boxes[b_id - 1] is not None else None
        if sl is not None:
            fm[sl] = bld[sl] == b_id
        t = _wall_direction(ctx, fm, sl)
        ai, wh = _wall_areas(ctx, by_wall[b_id], fm, t)
        ar, _ = _wall_areas(ctx, by_wall[b_id], fm, t, shrink=False)
        for q, x, y, w in zip(by_wall[b_id], ai, ar, wh):
            a[id(q)], a_ref[id(q)], whole[id(q)] = x, y, bool(w)

    tol = float(p.window_shop_above_depth_tol)
    above = [f for f in wins if top[id(f)] > p.window_shop_max_top_m and np.isfinite(depth[id(f)])]

    def sizes(qs: list) -> list[float]:
        """The whole ones' areas, or all of theirs when under three are whole (a tree or the frame's
        top cuts the floors above: their visible parts, smaller than a pane, as in :func:`_median_rule`)."""
        for q in qs:
            measure(q[0])
        w_ = [a_ref[id(q)] for q in qs if whole[id(q)]]
        return w_ if len(w_) >= 3 else [a_ref[id(q)] for q in qs]

    for f in cands:
        measure(f[0])
        if not np.isfinite(a[id(f)]):
            continue
        ref = sizes([q for q in above if q[0] == f[0]])
        if len(ref) < 3:
            li = f[3]
            x0, x1, w = li.x0, li.x0 + li.mask.shape[1], li.mask.shape[1]
            ref = sizes([q for q in above if x0 - w <= q[3].x0 + q[3].mask.shape[1] / 2.0 <= x1 + w
                         and abs(depth[id(q)] - depth[id(f)]) <= tol * depth[id(f)]])
        if len(ref) >= 2 and a[id(f)] > r * float(median(ref)):
            f[3].kind = "shop"


def _trim_ends(li: Light, dev: np.ndarray, p) -> None:
    """Take off a window's end rows of the wall's colour, in place: a top (bottom) row whose mean
    departure from the wall over the window's pixels in it (``dev``, HxW, in window thresholds) is
    under ``window_unblur_ratio`` x the window's median row, one row at a time, at most a quarter of
    its rows. A lintel or a sill is not glass."""
    r = float(p.window_unblur_ratio)
    h, w = li.mask.shape
    if r <= 0 or h < 6:
        return
    d = dev[li.y0:li.y0 + h, li.x0:li.x0 + w]
    cnt = li.mask.sum(1)
    prof = np.where(cnt > 0, (d * li.mask).sum(1) / np.maximum(cnt, 1), np.nan)
    med = float(nanmedian(prof))
    a, b, n = 0, h - 1, 0
    while n < h // 4 and b - a >= 4:
        if np.isfinite(prof[a]) and prof[a] < r * med:
            a += 1
        elif np.isfinite(prof[b]) and prof[b] < r * med:
            b -= 1
        else:
            break
        n += 1
    if a == 0 and b == h - 1:
        return
    m = li.mask[a:b + 1]
    ys, xs = np.nonzero(m)
    if not ys.size:
        return
    li.y0, li.x0 = li.y0 + a + int(ys.min()), li.x0 + int(xs.min())
    li.mask = m[ys.min():ys.max() + 1, xs.min():xs.max() + 1]


def _unblur_narrow(found: list, dev: np.ndarray, p) -> None:
    """Take off a narrow window's faint edge columns where it is wider than its floor-mates, in place:
    a window of kind ``window`` at most ``window_row_pane_max_px`` wide, wider than the median width
    of its (up to four) nearest floor-mates (``found`` rows [wall id, level, tolerance, Light]: the
    same wall, levels within its tolerance; two at least), loses its edge columns whose mean departure
    from the wall (``dev``, HxW, in window thresholds) is under ``window_unblur_narrow_ratio`` x its
    strongest column's, as many a side as there are (:func:`_faint_sides_off`; the strongest column
    stays). A far pane 1 px wide on a receding wall shows in 3 columns -- its glass and its blur into
    the wall either side at half its departure, or its blur and a column of the next face --, its
    floor's panes in 1-2; :func:`_unblur` takes one column a side before the ends are trimmed, and a
    3-px window of a 1-px pane is twice its facade's median (docs/proposals.md "Eighteenth pass: the
    1.5x rule -- far panes merged with their blur")."""
    r = float(p.window_unblur_narrow_ratio)
    if r <= 0 or len(found) < 3:
        return
    box = np.array([[f[3].y0, f[3].x0, f[3].mask.shape[0], f[3].mask.shape[1]] for f in found], float)
    bid = np.array([f[0] for f in found])
    lev = np.array([f[1] for f in found], float)
    cy, cx = box[:, 0] + box[:, 2] / 2.0, box[:, 1] + box[:, 3] / 2.0
    ids = _window_ids(dev.shape, found)
    for i, f in enumerate(found):
        li = f[3]
        w = li.mask.shape[1]
        if w < 2 or w > p.window_row_pane_max_px or (li.kind or "window") != "window":
            continue
        mate = (bid == f[0]) & (np.abs(lev - f[1]) <= f[2])
        mate[i] = False
        j = np.flatnonzero(mate)
        if j.size < 1:
            continue
        j = j[np.argsort(np.hypot(cx[j] - cx[i], cy[j] - cy[i]))[:4]]
        mw = float(median(box[j, 3]))
        if w <= mw + 1.0:  # a pane 1.5 px wide shows as 1 or 2 px
            continue
        _faint_ends_off(li, i, ids, dev, r, max(int(np.ceil(mw)), 1))  # to the mates' width


def _blur_columns_off(found: list, dev: np.ndarray, ratio: float, dev_own: np.ndarray | None = None,
                      own_ratio: float = 0.0) -> list:
    """The windows less the far panes' blur columns split off as windows of their own: a window of kind
    ``window`` 1 px wide beside another window of its wall (no column between them, half its rows at
    least beside it) whose mean departure from the wall (``dev``, HxW, in window thresholds) is under
    ``ratio`` (``window_blur_column_ratio``) x that window's strongest column's is the other's glass
    blurred into the wall, not a pane (512x256 seeds 0-5: every one under 0.33 false, IoU under 0.1; a
    true 1-px pane beside another is at 0.4 or more; docs/proposals.md "Twentieth pass: the 1.5x rule").
    ``dev_own``: ``dev`` with a face's own colour as the reference where the smooth one missed it
    (:func:`_own_colour_dev`): a window under ``own_ratio`` of its neighbour's by that measure goes too, and
    there its neighbours are the windows beside it that together hold half its rows (the strongest's
    departure the measure; docs/proposals.md "Twenty-second pass: the gable faces")."""
    if ratio <= 0 or len(found) < 2:
        return found

    def profiles(dv: np.ndarray) -> list:
        out = []
        for f in found:
            li = f[3]
            cnt = li.mask.sum(0)
            d = dv[li.y0:li.y0 + li.mask.shape[0], li.x0:li.x0 + li.mask.shape[1]]
            out.append(np.where(cnt > 0, (d * li.mask).sum(0) / np.maximum(cnt, 1), 0.0))
        return out

    prof = profiles(dev)
    prof_own = profiles(dev_own) if dev_own is not None and dev_own is not dev and own_ratio > 0 else None
    box = np.array([[f[3].y0, f[3].x0, f[3].mask.shape[0], f[3].mask.shape[1]] for f in found], int)
    bid = np.array([f[0] for f in found])
    drop = set()
    for i, f in enumerate(found):
        y0, x0, h, w = box[i]
        if w != 1 or (f[3].kind or "window") != "window":
            continue
        side = (bid == f[0]) & ((box[:, 1] + box[:, 3] == x0) | (box[:, 1] == x0 + 1))
        side &= np.minimum(box[:, 0] + box[:, 2], y0 + h) - np.maximum(box[:, 0], y0) >= 0.5 * h
        side[i] = False
        if any(float(prof[i][0]) < ratio * float(prof[j].max()) for j in np.flatnonzero(side)):
            drop.add(i)
        elif prof_own is not None and any(float(prof_own[i][0]) < own_ratio * float(prof_own[j].max())
                                          for j in np.flatnonzero(side)):
            drop.add(i)
        elif prof_own is not None and (dev_own[y0:y0 + h, x0] != dev[y0:y0 + h, x0])[f[3].mask[:, 0]].any():
            # on a face of its own colour, half its rows beside windows of the next column together (a
            # face's edge column beside two panes of a receding row a few rows apart)
            near = (bid == f[0]) & ((box[:, 1] + box[:, 3] == x0) | (box[:, 1] == x0 + 1))
            near &= np.minimum(box[:, 0] + box[:, 2], y0 + h) - np.maximum(box[:, 0], y0) >= 1
            near[i] = False
            js = np.flatnonzero(near)
            rows = np.zeros(h, bool)
            for j in js:
                rows[max(box[j, 0] - y0, 0):max(min(box[j, 0] + box[j, 2] - y0, h), 0)] = True
            if js.size and rows.sum() >= 0.5 * h and \
                    float(prof_own[i][0]) < own_ratio * max(float(prof_own[j].max()) for j in js):
                drop.add(i)
    return [f for i, f in enumerate(found) if i not in drop]


def _own_colour_dev(feat: np.ndarray, ref: np.ndarray, dev: np.ndarray, own: list, p) -> np.ndarray:
    """``dev`` (HxW, departure from the wall reference in window thresholds) with the pixels of each blob
    whose own wall colour :func:`_blob_panes` found (``own``: (y, x, mask, colour (log luminance, Lab a,
    b))) measured against that colour instead: a face the smooth reference missed (a bluish gable at
    512x256 `lights` seed 0) departs from it all over, its far panes' blur between them as much as the
    panes (2.0-2.4 against 2.6), and against its own colour a quarter as much (docs/proposals.md
    "Twenty-second pass: the gable faces"). ``dev`` itself when ``own`` is empty or
    ``window_blur_own_ratio`` is 0."""
    if not own or p.window_blur_own_ratio <= 0:
        return dev
    out = dev.copy()
    t = -np.log(p.window_dark_ratio)
    for y, x, m, c in own:
        h, w = m.shape
        f = feat[y:y + h, x:x + w]
        d = np.maximum(np.abs(f[..., 0] - c[0]) / t,
                       np.hypot(f[..., 1] - c[1], f[..., 2] - c[2]) / p.window_chroma_delta)
        out[y:y + h, x:x + w][m] = d[m]
    return out


def _floor_ends(found: list, dev: np.ndarray, free: np.ndarray, p) -> None:
    """Give a window found in part the rows its floor-mates' sill and lintel lines say its pane has, in
    place: the windows of one floor share their size, so where a pane shows a bright band or a curtain
    over glass of nearly the wall's colour and the thresholds take the band alone, its mates -- found
    whole -- mark where its top and bottom are (docs/proposals.md "Thirteenth pass: window masks at
    512x256"). Mates: the windows of the same wall (``found`` rows [wall id, level, tolerance, Light])
    on its floor whose rows overlap its own, up to six nearest; their tops and bottoms lie on two
    lines (a floor's lintel and sill, straight in the image also on a receding wall): the pair of
    mates whose lines hold the most of them within ``window_mates_fit_px`` (top and bottom residuals
    summed; a pane found in part, a door, a smaller window is off them), half the mates and two at
    least, the lines then fitted to those. A window at most ``window_mates_short`` x the height those
    lines give at its centre, with one end on its line (within a pixel) and the other short of it by
    two rows or more, grows row by row towards the line while the row is ``free`` (building, no other
    window; updated) and departs from the wall (``dev``, HxW, in window thresholds) by a mean of
    ``window_mates_dev`` over its columns. The new rows copy the columns of the end row."""
    short, fit_px, a = float(p.window_mates_short), float(p.window_mates_fit_px), float(p.window_mates_dev)
    if short <= 0 or len(found) < 3:
        return
    H, W = dev.shape
    box = np.array([[f[3].y0, f[3].x0, f[3].mask.shape[0], f[3].mask.shape[1]] for f in found], float)
    bid = np.array([f[0] for f in found])
    lev = np.array([f[1] for f in found], float)
    kind_ok = np.array([(f[3].kind or "window") == "window" for f in found])
    idx = np.arange(len(found))
    top, bot, cx = box[:, 0], box[:, 0] + box[:, 2] - 1, box[:, 1] + (box[:, 3] - 1) / 2.0
    for i, f in enumerate(found):
        li = f[3]
        if not kind_ok[i]:
            continue
        y0, x0, h, w = (int(v) for v in box[i])
        rows = np.minimum(bot, y0 + h - 1) - np.maximum(top, y0) + 1
        mate = (bid == f[0]) & (idx != i) & kind_ok & (np.abs(lev - f[1]) <= f[2]) & (rows > 0)
        j = np.nonzero(mate)[0]
        if j.size < 2:
            continue
        j = j[np.argsort(np.abs(cx[j] - cx[i]))[:6]]
        # the lines most mates lie on (a pane found in part, a door or a shorter window is off them):
        # through each pair of mates, the one with the most mates within fit_px (residuals of top and
        # bottom summed), then fitted to those
        best = None
        # every pair at once (rows in the order of a loop over u < v; the same float operations per
        # element, and the residuals of each row summed in order: the same sums)
        U, V = _triu(j.size)
        A_, B_ = j[U], j[V]
        keep = ~(np.abs(cx[A_] - cx[B_]) < 1.0)
        A_, B_ = A_[keep], B_[keep]
        if A_.size:
            st = (top[B_] - top[A_]) / (cx[B_] - cx[A_])
            sb = (bot[B_] - bot[A_]) / (cx[B_] - cx[A_])
            rel = cx[j][None, :] - cx[A_][:, None]
            res = (np.abs(top[A_][:, None] + st[:, None] * rel - top[j][None, :])
                   + np.abs(bot[A_][:, None] + sb[:, None] * rel - bot[j][None, :]))
            inl = res <= fit_px
            n_in, r_in = inl.sum(1).tolist(), np.where(inl, res, 0.0).sum(1).tolist()
            for q in range(A_.size):
                if best is None or (n_in[q], -r_in[q]) > (int(best.sum()), -best_res):
                    best, best_res = inl[q], r_in[q]
        if best is None or best.sum() < max(2, (j.size + 1) // 2):
            continue  # the mates' ends are no floor's lines
        j = j[best]
        ct, cb = np.polyfit(cx[j], top[j], 1), np.polyfit(cx[j], bot[j], 1)
        pt, pb = int(round(float(np.polyval(ct, cx[i])))), int(round(float(np.polyval(cb, cx[i]))))
        if h > short * (pb - pt + 1):
            continue
        y1 = y0 + h - 1
        if abs(y0 - pt) <= 1 and pb - y1 >= 2:
            ys, src = range(y1 + 1, min(pb, H - 1) + 1), li.mask[-1]
        elif abs(y1 - pb) <= 1 and y0 - pt >= 2:
            ys, src = range(y0 - 1, max(pt, 0) - 1, -1), li.mask[0]
        else:
            continue
        cols = x0 + np.flatnonzero(src)
        n = 0
        for y in ys:
            if not free[y, cols].all() or float(dev[y, cols].mean()) < a:
                break
            n += 1
        if n == 0:
            continue
        add = np.repeat(src[None, :], n, 0)
        if ys.step > 0:
            li.mask = np.concatenate([li.mask, add], 0)
        else:
            li.mask = np.concatenate([add, li.mask], 0)
            li.y0 -= n
        free[li.y0:li.y0 + li.mask.shape[0], x0:x0 + w] &= ~li.mask
        box[i, 0], box[i, 2] = li.y0, li.mask.shape[0]
        top[i], bot[i] = box[i, 0], box[i, 0] + box[i, 2] - 1


def _frame_ends(ctx: Context, found: list, dev: np.ndarray, p) -> list:
    """Give a window found as its top (bottom) part the rest of its pane that its frame outlines: a
    reflection or a curtain band departs from the wall, the glass beyond it barely, and the thresholds
    take the band while the frame -- a side of it in its reveal's shade, a line one pixel wide that the
    candidates' opening removes -- runs on along the pane's side to its bottom rail or sill (docs/proposals.md
    "Fourteenth pass: panes found as their top part"). From each end row of a window of kind ``window``
    (``found`` rows [wall id, level, tolerance, Light]; ``dev``, HxW, departure from the wall in window
    thresholds), an edge column of the window's box walks on while it departs by the thresholds (``dev``
    >= 1) on building pixels, until a cross row: one departing by the thresholds over two thirds of the
    window's columns. The column beyond the edge departs under the thresholds on mean along the walk (a
    frame line has wall beside it; a shadow or a neighbour running on past the side has not). The
    window grows to that row, inclusive, when the walk is three rows or more, the
    window then at most a pane tall (``window_tall_keep_m`` at its depth; twice its height without
    depth), and the glass between (its other columns) departs by ``window_mates_dev`` on mean; the new
    rows copy the columns of the end row. A window whose box lies in the rows added, within the
    window's columns (the pane's rail found alone), is part of it and goes; one the cross row runs into
    (within a row), over 0.6 of the narrower's columns (the pane's band, reached from its rail), is
    joined to it. Returns ``found``."""
    H, W = dev.shape
    B = ctx.labels == BUILDING
    fy = float(ctx.intrinsics.fy)
    strong = (dev >= 1.0) & B
    a = float(p.window_mates_dev)
    gone: set[int] = set()
    for i, f in enumerate(found):
        li = f[3]
        if i in gone or (li.kind or "window") != "window":
            continue
        h, w = li.mask.shape
        if w < 2 or h < 3:
            continue
        z = _median_depth(ctx, li)
        max_h = max(h, int(p.window_tall_keep_m * fy / z)) if z else 2 * h
        x0, x1 = li.x0, li.x0 + w
        best = None
        for down in (True, False):
            end = li.y0 + h - 1 if down else li.y0
            step = 1 if down else -1
            src = li.mask[-1] if down else li.mask[0]
            for c in (x0, x1 - 1):
                if not src[c - x0]:
                    continue
                y, n = end + step, 0
                while 0 <= y < H and h + n + 1 <= max_h and strong[y, c]:
                    n += 1
                    if (strong[y, x0:x1]).mean() >= 2.0 / 3.0:
                        break
                    y += step
                else:
                    continue
                if n < 3:
                    continue
                rows = slice(end + step, y) if down else slice(y + 1, end)
                out = c - 1 if c == x0 else c + 1
                # a frame line has wall beyond it: a darker area running on past the window's side (a
                # shadow, a neighbour) is no line of its pane
                if not 0 <= out < W or float(dev[rows, out].mean()) >= 1.0:
                    continue
                inner = [k for k in range(x0, x1) if k != c and src[k - x0]]
                glass = dev[rows, inner] if inner else np.zeros(0)
                if glass.size and float(glass.mean()) < a:
                    continue
                if best is None or n > best[0]:
                    best = (n, down, src)
        if best is None:
            continue
        n, down, src = best
        ny0 = li.y0 + h if down else li.y0 - n
        cross = ny0 + n - 1 if down else ny0
        add = np.repeat(src[None, :], n, 0)
        if down:
            li.mask = np.concatenate([li.mask, add], 0)
        else:
            li.mask = np.concatenate([add, li.mask], 0)
            li.y0 -= n
        # the pane's other part found alone: a window inside the rows added and the window's columns (its
        # rail), or one the cross row runs into, over most of the narrower's columns (its band), joins it
        for j, g in enumerate(found):
            lj = g[3]
            if j == i or j in gone or (lj.kind or "window") != "window":
                continue
            jh, jw = lj.mask.shape
            inside = lj.y0 >= ny0 - 1 and lj.y0 + jh <= ny0 + n + 1 and lj.x0 >= x0 - 1 and lj.x0 + jw <= x1 + 1
            ov = min(x1, lj.x0 + jw) - max(x0, lj.x0)
            meets = lj.y0 - 1 <= cross <= lj.y0 + jh and ov >= 0.6 * min(w, jw)
            if not (inside or meets):
                continue
            gone.add(j)
            if inside:
                continue
            uy0, ux0 = min(li.y0, lj.y0), min(li.x0, lj.x0)
            uy1 = max(li.y0 + li.mask.shape[0], lj.y0 + jh)
            ux1 = max(li.x0 + li.mask.shape[1], lj.x0 + jw)
            m = np.zeros((uy1 - uy0, ux1 - ux0), bool)
            m[li.y0 - uy0:li.y0 - uy0 + li.mask.shape[0], li.x0 - ux0:li.x0 - ux0 + li.mask.shape[1]] |= li.mask
            m[lj.y0 - uy0:lj.y0 - uy0 + jh, lj.x0 - ux0:lj.x0 - ux0 + jw] |= lj.mask
            li.y0, li.x0, li.mask = uy0, ux0, m
            li.confidence = max(li.confidence, lj.confidence)
    return [f for j, f in enumerate(found) if j not in gone]


def _join_split_panes(ctx: Context, found: list, dev: np.ndarray, p, log: list | None = None) -> list:
    """Join the parts of one pane that a frame bar, a curtain's edge or something in front splits (a
    mullion, a transom, a pole, a branch), in place: each part passed the window tests alone, while an
    annotator outlines the pane (docs/proposals.md "Fourteenth pass: a pane split in parts"). Two
    windows of kind ``window`` (``found`` rows [wall id, level, tolerance, Light]; not one wall id:
    :func:`facades` cuts the wall at a post in front), side by side on one floor (levels within the
    tolerance) or one above the other, their extents across the split overlapping by 0.6 of the
    smaller, join when

    (a) the gap is not wall. Side by side: at most ``window_split_gap_m`` wide at their depth (2 px at
    least), every column of it over their common rows departing from the wall (``dev``, HxW, in window
    thresholds) by a mean of ``window_split_gap_dev`` -- a frame bar or glass, not a pier of wall -- or
    mostly labelled in front of the wall; or covered in front all along and at most both parts' width.
    One above the other (no pier parts two panes of a floor that way): every row so, up to both parts'
    height;
    (b) the union box is the floor's pane: the floor-mates (windows whose rows overlap the union's by
    half, depth within 15 %, the six nearest, two at least) are of one size (two in three within a
    quarter of their median and a pixel) and the union is within ``window_split_size`` x their median
    height and width plus a pixel -- half a pixel along the split, since two 1-px panes and their
    blurred pier, 3 px, depart like a 2-px pane split by a bar. Two whole panes side by side are twice
    a pane.

    The joined mask is the parts and the gap's pixels not labelled in front (a bar is the pane's, a pole
    in front is not); its confidence the larger. ``log``: each pair tested, with its measures (tools)."""
    gap_m, gdev, size = float(p.window_split_gap_m), float(p.window_split_gap_dev), float(p.window_split_size)
    if gap_m <= 0 or len(found) < 4:
        return found
    fy = float(ctx.intrinsics.fy)
    front = _in_front(ctx)
    box = np.array([(f[3].y0, f[3].x0, f[3].y0 + f[3].mask.shape[0], f[3].x0 + f[3].mask.shape[1])
                    for f in found], np.int64).reshape(-1, 4)
    wall = np.array([f[0] for f in found])
    lev = np.array([f[1] for f in found], float)
    tol = np.array([f[2] for f in found], float)
    ok = np.array([(f[3].kind or "window") == "window" for f in found])
    z = np.array([np.nan if (v := _median_depth(ctx, f[3])) is None else v for f in found], float)
    i = 0
    while i < len(found):
        if not ok[i]:
            i += 1
            continue
        ext = box[:, 2:] - box[:, :2]
        cx = 0.5 * (box[:, 1] + box[:, 3])
        done = False
        for ax in (1, 0):
            co = 1 - ax
            gap = box[:, ax] - box[i, 2 + ax]  # windows after i along the axis
            ovl = np.minimum(box[i, 2 + co], box[:, 2 + co]) - np.maximum(box[i, co], box[:, co])
            cand = ok & (gap >= 1) & (ovl >= 0.6 * np.minimum(ext[i, co], ext[:, co])) & (ovl > 0)
            if ax == 1:  # side by side: one floor (one above the other: a part's level is not its pane's)
                cand &= np.abs(lev - lev[i]) <= tol[i]
            cand[i] = False
            gmax = max(2.0, gap_m * fy / z[i]) if np.isfinite(z[i]) else 2.0
            cand &= gap <= np.maximum(gmax, ext[i, ax] + ext[:, ax])  # no gap passes beyond both parts
            for j in np.flatnonzero(cand)[np.argsort(gap[cand], kind="stable")].tolist():
                g = int(gap[j])
                a0, a1 = max(box[i, co], box[j, co]), min(box[i, 2 + co], box[j, 2 + co])
                sl = [slice(a0, a1), slice(a0, a1)]
                sl[ax] = slice(box[i, 2 + ax], box[j, ax])
                fr = front[tuple(sl)].mean(co) if g else np.zeros(0)
                dv = dev[tuple(sl)].mean(co) if g else np.zeros(0)
                bar = bool(((fr >= 0.5) | (dv >= gdev)).all())
                covered = bool(g and (fr >= 0.5).all())
                # side by side: thin, or a post in front all along; one above the other no pier parts
                # two panes of a floor, so as high as the union's size allows (a transom, faint glass)
                gap_ok = bar and (g <= gmax or ax == 0) or (covered and g <= ext[i, ax] + ext[j, ax])
                if not gap_ok and log is None:
                    continue
                uy0, uy1 = min(box[i, 0], box[j, 0]), max(box[i, 2], box[j, 2])
                u = np.array([uy1 - uy0, max(box[i, 3], box[j, 3]) - min(box[i, 1], box[j, 1])])
                # the floor's panes: windows whose rows overlap the union's by half the shorter (a wall
                # id stops at a post in front: facades() cuts there), at its depth
                rov = np.minimum(box[:, 2], uy1) - np.maximum(box[:, 0], uy0)
                mates = ok & (rov >= 0.5 * np.minimum(ext[:, 0], u[0])) & (rov > 0)
                if np.isfinite(z[i]):
                    mates &= np.abs(z - z[i]) <= 0.15 * z[i]
                mates[[i, j]] = False
                k = np.flatnonzero(mates)
                k = k[np.argsort(np.abs(cx[k] - cx[i]), kind="stable")[:6]]
                med = median(ext[k], 0) if k.size >= 2 else None
                # a floor of one pane size (two in three of the mates within a quarter of their median
                # and a pixel), and the union is that size: two whole panes side by side are twice it;
                # along the split within half a pixel (two 1-px panes and their pier are 3 px, a 2-px
                # floor's 1.5x: at 1-2 px a pier blurred by its panes departs like a bar)
                allow = np.full(2, 1.0)
                allow[ax] = 0.5
                size_ok = med is not None \
                    and 3 * int((np.abs(ext[k] - med) <= 0.25 * med + 1).all(1).sum()) >= 2 * k.size \
                    and bool((np.abs(u - med) <= (size - 1) * med + allow).all())
                if log is not None:
                    log.append(dict(a=(found[i][3].y0, found[i][3].x0, found[i][3].mask.copy()),
                                    b=(found[j][3].y0, found[j][3].x0, found[j][3].mask.copy()), ax=ax, gap=g, gmax=gmax, bar=bar,
                                    covered=covered, union=u.tolist(),
                                    med=None if med is None else med.tolist(), mates=int(k.size), mext=ext[k].tolist(),
                                    dev=dv.tolist(), front=fr.tolist(), joined=gap_ok and size_ok))
                if not (gap_ok and size_ok):
                    continue
                a, b = found[i][3], found[j][3]
                y0, x0 = int(box[[i, j], 0].min()), int(box[[i, j], 1].min())
                y1, x1 = int(box[[i, j], 2].max()), int(box[[i, j], 3].max())
                m = np.zeros((y1 - y0, x1 - x0), bool)
                m[a.y0 - y0:a.y0 - y0 + a.mask.shape[0], a.x0 - x0:a.x0 - x0 + a.mask.shape[1]] |= a.mask
                m[b.y0 - y0:b.y0 - y0 + b.mask.shape[0], b.x0 - x0:b.x0 - x0 + b.mask.shape[1]] |= b.mask
                if g:  # the bar between them is the pane's; what stands in front is not
                    gs = [slice(a0 - (y0, x0)[co], a1 - (y0, x0)[co])] * 2
                    gs[ax] = slice(box[i, 2 + ax] - (y0, x0)[ax], box[j, ax] - (y0, x0)[ax])
                    m[tuple(gs)] |= ~front[tuple(sl)]
                a.y0, a.x0, a.mask = y0, x0, m
                a.confidence = max(a.confidence, b.confidence)
                a.cut = a.cut and b.cut
                box[i] = (y0, x0, y1, x1)
                z[i] = np.nan if (v := _median_depth(ctx, a)) is None else v
                del found[j]
                box, wall, lev, tol, ok, z = (np.delete(v, j, 0) for v in (box, wall, lev, tol, ok, z))
                if j < i:
                    i -= 1
                done = True
                break
            if done:
                break
        if not done:
            i += 1
    return found


def _cap_lit(p, wins: list, area: float) -> list:
    """The most confident windows covering at most ``window_max_lit_share`` of a region of ``area``
    pixels (a lit facade is lit per room, not as a whole)."""
    total, final = 0.0, []
    for f in sorted(wins, key=lambda f: -f[3].confidence):
        a = float(f[3].mask.sum())
        if total + a <= p.window_max_lit_share * area:
            final.append(f)
            total += a
    return final


def _split_blocks(ctx: Context, row: list, ref: np.ndarray) -> list[list]:
    """Split one floor of a building region into the facades it crosses (one windows_group each, as
    an annotator groups them): walking along the row, a new facade starts where the wall around the
    windows changes (log luminance by more than ``window_block_lum``, or chroma by more than
    ``window_block_chroma``), where the window kind or height changes (by more than
    ``window_block_height`` relative, against the last window and the median of the last three: each
    building has its own windows, while heights along one receding facade shrink smoothly)."""
    p = ctx.params
    if len(row) < 2:
        return [row]

    def desc(f):
        li = f[3]
        h, w = li.mask.shape
        wall = ref[li.y0:li.y0 + h, li.x0:li.x0 + w][li.mask].mean(0)
        return wall, h, li.x0 + w / 2.0, getattr(li, "kind", None) or "window"

    row = sorted(row, key=lambda f: f[3].x0)
    info = [desc(f) for f in row]
    out = [[row[0]]]
    for k in range(1, len(row)):
        (wa, ha, _, ka), (wb, hb, _, kb) = info[k - 1], info[k]
        new = abs(float(wa[0] - wb[0])) > p.window_block_lum or \
            float(np.hypot(wa[1] - wb[1], wa[2] - wb[2])) > p.window_block_chroma or ka != kb
        if not new and ka == "window":
            # heights of neighbours on one receding facade shrink smoothly; a new building's jump
            prev = [info[j][1] for j in range(max(0, k - 3), k)]
            new = abs(hb - ha) > p.window_block_height * max(ha, hb) and \
                abs(hb - float(median(prev))) > p.window_block_height * max(hb, float(median(prev))) \
                and max(ha, hb) >= 6
        if new:
            out.append([row[k]])
        else:
            out[-1].append(row[k])
    return out


def fl_level(ctx: Context, li: Light) -> float:
    """A window's floor level: its centre's height above the ground (m) with depth, else its centre row."""
    z = _median_depth(ctx, li)
    cy = li.y0 + li.mask.shape[0] / 2.0
    return float(ctx.height_above_ground(cy, z)) if z is not None else float(cy)


def _wall_beyond(ctx: Context, li: Light, ax: int, end: bool, r: int = 6) -> float | None:
    """Median depth (m) of the wall (building pixels) just beyond window ``li`` along image axis ``ax``
    (1: the ``r`` columns right of it if ``end``, else left; 0: the rows below / above), over its rows
    (columns); None without depth or wall there. A post or a trunk in front of a pane pulls the depth
    of the glass either side of it towards its own (a depth map, estimated or filtered, bleeds across
    the occluder's edges over several pixels), so two parts of one pane differ in median depth by how
    much of each lies in that bleed; the wall on their far sides does not (docs/proposals.md "Eleventh
    pass: parts of a pane either side of a post")."""
    if ctx.depth is None:
        return None
    h, w = li.mask.shape
    H, Wd = ctx.depth.shape
    if ax == 1:
        c0, c1 = (li.x0 + w, li.x0 + w + r) if end else (li.x0 - r, li.x0)
        sl = (slice(max(li.y0, 0), min(li.y0 + h, H)), slice(max(c0, 0), min(c1, Wd)))
    else:
        r0, r1 = (li.y0 + h, li.y0 + h + r) if end else (li.y0 - r, li.y0)
        sl = (slice(max(r0, 0), min(r1, H)), slice(max(li.x0, 0), min(li.x0 + w, Wd)))
    d = ctx.depth[sl][ctx.labels[sl] == BUILDING]
    d = d[np.isfinite(d)]
    return float(median(d)) if d.size >= 4 else None


def _median_depth(ctx: Context, li: Light) -> float | None:
    if ctx.depth is None:
        return None
    h, w = li.mask.shape
    # asked ~1400 times a frame, mostly again for the same window: memoised per context on the
    # window's box and mask (a window grown or trimmed is another key)
    memo = ctx.__dict__.setdefault("_window_median_depth", {})
    key = (li.y0, li.x0, h, w, np.packbits(li.mask).tobytes())
    if key in memo:
        return memo[key]
    d = ctx.depth[li.y0:li.y0 + h, li.x0:li.x0 + w][li.mask]
    d = d[np.isfinite(d)]
    z = float(median(d)) if d.size else None
    memo[key] = z
    return z


def _soffit_like(ctx: Context, li: Light) -> bool:
    """A wide, low (or square) window on a face the depth reads as far from vertical: a balcony soffit
    seen from below, a slab's face (``window_soffit_*``; docs/proposals.md "Nineteenth pass: false windows
    on balcony soffits"). Per column of the window (3 rows of depth at least) the least-squares rise of
    the height above the ground per row, over the rise a vertical wall at that depth gives (z / fy); the
    median over the columns under ``window_soffit_tilt`` (``window_soffit_square_tilt`` for a window under
    ``window_soffit_aspect`` times as wide as tall but as wide as tall, 4 rows at least)."""
    p = ctx.params
    h, w = li.mask.shape
    tilt = p.window_soffit_tilt if w >= p.window_soffit_aspect * h else \
        p.window_soffit_square_tilt if w >= h >= 4 else 0.0
    if ctx.depth is None or p.window_soffit_tilt <= 0 or h < 3 or tilt <= 0:
        return False
    z = ctx.depth[li.y0:li.y0 + h, li.x0:li.x0 + w].astype(np.float64)
    ok = li.mask & np.isfinite(z) & (z > 0)
    n = ok.sum(0)
    good = n >= 3
    if not good.any():
        return False
    ok, z, n = ok[:, good], np.where(ok, z, 0.0)[:, good], n[good]
    fy, cp, sp = float(ctx.intrinsics.fy), np.cos(p.camera_pitch_rad), np.sin(p.camera_pitch_rad)
    r = np.arange(h, dtype=np.float64)[:, None]
    down = np.where(ok, ((li.y0 + r - ctx.intrinsics.cy) * cp / fy + sp) * z, 0.0)  # metres below the camera
    rm = (r * ok).sum(0) / n
    dm = down.sum(0) / n
    slope = ((r - rm) * (down - dm) * ok).sum(0) / np.maximum(((r - rm) ** 2 * ok).sum(0), 1e-9)
    zc = np.array([median(z[ok[:, k], k]) for k in range(z.shape[1])])  # each column's depth
    return float(median(slope / (zc / fy))) < tilt


def _wedge_like(ctx: Context, li: Light) -> bool:
    """A window at the frame's top shaped as a solid triangle of one colour (``window_wedge_*``;
    docs/proposals.md "Twentieth pass: the 40 % lit share"): touching the top row, at least
    ``window_wedge_min_px`` px each way, its convex hull at most ``window_wedge_hull_fill`` of its box, its
    pixels at least ``window_wedge_mask_fill`` of its hull, a row or a column of it at least ``window_wedge_base``
    of the box across (a triangle's base), and ``window_wedge_one_colour`` of its pixels within the window
    threshold (-ln ``window_dark_ratio``, log luminance) of its median. A pane's image has vertical sides and
    a top and a bottom along its wall's rows: a quadrilateral whose hull fills most of its box, or, receding
    steeply near the frame's top, a diagonal band with no row or column across its box; the frame cuts it
    along a row. A triangle there is a face in shade under a roof's or a gable's slope. (Below the frame's top
    a pane's visible part is a triangle where a tree, a post or a cast shadow's edge cuts it diagonally.)"""
    p = ctx.params
    h, w = li.mask.shape
    if p.window_wedge_hull_fill <= 0 or min(h, w) < p.window_wedge_min_px or li.y0 > 0:
        return False
    sub = li.mask.astype(np.uint8)
    hull = np.zeros_like(sub)
    cv2.fillConvexPoly(hull, cv2.convexHull(cv2.findNonZero(sub)), 1)
    n_hull = int(hull.sum())
    if n_hull > p.window_wedge_hull_fill * h * w or int(sub.sum()) < p.window_wedge_mask_fill * n_hull:
        return False
    # a triangle has a side across its box (the frame's top, a vertical corner); a receding pane's image near
    # the frame's top or bottom, a diagonal band of short vertical sides, has none
    if not (sub.sum(1).max() >= p.window_wedge_base * w or sub.sum(0).max() >= p.window_wedge_base * h):
        return False
    # one colour, as a face in shade is: a pane merged with a wedge of wall beside it is not this test's
    lum = np.log(np.maximum(ctx.lum[li.y0:li.y0 + h, li.x0:li.x0 + w][li.mask], 1e-4))
    return bool(np.mean(np.abs(lum - median(lum)) <= -np.log(p.window_dark_ratio)) >= p.window_wedge_one_colour)


def _wedge_pane(ctx: Context, li: Light) -> Light | None:
    """The pane inside a frame-top wedge (:func:`_wedge_like`), or None: the wedge's pixels departing from
    its median log luminance by more than the window threshold (-ln ``window_dark_ratio``: a pane's frame and
    glint; its glass is often in the wall's own luminance), their largest 8-connected part filled to its
    convex hull within the wedge, kept when at least ``window_wedge_pane_min_px`` px each way with the wedge
    either side of it (a patch at the wedge's end is its shade), filling half its box (a diagonal streak along
    the wedge's edge does not) and under ``window_wedge_pane_share`` of the wedge's pixels. A gable or a wall
    under a roof's slope cut by the frame's top is a triangle of one colour with its window in it
    (docs/proposals.md "Twenty-first pass: the 1.5x rule -- the pane in a frame-top wedge")."""
    p = ctx.params
    if p.window_wedge_pane_min_px <= 0:
        return None
    h, w = li.mask.shape
    lum = np.log(np.maximum(ctx.lum[li.y0:li.y0 + h, li.x0:li.x0 + w], 1e-4))
    off = li.mask & (np.abs(lum - median(lum[li.mask])) > -np.log(p.window_dark_ratio))
    if not off.any():
        return None
    n, lab, stats, _ = cv2.connectedComponentsWithStats(off.astype(np.uint8), connectivity=8)
    k = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    x, y, cw, ch = (int(v) for v in stats[k, :4])
    if min(cw, ch) < p.window_wedge_pane_min_px or x == 0 or x + cw >= w \
            or not (li.mask[y:y + ch, x - 1].any() and li.mask[y:y + ch, x + cw].any()):
        return None
    part = (lab[y:y + ch, x:x + cw] == k).astype(np.uint8)
    filled = np.zeros_like(part)
    cv2.fillConvexPoly(filled, cv2.convexHull(cv2.findNonZero(part)), 1)
    filled = filled.astype(bool) & li.mask[y:y + ch, x:x + cw]
    if filled.sum() > p.window_wedge_pane_share * li.mask.sum() or filled.sum() < 0.5 * cw * ch:
        return None
    return Light(li.class_id, li.y0 + y, li.x0 + x, filled, li.confidence, kind=li.kind)


def propose(ctx: Context) -> list[Group]:
    """Window instances in one windows_group per floor of each wall (:func:`facades`).

    Candidates are building pixels whose luminance differs from the local wall
    (:func:`wall_reference`) by more than ``window_dark_ratio`` either way (dark glass, bright
    reflections and frames), or whose chromaticity differs (tinted glass). A blob whose columns
    (rows) run nearly empty between fuller ones is first cut there (:func:`_occupancy_split`). Each
    blob is filled to its convex hull (frames, curtains and mullions split a pane) and kept when its
    height is plausible (``window_height_m`` with depth; a blob cut off at its top or bottom by the
    frame or something in front, :func:`_cut_off`, may be lower: it is a pane's visible part, and
    the facade lattice is fitted without it) and it fills its box
    (``window_min_fill``); a blob failing the fill or size test is cut below (above) a band it fills
    across at its top (bottom) into its parts (:func:`_band_split`), else eroded, split into its parts
    and each part grown back and tested again (``window_split_steps`` times at most). A darker blob
    with the wall's own colour, or running down to the ground with little tint, is a cast shadow
    (``window_shadow_*``; blobs of at least ``window_shadow_min_m2`` on the wall) and dropped. Then the grid per wall (:func:`regularise`). Floors:
    blobs of one wall whose centre heights (with
    depth; else image rows) lie within ``window_floor_tol_m`` (else half a window). Confidence
    0.35 + 0.25 x fill + up to 0.2 for contrast + 0.2 when its floor has >= 3 windows, then rescored
    from the contrast to the wall around it and its height (:func:`window_confidence.window_confidence`).
    """
    p = ctx.params
    B = ctx.labels == BUILDING
    if not B.any():
        return []
    H, W = ctx.shape
    feat = _features(ctx)
    if ctx.depth is None:  # a bare image: a brick facade's courses are not panes (docs/proposals.md "Twelfth pass")
        feat, _ = _texture_walls(feat, B, p)
    ref = wall_reference(feat, B, p)
    ratio = feat[..., 0] - ref[..., 0]
    chroma = np.hypot(feat[..., 1] - ref[..., 1], feat[..., 2] - ref[..., 2])
    t = -np.log(p.window_dark_ratio)
    inner = B
    if p.window_skip_border:  # pixels on the building's outline against sky or foliage blend with them
        soft = _in_labels(ctx.labels, (SKY, VEGETATION)).astype(np.uint8)
        inner = B & ~(cv2.dilate(soft, np.ones((3, 3), np.uint8)) > 0)
    cand = inner & ((np.abs(ratio) > t) | (chroma > p.window_chroma_delta))  # _differs, from ratio and chroma
    cand = _open2(cand) if min(H, W) >= 512 else cand
    bld = facades(ctx, B, feat, cand)  # wall planes: grids, floors and the lit cap are per wall
    from scipy import ndimage

    boxes = ndimage.find_objects(bld)  # each wall's box, found once (a full-image pass each time)
    ref2 = rereference_walls(feat, bld, cand, ref, p, boxes)
    if ref2 is not ref:  # a narrow wall of its own colour took its neighbours' as its reference
        ref = ref2
        ratio = feat[..., 0] - ref[..., 0]
        chroma = np.hypot(feat[..., 1] - ref[..., 1], feat[..., 2] - ref[..., 2])
        cand = inner & ((np.abs(ratio) > t) | (chroma > p.window_chroma_delta))
        cand = _open2(cand) if min(H, W) >= 512 else cand
    fy = float(ctx.intrinsics.fy)
    found = []  # [building id, centre height or row, floor tolerance, Light]
    own: list = []  # blobs whose own wall colour _blob_panes found: (y, x, mask, colour)

    def accept(y: int, x: int, sub: np.ndarray) -> str | None:
        """Keep the blob ``sub`` at (y, x) as a window, or say why not ("small", "size", "fill")."""
        h, w = sub.shape
        a = int(sub.sum())
        if a < p.window_min_area_px or h < 2:
            return "small"
        z = None
        cut = False  # a pane's visible part, cut by the frame or something in front: not its size
        if ctx.depth is not None:
            d = ctx.depth[y:y + h, x:x + w][sub]
            d = d[np.isfinite(d)]
            if d.size:
                z = float(median(d))
        if z is not None:
            # Height, not area: facades recede, so a pane's image width is foreshortened but its height is not.
            height_m = h * z / fy
            if height_m < p.window_height_m[0]:
                if not (p.window_cut_any_height and _cut_off(ctx.labels, y, x, sub)):
                    return "small"  # a whole pane is taller; what a car, a tree or the frame cuts shows less
                cut = True
            if height_m > p.window_height_m[1] or w * z / fy > p.window_height_m[1]:
                return "size"
        elif a > 0.02 * H * W:
            return "size"
        if w < 2:
            filled = sub.copy()
        else:
            hull = cv2.convexHull(cv2.findNonZero(sub.astype(np.uint8)))
            filled = np.zeros((h, w), np.uint8)
            cv2.fillConvexPoly(filled, hull, 1)
            filled = filled.astype(bool) & B[y:y + h, x:x + w]
        # of the box's pixels not hidden: a tree, a pole or a car in front takes a pane's corner
        hidden = int((~_in_labels(ctx.labels[y:y + h, x:x + w], (BUILDING, SKY))).sum()) if p.window_fill_unhidden else 0
        fill = filled.sum() / float(max(w * h - hidden, 1))
        if fill < p.window_min_fill:
            return "fill"
        contrast = float(median(np.abs(ratio[y:y + h, x:x + w][sub])))
        dark = float(median(ratio[y:y + h, x:x + w][sub]))
        if p.window_shadow_chroma > 0 and np.log(p.window_shadow_ratio) < dark < 0 \
                and (z is None or a * (z / fy) ** 2 >= p.window_shadow_min_m2):
            tint = float(median(chroma[y:y + h, x:x + w][sub]))
            # A pane sits on a sill; a shadow runs down to the facade's foot on the ground.
            below = np.zeros(w, bool)
            rows = h - 1 - np.argmax(sub[::-1], axis=0)               # lowest blob pixel per column
            has = sub.any(0)
            yy = np.minimum(y + rows + 1, H - 1)
            below[has] = _in_labels(ctx.labels[yy[has], (x + np.arange(w))[has]], GROUND)
            footed = below[has].mean() > 0.5 if has.any() else False
            if tint < p.window_shadow_chroma or (footed and tint < p.window_shadow_chroma_footed):
                return "shadow"  # the wall's own colour, only darker: a cast shadow, not glass
        if p.window_ring_px > 0 and not _stands_out(feat, B, y, x, sub, p):
            return "flat"  # no different from the wall right around it: a wall-colour edge, not a pane
        ys, xs = np.nonzero(filled)
        cy_ = y + ys.mean()
        b_id = int(np.bincount(bld[y:y + h, x:x + w][filled]).argmax())
        if z is not None:
            level, tol = float(ctx.height_above_ground(cy_, z)), p.window_floor_tol_m
        else:
            level, tol = float(cy_), max(2.0, h / 2.0)
        conf = 0.35 + 0.25 * min(1.0, (fill - p.window_min_fill) / (1 - p.window_min_fill + 1e-6)) \
            + 0.2 * min(1.0, contrast / (3 * t))
        li = Light(WINDOW_BUILDING, y, x, filled, conf)
        li.cut = cut
        found.append([b_id, level, tol, li])
        return None

    dev_all = np.maximum(np.abs(ratio) / t, chroma / p.window_chroma_delta)  # once: full-image
    dev_all.flags.writeable = False  # (read in slices by the blobs' tests and the steps after the grid)
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    rejects = []  # blobs too large or too ragged for one window: the facade grid may cut them (regularise)
    judge = ctx.depth is not None  # (pieces are judged with depth only: _dead_pieces)

    def visit(y0: int, x0: int, m: np.ndarray, depth_: int, kids: list) -> None:
        """One blob: its windows to ``found``, its rejects to ``rejects``, the pieces it is cut into to
        ``kids`` as (y, x, mask, depth, judged) in the order the loop pushes them (judged: dropped when they
        cannot give a window, :func:`_dead_pieces`)."""
        pieces = _occupancy_split(m, p.window_gap_occupancy)
        if len(pieces) > 1:  # panes side by side (or stacked) joined by a frame or a sill line
            kids.extend((y0 + py, x0 + px, pm, depth_, judge) for py, px, pm in pieces)
            return
        why = accept(y0, x0, m)
        if why is None and p.window_row_gap_contrast > 0 and m.shape[1] >= 3:
            # kept as one window, but a pixel of it spans so much wall that a pane is a few pixels and
            # a mullion a fraction of one (a dip is wall), and it is longer along its wall than any
            # window or a pixel is most of a pane: a receding row of panes a pixel apart merged by
            # their blur (_row_split; its length from the depth only for a blob it would cut)
            dev = dev_all[y0:y0 + m.shape[0], x0:x0 + m.shape[1]]
            pieces = _row_split(m, dev, p, 0.0)
            ext = _extent_m(ctx, y0, x0, m) if pieces else None
            if ext is not None and ext[0] >= p.window_row_min_m_per_px * (m.shape[1] - 1) \
                    and (ext[0] > p.window_height_m[1] or ext[0] >= p.window_row_wall_m_per_px * (m.shape[1] - 1)):
                pieces = _row_split(m, dev, p, p.window_height_m[0] * fy / ext[1])
                if pieces:
                    found.pop()
                    kids.extend((y0 + py, x0 + px, pm, p.window_split_steps + 1, False) for py, px, pm in pieces)
                    return
        if why is None and depth_ == 0 and p.window_blob_row_min_panes > 0:
            # kept as one window, but a row of panes on a face of its own colour that the wall reference
            # missed: the face between them is candidate too, and the blob passes as one window
            col: list = []
            inner = _panes_side_by_side(ctx, feat, y0, x0, m, p, col)
            if inner:
                own.extend((y0, x0, m, c) for c in col[:1])
                found.pop()
                kids.extend((y0 + py, x0 + px, pm, p.window_split_steps + 1, False) for py, px, pm in inner)
                return
        ground = why is None and min(m.shape) >= 8 and _on_ground_floor(ctx, y0, x0, m)
        if why is None and p.window_trim_wall_share < 1 and depth_ <= p.window_split_steps \
                and min(m.shape) >= 8 and (ground or p.window_trim_any_floor):
            # shop glazing and a strip of the wall beside it (an awning or a fascia over it, a pier): the
            # parts of other colours than the wall around it, each a pane's rectangle, judged instead
            wall = _wall_coloured(feat, B, y0, x0, m, p)
            if wall.sum() >= p.window_trim_wall_share * m.sum():
                parts = list(components(m & ~wall, p.window_min_area_px, connectivity=4))
                if not ground and all(a < p.window_trim_upper_share * m.sum() for *_, a in parts):
                    parts = []  # (none large enough to be the one part the test below keeps: no hulls)
                parts = [(py, px, pm) for py, px, pm, _ in parts if _hull_fill(pm) >= p.window_trim_min_fill]
                if not ground and (len(parts) != 1 or parts[0][2].sum() < p.window_trim_upper_share * m.sum()):
                    parts = []
                if parts:
                    whole = found.pop()
                    n = len(found)
                    for py, px, pm in parts:
                        accept(y0 + py, x0 + px, pm)
                    # the glass is most of what is not wall: a fleck of another colour is not
                    if sum(int(f[3].mask.sum()) for f in found[n:]) >= int((m & ~wall).sum()) / 3.0:
                        for f in found[n:]:
                            f[3].shop_front = ground  # ground-floor glazing under its fascia: a shop front
                        return
                    del found[n:]
                    found.append(whole)
        if why in ("fill", "size"):
            rejects.append((y0, x0, m))
        if why == "size" and depth_ == 0 and p.window_blob_wall_share > 0:
            # A wall piece whose colour the reference missed, with its panes: one blob too large for
            # a window. Its own colour is the mode of it; what differs from that are its panes.
            col = []
            inner = _blob_panes(feat, y0, x0, m, p, col)
            if inner:
                own.extend((y0, x0, m, c) for c in col[:1])
                kids.extend((y0 + py, x0 + px, pm, p.window_split_steps + 1, False) for py, px, pm in inner)
                return
        if why in ("fill", "size") and depth_ <= p.window_split_steps and p.window_band_split_share > 0:
            # Panes hanging from a band across their tops (or standing on one): a fascia, a cornice or a
            # lintel strip the reference calls different joins a floor's panes into one blob
            pieces = _band_split(m, p.window_band_split_share, p.window_min_area_px, p.window_band_part_ratio)
            if pieces:
                kids.extend((y0 + py, x0 + px, pm, depth_ + 1, False) for py, px, pm in pieces)
                return
        if why in ("fill", "size") and depth_ <= p.window_split_steps and p.window_gap_contrast > 0:
            # Panes of a receding row merged across one-pixel walls: cut where the wall shows through.
            dev = dev_all[y0:y0 + m.shape[0], x0:x0 + m.shape[1]]
            pieces = _gap_split(m, dev, p.window_gap_contrast)
            if len(pieces) > 1:
                kids.extend((y0 + py, x0 + px, pm, p.window_split_steps + 1, judge) for py, px, pm in pieces)
                return
        if why in ("fill", "size") and depth_ < p.window_split_steps:
            # Panes joined by thin bridges (a shadow edge, 1-px gaps far away): erode, split, grow back.
            er = cv2.erode(m.astype(np.uint8), cross) > 0
            parts = list(components(er, 1, connectivity=4))
            if len(parts) > 1 or (parts and depth_ + 1 < p.window_split_steps):
                grown_parts = []
                for py, px, pm, _ in parts:
                    # grown by the cross within its box and a pixel around it (a textured wall's blob
                    # erodes into a thousand parts: each over the whole blob's box took a second)
                    ga, gb = max(py - 1, 0), min(py + pm.shape[0] + 1, m.shape[0])
                    gc, gd = max(px - 1, 0), min(px + pm.shape[1] + 1, m.shape[1])
                    grown = np.zeros((gb - ga, gd - gc), np.uint8)
                    grown[py - ga:py - ga + pm.shape[0], px - gc:px - gc + pm.shape[1]] = pm
                    grown = (cv2.dilate(grown, cross) > 0) & m[ga:gb, gc:gd]
                    ys, xs = np.nonzero(grown)
                    gy0, gx0 = ys.min(), xs.min()
                    grown_parts.append((ga + gy0, gc + gx0, grown[gy0:ys.max() + 1, gx0:xs.max() + 1]))
                kids.extend((y0 + gy0, x0 + gx0, gm, depth_ + 1, judge and len(grown_parts) > 1)
                            for gy0, gx0, gm in grown_parts)

    # The blobs as a stack (the last pushed first), visited a generation at a time: the pieces the blobs of
    # one generation are cut into are judged together (_dead_pieces; per blob, _live_pieces' tables took
    # ~10 % of the textured street's time), then the windows, rejects and own colours are put in the stack's
    # order.
    blobs = _first_blobs(ctx, cand, fy, p)  # less the blobs that cannot give a window
    spans: list = [None] * len(blobs)  # per blob visited: its range of found, of rejects and of own
    pushed: list = [[] for _ in blobs]  # per blob visited: the ids of its live pieces, in push order
    level = list(enumerate(blobs))
    while level:
        kids: list = []
        for i, (y0, x0, m, depth_) in level:
            f0, r0, o0 = len(found), len(rejects), len(own)
            got: list = []
            visit(y0, x0, m, depth_, got)
            spans[i] = (f0, len(found), r0, len(rejects), o0, len(own))
            kids.extend((i, k) for k in got)
        dead = _dead_pieces(ctx, [k[:3] for _, k in kids], fy, p).tolist()
        level = []
        for (i, k), dd in zip(kids, dead):
            if dd:
                continue
            pushed[i].append(len(spans))
            level.append((len(spans), k[:4]))
            spans.append(None)
            pushed.append([])
    walk, order_f, order_r, order_o = list(range(len(blobs))), [], [], []
    while walk:
        i = walk.pop()
        f0, f1, r0, r1, o0, o1 = spans[i]
        order_f.extend(found[f0:f1])
        order_r.extend(rejects[r0:r1])
        order_o.extend(own[o0:o1])
        walk.extend(pushed[i])
    found, rejects, own = order_f, order_r, order_o
    found = regularise(ctx, found, ratio, chroma, B, bld, rejects, boxes)
    # The grid and the lattice propose cells of their own: the same tests on every final window.
    if found and ctx.depth is not None and p.window_ledge_step_m > 0 and p.window_ledge_min_share > 0:
        # (_ledge_split's first test for all windows at once: most are flush with their wall)
        c, _, _, area = _pieces_columns(ctx, [(f[3].y0, f[3].x0, f[3].mask) for f in found])
        may = _may_ledge(ctx, c, len(found) + 1, area, p)[1:].tolist()
    else:
        may = [True] * len(found)
    found = [f for f, m_ in zip(found, may) if not (m_ and _juts_out(ctx, f[3]))]
    for f in found:
        if _is_dormer(ctx, f[3]):
            f[3].kind = "dormer"
        li = f[3]
        box = (slice(li.y0, li.y0 + li.mask.shape[0]), slice(li.x0, li.x0 + li.mask.shape[1]))
        _unblur(li, dev_all[box], p)
    if p.window_extend_dev > 0 and found:
        dev = dev_all
        taken = np.zeros((H, W), np.int32)
        for k, f in enumerate(found, 1):
            li = f[3]
            taken[li.y0:li.y0 + li.mask.shape[0], li.x0:li.x0 + li.mask.shape[1]][li.mask] = k
        # a window's own pixels count as free too, but _extend_ends reads only rows above and below
        # its box: one map for all (a full-image map per window took seconds on a textured wall)
        free = B & (taken == 0)
        for k, f in enumerate(found, 1):
            li = f[3]
            z = _median_depth(ctx, li)
            # grown, a window stays within a pane's height (window_tall_keep_m; a blob most of a storey
            # tall is not a pane): a vertical crease or downpipe departs from the wall all along
            cap_m = p.window_tall_keep_m if p.window_tall_keep_m > 0 else p.window_height_m[1]
            max_h = max(li.mask.shape[0], int(cap_m * fy / z)) if z else 2 * li.mask.shape[0]
            _extend_ends(li, dev, free, max_h, p)
        _extend_sides(found, dev, free, p)
    found = _join_across_occluders(ctx, found, p)
    for f in found:
        if (f[3].kind or "window") == "window":
            _trim_ends(f[3], dev_all, p)
    if p.window_mates_short > 0 and found:
        taken = np.zeros((H, W), bool)
        for f in found:
            li = f[3]
            taken[li.y0:li.y0 + li.mask.shape[0], li.x0:li.x0 + li.mask.shape[1]] |= li.mask
        _floor_ends(found, dev_all, B & ~taken, p)
    if p.window_frame_ends and found:
        found = _frame_ends(ctx, found, dev_all, p)
    found = _join_split_panes(ctx, found, dev_all, p)
    if p.window_min_width_m > 0:
        # a strip narrower along its wall than any pane: a downpipe, a crease, a pilaster's shaded side
        found = [f for f in found if not ((wm := _strip_width_m(ctx, f[3])) is not None
                                          and wm < p.window_min_width_m)]
    found = [f for f in found if not _soffit_like(ctx, f[3])]  # a balcony soffit or a slab's face
    kept = []
    for f in found:  # a triangle of shaded wall is not a pane; the pane in it is
        if not _wedge_like(ctx, f[3]):
            kept.append(f)
        elif (pane := _wedge_pane(ctx, f[3])) is not None:
            kept.append(f[:3] + [pane])
    found = kept
    _unblur_narrow(found, dev_all, p)  # the final shapes: what the steps above grew by their mates stays
    found = _blur_columns_off(found, dev_all, p.window_blur_column_ratio, _own_colour_dev(feat, ref, dev_all, own, p),
                              p.window_blur_own_ratio)
    found = _split_two_panes(ctx, found, dev_all, p)  # two far panes a column apart, merged by their blur
    _oversized_narrow_off(ctx, found, dev_all, p)  # a far pane and its blur, larger than the panes around it
    _wide_wall_columns_off(ctx, found, dev_all, p)  # a pane's hull over a wall stripe or its sill's steps
    _sill_rows_off(ctx, found, dev_all, p)  # a sill or lintel band running on past a pane taller than its mates
    found = _shaded_patches(ctx, found, ratio, p)  # a far patch of shade: the lit pane in it, else nothing
    _shop_fronts(ctx, found, bld, B, boxes)  # the kind only: ground-floor glazing larger than the windows above
    for f in found:  # the kind only: a glass floor band receding down the street
        if _receding_band(ctx, f[3]):
            f[3].kind = "office_band"
    # Floors: sort by building then level, split where the level jumps by more than the tolerance.
    found.sort(key=lambda f: (f[0], f[1]))
    rows: list[list] = []
    for f in found:
        if rows and rows[-1][-1][0] == f[0] and f[1] - rows[-1][-1][1] <= f[2]:
            rows[-1].append(f)
        else:
            rows.append([f])
    groups = [g for row in rows for g in _split_blocks(ctx, row, ref)]
    out: list[Group] = []
    for g in groups:
        regular = len(g) >= 3
        members = []
        for f in g:
            li = f[3]
            li.confidence = float(np.clip(li.confidence + (0.2 if regular else 0.0), 0, 1))
            if li.mask.sum() < p.window_tiny_px:  # a few pixels say little: below the editor's sliders
                li.confidence = min(li.confidence, p.window_tiny_max_confidence)
            members.append(li)
        members.sort(key=lambda li: (li.x0, li.y0))
        out.append(Group(WINDOWS_GROUP, members, float(np.mean([li.confidence for li in members]))))
    from .window_confidence import rescore_windows
    from .window_groups import regroup_windows  # per floor of each building, not of each wall piece
    return rescore_windows(ctx, regroup_windows(ctx, out, feat), feat, B)


def _runs_cut(score: np.ndarray, thr: float) -> np.ndarray:
    """Indices where a 1-D jump ``score`` exceeds ``thr``, one per run (its maximum)."""
    over = score > thr
    if not over.any():
        return np.zeros(0, int)
    d = np.diff(np.r_[0, over.astype(np.int8), 0])
    return np.array([a + int(np.argmax(score[a:b])) for a, b in zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1))],
                    int)


def _side_median(prof: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
    """Per gap j (between columns j and j+1) the nan-medians of ``prof`` over the ``r`` columns left
    (j-r+1..j) and right (j+1..j+r) of it; ``prof``: (n,) or (n, C)."""
    n = prof.shape[0]
    pad = np.concatenate([np.full((r,) + prof.shape[1:], np.nan), prof, np.full((r,) + prof.shape[1:], np.nan)])
    win = np.lib.stride_tricks.sliding_window_view(pad, r, axis=0)  # (n + r + 1, ..., r)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows (columns hidden by a tree): NaN, no cut
        med = nanmedian(win, axis=-1)
    return med[1:n], med[r + 1:r + n]


def _fill_nearest(ids: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Building pixels without an id take the id of the nearest pixel that has one."""
    miss = B & (ids == 0)
    if not miss.any() or not (ids > 0).any():
        return ids
    _, lab = cv2.distanceTransformWithLabels((ids == 0).astype(np.uint8), cv2.DIST_L2, 3,
                                             labelType=cv2.DIST_LABEL_PIXEL)
    # OpenCV numbers the labelled pixels 1, 2, ... in raster order (DIST_LABEL_PIXEL): their ids in
    # that order are the table (no coordinates of a million pixels)
    lut = np.concatenate([np.zeros(1, np.int32), np.maximum(ids[ids != 0], 0).astype(np.int32)])
    out = ids.copy()
    out[miss] = lut[lab[miss]]
    return out


def facades(ctx: Context, B: np.ndarray, feat: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """Wall planes of the building pixels (HxW int32 ids, 0 off building; docs/proposals.md "Building windows").

    A connected building region holds many walls: neighbouring buildings set back from each other,
    each in its own colour, walls facing the camera beside walls receding along the street, gables
    and dormers set back on the roof. With depth, each building pixel is seen from above (its
    sideways and forward position in metres, smoothed down the column: walls are vertical); the
    horizontal direction of the wall through it comes from how that point moves along the image
    row, binned by ``window_facade_angle_deg``. Each connected piece of one direction is cut into
    column ranges where the median offset of the wall plane jumps by more than
    ``window_facade_step_m`` (+1 % of the depth) or the median wall colour (pixels not window-like,
    ``cand``) by ``window_block_lum`` / ``window_block_chroma``; pixels more than
    ``window_facade_step_m`` off their column's plane (dormers, balconies, awnings) form their own
    walls; pieces too small to judge join their nearest wall. Computed at about 512 px wide.
    Without depth: the connected building regions.
    """
    p = ctx.params
    H, W = B.shape
    if ctx.depth is None:
        return cv2.connectedComponents(B.astype(np.uint8), connectivity=4)[1].astype(np.int32)
    if not B.any():  # (the regions are not needed with depth: a full-image labelling saved)
        return np.zeros((H, W), np.int32)
    f = max(1, W // 512)
    h, w = max(1, H // f), max(1, W // f)
    K = ctx.intrinsics
    if f > 1:
        Bs = cv2.resize(B.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
        z = cv2.resize(ctx.depth, (w, h), interpolation=cv2.INTER_NEAREST)
        fs = cv2.resize(feat, (w, h), interpolation=cv2.INTER_AREA)
        cs = cv2.resize(cand.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST) > 0
        sx, sy = w / W, h / H
        fx, fy_, cx, cy = K.fx * sx, K.fy * sy, (K.cx + 0.5) * sx - 0.5, (K.cy + 0.5) * sy - 0.5
    else:
        Bs, z, fs, cs = B, ctx.depth, feat, cand
        fx, fy_, cx, cy = K.fx, K.fy, K.cx, K.cy
    valid = Bs & np.isfinite(z)
    zz = np.where(valid, z, 0.0).astype(np.float32)
    u = np.arange(w, dtype=np.float32)[None, :]
    v = np.arange(h, dtype=np.float32)[:, None]
    X = (u - np.float32(cx)) * zz / np.float32(fx)
    Yc = (v - np.float32(cy)) * zz / np.float32(fy_)
    pitch = float(p.camera_pitch_rad)
    Zw = zz * np.float32(np.cos(pitch)) - Yc * np.float32(np.sin(pitch))
    # Smoothed down the column (walls are vertical), barely across it (wall edges stay sharp).
    wv = valid.astype(np.float32)
    kv = max(5, (h // 16) | 1)
    num_x = cv2.blur(X * wv, (3, kv), borderType=cv2.BORDER_REPLICATE)
    num_z = cv2.blur(Zw * wv, (3, kv), borderType=cv2.BORDER_REPLICATE)
    den = np.maximum(cv2.blur(wv, (3, kv), borderType=cv2.BORDER_REPLICATE), 1e-6)
    Xs, Zs = num_x / den, num_z / den
    r = 3
    dX = np.zeros_like(Xs)
    dZ = np.zeros_like(Zs)
    dX[:, r:-r], dZ[:, r:-r] = Xs[:, 2 * r:] - Xs[:, :-2 * r], Zs[:, 2 * r:] - Zs[:, :-2 * r]
    ang = np.degrees(np.arctan2(dZ, dX)) % 180.0
    step = float(p.window_facade_angle_deg)
    nb = max(1, int(round(180.0 / step)))
    bins = (np.floor((ang + step / 2.0) / step).astype(np.int32) % nb).astype(np.uint8)
    bins = cv2.medianBlur(np.where(valid, bins + 1, 0).astype(np.uint8), 5)  # 0: no depth
    bins[~valid] = 0
    out = np.zeros((h, w), np.int32)
    nxt = 1
    rc = 3  # columns either side of a cut compared
    min_px = max(16, (h * w) // 2000)
    lum_t, chroma_t = float(p.window_block_lum), float(p.window_block_chroma)
    for o in range(1, nb + 1):
        nc, lab, st, _ = cv2.connectedComponentsWithStats((bins == o).astype(np.uint8), connectivity=4)
        t = np.radians((o - 1) * step)
        for c in range(1, nc):
            x0, y0, ww, hh, area = (int(q) for q in st[c])
            if area < min_px or (area < 4 * min_px and area < 0.6 * ww * hh):
                continue  # joins its nearest wall below (directions are noisy beside trees and cars;
                # a small piece is a wall when it fills its box: the side of a building's step)
            sl = (slice(y0, y0 + hh), slice(x0, x0 + ww))
            m = lab[sl] == c
            d = np.where(m, -np.sin(t) * X[sl] + np.cos(t) * Zw[sl], np.nan)   # plane offset (m)
            zc = np.where(m, zz[sl], np.nan)
            fm = np.where((m & ~cs[sl])[..., None], fs[sl], np.nan)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # columns without depth or wall: NaN
                col_d = nanmedian(d, axis=0)
                col_z = nanmedian(zc, axis=0)
                col_f = nanmedian(fm, axis=0)
            if ww > 2 * rc:
                ld, rd = _side_median(col_d, rc)
                lf, rf = _side_median(col_f, rc)
                zref = np.nan_to_num(np.fmin(col_z[:-1], col_z[1:]), nan=0.0)
                jump = np.nan_to_num(np.abs(ld - rd) / (p.window_facade_step_m + 0.01 * zref))
                cj = np.nan_to_num(np.maximum(np.abs(lf[:, 0] - rf[:, 0]) / lum_t,
                                              np.hypot(lf[:, 1] - rf[:, 1], lf[:, 2] - rf[:, 2]) / chroma_t))
                cuts = _runs_cut(np.maximum(jump, cj), 1.0)
            else:
                cuts = np.zeros(0, int)
            edges = np.r_[0, cuts + 1, ww]
            colid = np.zeros(ww, np.int32)
            seg_d = np.full(len(edges) - 1, np.nan)
            for i in range(len(edges) - 1):
                colid[edges[i]:edges[i + 1]] = i
                seg = col_d[edges[i]:edges[i + 1]]
                if np.isfinite(seg).any():
                    seg_d[i] = nanmedian(seg)
            with np.errstate(invalid="ignore"):
                off = np.abs(d - seg_d[colid][None, :]) > p.window_facade_step_m + 0.01 * zz[sl]
            base = nxt + colid  # each column range's wall
            nxt += len(edges) - 1
            out[sl][m] = np.broadcast_to(base[None, :], m.shape)[m]
            n2, lab2, st2, _ = cv2.connectedComponentsWithStats((m & off).astype(np.uint8), connectivity=4)
            for c2 in range(1, n2):
                # off-plane pieces: their own wall when large and flat (a dormer, an awning); a ramp
                # is depth bled from a car or a tree in front and stays on the wall
                if st2[c2, 4] < min_px:
                    continue
                piece = lab2 == c2
                dd = d[piece]
                dd = dd[np.isfinite(dd)]
                if dd.size and float(np.std(dd)) <= p.window_facade_step_m + 0.01 * float(median(zz[sl][piece])):
                    out[sl][piece] = nxt
                    nxt += 1
    out = _fill_nearest(out, Bs)
    if f > 1:
        out = cv2.resize(out, (W, H), interpolation=cv2.INTER_NEAREST)
        out = _fill_nearest(np.where(B, out, 0), B)
    return np.where(B, out, 0).astype(np.int32, copy=False)  # (np.where made a new array)


def _rows_cols(fm: np.ndarray, box: tuple[slice, slice] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The rows and the columns holding a pixel of ``fm`` (HxW bool); with ``box`` (slices holding all of
    its pixels) read on the box only (a full-image pass per wall otherwise)."""
    if box is None:
        return np.flatnonzero(fm.any(1)), np.flatnonzero(fm.any(0))
    sub = fm[box]
    return np.flatnonzero(sub.any(1)) + (box[0].start or 0), np.flatnonzero(sub.any(0)) + (box[1].start or 0)


def _wall_direction(ctx: Context, fm: np.ndarray, box: tuple[slice, slice] | None = None) -> tuple[float, float] | None:
    """Horizontal direction (tx, tz) of a wall seen from above (``fm``: HxW bool, the wall's pixels):
    the principal axis of its points' sideways and forward positions (m, from depth); None without
    depth or when the wall spans under 0.5 m."""
    if ctx.depth is None:
        return None
    rows, cols = _rows_cols(fm, box)  # (``box``: slices holding all of the wall, :func:`_rows_cols`)
    if rows.size == 0:
        return None
    ys, xs = np.nonzero(fm[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1])
    ys, xs = ys + rows[0], xs + cols[0]
    if ys.size < 8:
        return None
    step = max(1, ys.size // 4000)
    ys, xs = ys[::step], xs[::step]
    z = ctx.depth[ys, xs].astype(np.float64)
    ok = np.isfinite(z)
    if ok.sum() < 8:
        return None
    ys, xs, z = ys[ok], xs[ok], z[ok]
    K, pitch = ctx.intrinsics, float(ctx.params.camera_pitch_rad)
    X = (xs - K.cx) * z / K.fx
    Zw = z * np.cos(pitch) - (ys - K.cy) * z / K.fy * np.sin(pitch)
    evals, evecs = np.linalg.eigh(np.cov(np.stack([X, Zw])))
    if np.sqrt(max(evals[1], 0.0)) < 0.5:
        return None
    return float(evecs[0, 1]), float(evecs[1, 1])


def _wall_vp(ctx: Context, fm: np.ndarray, t: tuple[float, float] | None,
            box: tuple[slice, slice] | None = None) -> float | None:
    """Image column of the vanishing point of a wall's horizontal direction ``t``
    (:func:`_wall_direction`; ``fm``: HxW bool, the wall's pixels); None when the wall faces the
    camera (its bays are evenly spaced in the image), is too short to tell, or without depth."""
    if t is None:
        return None
    tx, tz = t
    if abs(tz) < 0.15 * abs(tx):
        return None
    K, pitch = ctx.intrinsics, float(ctx.params.camera_pitch_rad)
    u_vp = K.fx * tx / (tz * np.cos(pitch)) + K.cx
    W = ctx.shape[1]
    if not -3 * W < u_vp < 4 * W:
        return None
    # the wall's columns must lie on one side of it (else it is not a receding plane)
    cols = _rows_cols(fm, box)[1]
    if cols.size == 0 or abs(np.sign(cols - u_vp).mean()) < 0.98:
        return None
    return float(u_vp)


_TRIU: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def _triu(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(n, 1)``, made once per ``n`` (it costs more than the rest of a small lattice
    fit or a floor's mates; the arrays are shared: read only)."""
    iu = _TRIU.get(n)
    if iu is None:
        iu = np.triu_indices(n, 1)
        if n > 256:  # (kept only for small n)
            return iu
        _TRIU[n] = iu
        for a in iu:
            a.flags.writeable = False
    return iu


def _fit_lattice(c: np.ndarray, width: float, tol: float = 0.12) -> tuple[float, float, float] | None:
    """Period, phase and fit (P, phi, score) of centres ``c`` lying on phi + k P (bays).

    Candidate periods are the pairwise differences wider than 1.4 windows (a pane fills at most ~70 %
    of its bay); each is scored by how close the centres lie to its lattice (sum of
    max(0, 1 - (r / ``tol``)^2), r the distance in periods: a finer lattice halves the tolerance in
    pixels, so it does not win by fitting everything loosely), the best refined by least squares.
    A period whose centres on it occupy fewer than three bays is no lattice of bays (one as long as
    the wall fits every centre loosely: docs/proposals.md "Fifteenth pass: windows at 512x256 --
    panes in no blob between found mates"). None without three centres on three bays of it.
    """
    n = c.size
    if n < 3:
        return None
    d = np.abs(c[:, None] - c[None, :])[_triu(n)]
    d = np.sort(d[d > 1.4 * width])
    if d.size == 0:
        return None
    d = d[np.concatenate(([True], np.diff(np.log(d)) > 0.01))][:150]  # distinct to 1 %, the shortest

    def score(P, phi):
        r = (c - phi) / P
        r = r - np.round(r)
        return np.maximum(0.0, 1.0 - (r / tol) ** 2), r

    def bays(P, phi, sc):
        # bays the centres on the lattice occupy: a period as long as the wall fits every centre
        # loosely on one or two bays (a vanishing column next to the wall's far end stretches w there)
        return np.unique(np.round((c[sc > 0] - phi) / P)).size

    # every candidate period at once (one row each; row-wise means and sums add as the 1-D ones do)
    Pc = d[:, None]
    phis = np.angle(np.exp(2j * np.pi * c / Pc).mean(axis=1)) * d / (2 * np.pi)
    r = (c - phis[:, None]) / Pc
    k = np.round(r)
    sc = np.maximum(0.0, 1.0 - ((r - k) / tol) ** 2)
    # bays the centres on each lattice occupy (distinct k of the centres scoring > 0)
    ks = np.sort(np.where(sc > 0, k, np.inf), axis=1)
    n_bays = np.isfinite(ks[:, 0]) + ((ks[:, 1:] != ks[:, :-1]) & np.isfinite(ks[:, 1:])).sum(1)
    ok = np.flatnonzero(n_bays >= 3)
    if ok.size == 0:
        return None
    sums = sc[ok].sum(axis=1)
    j = ok[int(np.argmax(sums))]  # the first of the best, as a loop keeping only a strictly better one
    P, phi = d[j], phis[j]
    for _ in range(2):
        sc, r = score(P, phi)
        inl = sc > 0
        if inl.sum() < 3:
            return None
        k = np.round((c[inl] - phi) / P)
        if np.ptp(k) > 0:
            P, phi = np.polyfit(k, c[inl], 1)
    sc, _ = score(P, phi)
    if (sc > 0).sum() < max(3, 0.5 * n):
        return None
    if bays(P, phi, sc) < 3:
        return None
    return float(P), float(phi), float(sc.sum())


def lattice_cells(ctx: Context, fm: np.ndarray, wins: list, ratio: np.ndarray, chroma: np.ndarray,
                  dropped: list | tuple = (), direction: tuple[float, float] | None = None,
                  wall_box: tuple[slice, slice] | None = None) -> tuple[list[tuple[int, int, np.ndarray]], set[int]]:
    """The facade grid of one wall (docs/proposals.md "Building windows"): every cell of it in view.

    ``wins``: the wall's windows as [wall id, level, level tolerance, Light]. Bays are a lattice in
    the wall's projective column coordinate (w = 1 / (u - u_vp) for a wall receding to the vanishing
    column u_vp, :func:`_wall_vp`, u for a wall facing the camera: evenly spaced along the wall, so
    the lattice is evenly spaced in w) fitted to the windows' centres (:func:`_fit_lattice`); the
    window width is their median width in w. Floors are the windows' levels (within the level
    tolerance) with two windows at least; a floor's top and bottom are lines through the wall's
    vanishing point on the horizon (their median slopes), or rows for a wall facing the camera.
    The vanishing column from depth is a few pixels off; the column within 6 % of the image width
    whose lattice fits best is taken. Bays run over the windows found and up to
    ``window_cell_max_extra_bays`` beyond them toward the vanishing point (where panes shrink until
    the blob test misses them; a facing wall: none beyond).
    A cell is kept when ``window_cell_min_visible`` of it is this wall's pixels, it looks faintly
    like a window (``window_cell_min_share`` of it beyond half the window thresholds in ``ratio``, the
    log luminance against the wall, or ``chroma``), and it is at most ``window_cell_max_px`` wide or
    lies on a window spanning cells or on one of ``dropped`` (Lights :func:`_median_rule` removed).
    Returns the cells (y0, x0, local mask) and the indices of ``wins`` that span two or more cells
    (merged panes, replaced by the cells).
    """
    p = ctx.params
    H, W = fm.shape
    if len(wins) < 3:
        return [], set()
    # (``wall_box``: slices holding all of the wall, :func:`_rows_cols`)
    u0 = _wall_vp(ctx, fm, direction if direction is not None else _wall_direction(ctx, fm, wall_box), wall_box)
    K = ctx.intrinsics
    v_h = float(K.cy - K.fy * np.tan(p.camera_pitch_rad))  # the horizon row

    edges_u = np.array([[f[3].x0 - 0.5, f[3].x0 + f[3].mask.shape[1] - 0.5] for f in wins], float)

    def to_w(u, u_vp):
        u = np.asarray(u, float)
        return 1.0 / (u - u_vp) if u_vp is not None else u

    fits: dict = {}

    def lattice(u_vp):
        if u_vp in fits:  # the fine search's centre is the coarse one's best
            return fits[u_vp]
        wab = np.sort(to_w(edges_u, u_vp), axis=1)
        width = float(median(wab[:, 1] - wab[:, 0]))
        fits[u_vp] = (_fit_lattice(wab.mean(1), width), width, wab)
        return fits[u_vp]

    # The vanishing column from depth is a few pixels off (depth is warped); the bays' regularity
    # fixes it: the column near it whose lattice fits the windows best.
    best = None
    cands = [None] if u0 is None else [u0 + d * W for d in np.linspace(-0.06, 0.06, 9)]
    for rnd in range(2):  # coarse, then fine around the best
        for u_vp in cands:
            if u_vp is not None and not (np.all(edges_u > u_vp + 0.5) or np.all(edges_u < u_vp - 0.5)):
                continue
            fit, width, wab = lattice(u_vp)
            if fit is not None and (best is None or fit[2] > best[1][2]):
                best = (u_vp, fit, width, wab)
        if best is None or best[0] is None:
            break
        cands = [best[0] + d * W for d in np.linspace(-0.0075, 0.0075, 7)]
    if best is None:
        return [], set()
    u_vp, (P, phi, _), width, wab = best

    def to_u(w):
        w = np.asarray(w, float)
        return u_vp + 1.0 / w if u_vp is not None else w

    box = [(f[3].y0, f[3].y0 + f[3].mask.shape[0] - 1, f[3].x0, f[3].x0 + f[3].mask.shape[1] - 1,
            wab[i, 0], wab[i, 1]) for i, f in enumerate(wins)]
    bx = np.array(box, float)
    if width >= 0.9 * abs(P):
        return [], set()
    # floors: windows whose levels lie within the tolerance
    order = sorted(range(len(wins)), key=lambda i: wins[i][1])
    floors: list[list[int]] = []
    for i in order:
        if floors and wins[i][1] - wins[floors[-1][-1]][1] <= wins[i][2]:
            floors[-1].append(i)
        else:
            floors.append([i])
    uc = (bx[:, 2] + bx[:, 3]) / 2.0
    rows = []
    for fl in floors:
        if len(fl) < 2:
            continue
        t, b = bx[fl, 0], bx[fl, 1]
        if u_vp is not None:
            du = uc[fl] - u_vp
            ok = np.abs(du) > 1.0
            if not ok.any():
                continue
            at, ab = median((t[ok] - v_h) / du[ok]), median((b[ok] - v_h) / du[ok])
            rows.append((lambda u, a=at: v_h + a * (u - u_vp), lambda u, a=ab: v_h + a * (u - u_vp)))
        else:
            rows.append((lambda u, a=float(median(t)): a + 0.0 * u, lambda u, a=float(median(b)): a + 0.0 * u))
    if not rows:
        return [], set()
    cols = _rows_cols(fm, wall_box)[1]
    wr = to_w(np.array([cols.min() - 0.5, cols.max() + 0.5]), u_vp)
    k0, k1 = sorted(((wr - phi) / P).tolist())
    # Bays beyond the windows found only toward the vanishing point, where panes shrink until the
    # blob test misses them; on the near side a pane would have been found (and a facing wall
    # has no far side).
    kd = np.round((wab.mean(1) - phi) / P)
    kd0, kd1 = float(kd.min()), float(kd.max())
    ext = p.window_cell_max_extra_bays
    if u_vp is None:
        k0, k1 = max(k0, kd0), min(k1, kd1)
    elif abs(phi + (kd1 + 1) * P) > abs(phi + (kd0 - 1) * P):
        k0, k1 = max(k0, kd0), min(k1, kd1 + ext)
    else:
        k0, k1 = max(k0, kd0 - ext), min(k1, kd1)
    cells = []
    merged = set()
    grid = []
    for k in range(int(np.ceil(k0)), int(np.floor(k1)) + 1):
        wa, wb = phi + k * P - width / 2.0, phi + k * P + width / 2.0
        ua, ub = sorted(to_u([wa, wb]).tolist())
        if not np.isfinite(ua) or not np.isfinite(ub) or ub < -0.5 or ua > W - 0.5:
            continue
        ca, cb = int(np.ceil(ua)), int(np.floor(ub))
        if cb < ca:  # narrower than a pixel: the column nearest its centre
            ca = cb = int(round((ua + ub) / 2.0))
        ca, cb = max(ca, 0), min(cb, W - 1)
        if cb < ca:
            continue
        us = np.arange(ca, cb + 1, dtype=float)
        for top, bot in rows:
            t, b = np.round(top(us)).astype(int), np.round(bot(us)).astype(int)
            ya, yb = int(max(t.min(), 0)), int(min(b.max(), H - 1))
            if yb - ya < 1:
                continue
            rr = np.arange(ya, yb + 1)[:, None]
            m = (rr >= t[None, :]) & (rr <= b[None, :])
            grid.append((ya, ca, m))
    # windows spanning two or more cells: merged panes, replaced by the cells (each window's overlap
    # with every cell at once: integer boxes, the same counts as a loop over the pairs)
    if grid:
        gy = np.array([ya for ya, _, _ in grid], np.int64)[None, :]
        gx = np.array([xa for _, xa, _ in grid], np.int64)[None, :]
        gh = np.array([m.shape[0] for _, _, m in grid], np.int64)[None, :]
        gw = np.array([m.shape[1] for _, _, m in grid], np.int64)[None, :]
        half = 0.5 * np.array([m.sum() for _, _, m in grid], np.int64)[None, :]
        q = np.array([b[:4] for b in box], np.int64)
        oy = np.minimum(q[:, 1:2], gy + gh - 1) - np.maximum(q[:, 0:1], gy) + 1
        ox = np.minimum(q[:, 3:4], gx + gw - 1) - np.maximum(q[:, 2:3], gx) + 1
        n_in = ((oy > 0) & (ox > 0) & (oy * ox >= half)).sum(1)
        merged.update(int(i) for i in np.flatnonzero(n_in >= 2))
    t = -np.log(p.window_dark_ratio)
    gone = [(li.y0, li.y0 + li.mask.shape[0] - 1, li.x0, li.x0 + li.mask.shape[1] - 1) for li in dropped]
    spans = [box[i] for i in merged] + gone
    for ya, xa0, m in grid:
        h, w = m.shape
        vis = fm[ya:ya + h, xa0:xa0 + w] & m
        if vis.sum() < p.window_cell_min_visible * m.sum() or not vis.any():
            continue
        # looks faintly like a window: half the window thresholds on enough of it
        odd = (np.abs(ratio[ya:ya + h, xa0:xa0 + w]) > 0.5 * t) | \
            (chroma[ya:ya + h, xa0:xa0 + w] > 0.5 * p.window_chroma_delta)
        # narrow cells (a wider pane is found as a blob where there is one), or the cells of a
        # blob over several cells
        in_merged = any(min(ya + h - 1, q[1]) >= max(ya, q[0]) and min(xa0 + w - 1, q[3]) >= max(xa0, q[2])
                        for q in spans)
        if (odd & vis).sum() >= p.window_cell_min_share * vis.sum() and (w <= p.window_cell_max_px or in_merged):
            cells.append((ya, xa0, m))
    return cells, merged
