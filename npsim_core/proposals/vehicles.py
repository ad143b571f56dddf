"""Vehicles: a lamp pair on the end face the camera sees, and the window panes; one group per vehicle
(docs/proposals.md)."""

from __future__ import annotations

import numpy as np

from ..annotation import VEHICLE_GROUP_OF_LABEL
from .core import Context, Group, Light, components, median, nanmedian, pixels

#: The vehicles looked at, Cityscapes labelId (car, truck, bus) -> their lights' group class.
VEHICLE_GROUP = {label: VEHICLE_GROUP_OF_LABEL[label] for label in (26, 27, 28)}
WINDOW_PARKED, PARKED_FRONT, PARKED_REAR, MOVING_FRONT, MOVING_REAR, WINDOW_TRANSPORT = 2, 3, 4, 5, 6, 7
#: Labels beside a parked vehicle's kerb side: sidewalk, parking, terrain, building, wall, fence, vegetation.
KERBSIDE = (8, 9, 22, 11, 12, 13, 21)
#: A lamp's visible part beside a cut (the car in front, the image border; :func:`_sliver_lamp`) is looked
#: for at these heights (m above the ground), up to this far (m) from the cut, and is as tall as this (m).
SLIVER_H_M, SLIVER_REACH_M, SLIVER_ROWS_M = (0.5, 0.95), 0.45, (0.07, 0.17)
#: No sliver is looked for on a vehicle whose whole lamp (0.15 m) would be under this many pixels tall.
SLIVER_MIN_LAMP_PX = 2.0
#: ... and it reaches to within this many pixels of the cut (a whole lamp further in, seen past the car
#: in front, was tried: more false lamps than found, docs/proposals.md).
SLIVER_MAX_GAP = 1
#: ... from pixels departing from the paint beside the cut by more than this (8-bit, any channel).
SLIVER_DIFF = 40.0
#: Labels that never hide a vehicle's end face: ground, buildings, vegetation, sky (void included).
BACKGROUND = (0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 21, 22, 23)
#: End faces whose whole lamp (0.15 m) is under this many pixels tall get their lamp boxes by pixel centres
#: from the face's edges, under a body top from the silhouette's full-width rows when that is at most
#: ``SMALL_TOP_MOVE`` rows from the face's (docs/proposals.md, "Seventh pass: far vehicle lamps").
SMALL_LAMP_PX, SMALL_TOP_MOVE = 3.0, 2
#: A nearer object cutting a vehicle's full-width body rows from below is this much nearer (m) than its face.
CUT_NEARER_M = 0.3
#: Lamp boxes at least this many rows tall snap to the pixels off the paint after a 3x3 opening.
OPEN_LAMP_PX = 10
#: A lamp's confidence grows with its pixels up to this many (a lamp of 1-8 px is a pixel or two off as
#: often as not; beyond, size adds nothing: docs/proposals.md, "Ninth pass: vehicle confidence").
LAMP_SURE_PX = 9
#: ... and a lamp under this many pixels across (its narrower side) counts at most this many pixels per pixel
#: across: a mask one or two pixels thin loses half its IoU to a pixel's offset, whatever its length (a
#: sliver beside the car in front, bounded by the occluder's blurred edge; docs/proposals.md, "Eleventh pass:
#: vehicle confidence at 2048x1024").
LAMP_THIN_PX = 3
#: Off-paint pixels taller than this many times the lamp box's rows (+2 px of blur) are not its lamp (the
#: darker end face or an edge running through the snap window: docs/proposals.md, "Tenth pass: vehicle
#: lamps").
LAMP_TALL_RATIO = 1.5
#: A pixel departing from the paint towards red is a lamp's only with channels this far apart (8-bit): grey
#: and black (a wheel, a shadow on blue paint) are not
#: (docs/proposals.md, "Tenth pass: vehicle lamps").
LAMP_MIN_CHROMA = 15.0
#: Heights (m above the ground) where a red lamp is looked for by colour alone (:func:`_red_lamps`).
RED_LAMP_H_M = (0.5, 1.1)
# A run of glass columns between pillars narrower than this is the blur of a pillar's or the
# silhouette's edge, not a pane (2048x1024 hard seeds 0-2: most 1-column runs matched no pane) -- except
# in a band too narrow to hold two such runs and a pillar between them (a far car in a parked row showing
# a sliver of its cabin): there a pane is a column or two, and 1-column runs count (docs/proposals.md,
# "Thirteenth pass: vehicle panes at 512x256").
PANE_MIN_COLS = 2
#: A snapped lamp's pixel at this share of the lamp's departure from the paint or more is all lamp
#: (:func:`_with_rim`); a pixel beside one departing by at most ``RIM_MIXED`` of it (and
#: ``vehicle_lamp_rim_share`` at least) is its antialiased rim, part lamp and part paint; an outermost pixel
#: beside none, under ``RIM_MIXED`` and ``RIM_STEP`` of it under a pixel inside it, is the blur beyond the
#: lamp's edge.
RIM_FULL = 0.85
RIM_MIXED = 0.8
RIM_STEP = 0.15
#: ... and in such a band a column departing from the paint by less than this share of the glass on both
#: sides of it (the band's most departing column either side) is a pillar the blur has mixed with the glass.
PILLAR_DIP = 0.85
#: A car's glass ends this far (m) below the cabin's top and above the body's top (its frame).
PANE_INSET_M = 0.07
#: A car's pillar between end and side pane is about this wide (m; :func:`_pillar_edge`).
PILLAR_M = 0.1
#: A run of glass between pillars narrower than this share of its band's widest run is a reflection's
#: edge or a pillar's blurred edge far more often than a pane (2048x1024 seeds 0-2: all 6 such runs
#: matched no pane): it keeps its rule confidence, not raised by the rescoring, so the slider's default
#: leaves it (docs/proposals.md, "Eleventh pass: pane slivers at the slider").
PANE_SLIVER_SHARE = 0.05
#: A pane trimmed of its body rows and columns (:func:`_body_trim`) keeps at least this share of its pixels,
#: or is left whole.
BODY_TRIM_KEEP = 0.5
#: A pane's glass (its median colour) at least this many levels (largest channel) off the paint is grown down
#: by its row below (:func:`_glass_below`); nearer the paint the row cannot be told from body.
GLASS_BELOW_MIN = 20.0
#: A car's narrowest pillar (m) and the pixels it must span for its middle column to be clear of the photo's
#: edge blur (3x3): on a face at that scale or nearer a pillar column is one whose pixels lie within half of
#: ``vehicle_pillar_paint_diff`` of the paint, its core in the paint's own colour -- glass departing 10-20
#: levels from the paint is glass there (docs/proposals.md, "Twelfth pass: whole cars at the slider").
PILLAR_CORE_M, PILLAR_CORE_PX = 0.1, 3.0


def _chan_max(a: np.ndarray) -> np.ndarray:
    """``a.max(-1)`` over the 3 colour channels, the same floats: a reduction over a last axis of 3 runs
    twenty times slower than two elementwise maxima (it was a third of the lamp snap's time)."""
    return np.maximum(np.maximum(a[..., 0], a[..., 1]), a[..., 2])


def _ring_contrast(img: np.ndarray, m: np.ndarray, light: np.ndarray) -> float:
    """How far a light's mean colour departs from the vehicle right around it: the largest channel
    difference (8-bit levels) between its pixels' mean and the median of the silhouette's pixels within
    two pixels of it (4-connected), 0 when it has no such pixels. ``img`` (h, w, 3), ``m`` the vehicle's
    silhouette and ``light`` its mask, both local (h, w) bool."""
    import cv2

    ys, xs = np.flatnonzero(light.any(1)), np.flatnonzero(light.any(0))  # its box (np.nonzero is slower)
    if ys.size == 0:
        return 0.0
    a, b = max(0, int(ys[0]) - 2), max(0, int(xs[0]) - 2)
    sl = (slice(a, int(ys[-1]) + 3), slice(b, int(xs[-1]) + 3))
    li = light[sl]
    grown = cv2.dilate(li.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3)), iterations=2,
                       borderType=cv2.BORDER_CONSTANT, borderValue=0)
    ring = grown.astype(bool) & ~li & m[sl]
    if not ring.any():
        return 0.0
    sub = img[sl]
    return float(np.abs(pixels(sub, li).mean(0) - median(pixels(sub, ring), axis=0)).max())


def _lamp_size_px(lamp: np.ndarray) -> int:
    """The pixels a lamp's confidence counts (local bool mask): its pixels, at most ``LAMP_SURE_PX``, and on a
    lamp under ``LAMP_THIN_PX`` pixels across (rows or columns of its box) at most ``LAMP_THIN_PX`` per pixel
    across -- a lamp 1-2 px thin is a pixel off as often as not (2048x1024 seeds 0-5: of the lamps 1-2 px
    thin scored >= 0.9, 1 tight, 1 needing a touch-up, 5 false)."""
    ys, xs = np.flatnonzero(lamp.any(1)), np.flatnonzero(lamp.any(0))  # its box (np.nonzero is slower)
    if ys.size == 0:
        return 1
    thin = min(int(ys[-1] - ys[0] + 1), int(xs[-1] - xs[0] + 1))
    cap = LAMP_SURE_PX if thin >= LAMP_THIN_PX else LAMP_THIN_PX * thin
    return max(1, min(int(np.count_nonzero(lamp)), cap))


def _cut_by_border(m: np.ndarray, x0: int, width: int) -> bool:
    """Whether a vehicle's silhouette (local bool mask at image column ``x0``) reaches the image's left or
    right border. Such a car is near, its side seen at a steep angle, and where its end face ends and its
    side begins is laid out from what the border leaves: its side pane takes in the cabin's pillars and part
    of the end pane (docs/proposals.md, "Eleventh pass: vehicle confidence at 2048x1024")."""
    return bool((x0 == 0 and m[:, 0].any()) or (x0 + m.shape[1] == width and m[:, -1].any()))


def _pane_parts(img: np.ndarray, band: np.ndarray, end: np.ndarray, paint: np.ndarray,
                diff: float, ppm: float | None = None) -> tuple[list[tuple[float, np.ndarray, bool]], bool]:
    """The cabin band split into panes: ``(is_end, mask, sliver)`` per pane, ``is_end`` 1.0 for the end
    pane, ``sliver`` True for a run of glass narrower than ``PANE_SLIVER_SHARE`` of the band's widest run
    (a reflection's or a pillar's edge as a rule, rarely a pane); and whether the band parted at a pillar
    (False: split at the end face's edge).

    A column of the band most of whose pixels lie within ``diff`` levels of the paint (every channel)
    is a pillar, painted as the body: the band's runs of other columns (at least ``PANE_MIN_COLS``, or
    one in a band narrower than two such runs and a pillar, where a column departing from the paint less
    than ``PILLAR_DIP`` of the glass either side is a pillar too) are the panes, and each is the
    end pane when most of it lies in the end face's columns (``end``). Without a pillar inside the band
    (glass the paint's colour, a far car's pillar blurred away) the band is split at the end face's
    edge, as before. Far cars in a parked row show their end face's edge only where the car in front
    leaves the body visible; the pillar between the windscreen and the side window is where the panes
    part (docs/proposals.md, eleventh pass: vehicle panes in parked rows). On a face of ``ppm`` pixels per
    metre where a pillar's core is clear of the blur (``PILLAR_CORE_M`` spans ``PILLAR_CORE_PX``), the
    pillar's pixels lie within half of ``diff``: glass a little off the paint's colour is not taken for
    pillar there (docs/proposals.md, "Twelfth pass: whole cars at the slider").
    """
    from scipy import ndimage

    old = [(1.0, band & end, False), (0.0, band & ~end, False)]
    if diff <= 0 or not band.any():
        return old, False
    if ppm is not None and ppm * PILLAR_CORE_M >= PILLAR_CORE_PX:
        diff = diff / 2.0
    rows = np.flatnonzero(band.any(1))  # the colours over the band's rows only: no other row counts
    img, in_band = img[rows[0]:rows[-1] + 1], band[rows[0]:rows[-1] + 1]
    dev = _chan_max(np.abs(img - paint))
    near = (dev <= diff) & in_band
    n = in_band.sum(0)
    cols = n > 0
    pillar = cols & (near.sum(0) * 2 > n)
    narrow = int(cols.sum()) < 2 * PANE_MIN_COLS + 1
    if narrow:  # a far sliver's pillar, a pixel or less, is blurred with the glass: a dip in the departure
        cc = np.flatnonzero(cols)
        d = np.array([median(dev[in_band[:, c], c]) for c in cc])
        for j in range(1, cc.size - 1):
            if d[j] < PILLAR_DIP * min(d[:j].max(), d[j + 1:].max()):
                pillar[cc[j]] = True
    glass = cols & ~pillar
    lab, k = ndimage.label(glass)
    min_cols = 1 if narrow else PANE_MIN_COLS
    size = np.bincount(lab, minlength=k + 1)  # each run's columns (a far car's band holds hundreds of runs)
    runs = [i for i in range(1, k + 1) if size[i] >= min_cols]
    if len(runs) < 2:  # no pillar between two runs of glass
        return old, False
    widths = {i: int(size[i]) for i in runs}
    widest = max(widths.values())
    out = []
    for i in runs:
        part = band & (lab == i)[None, :]
        out.append((float((part & end).sum() * 2 > part.sum()), part, widths[i] < PANE_SLIVER_SHARE * widest))
    return out, True


def _body_trim(img: np.ndarray, part: np.ndarray, paint: np.ndarray, tol: float, min_chroma: float) -> np.ndarray:
    """A pane's mask less its outer rows and columns of body: a row (from the bottom) or a column (from
    either side) most of whose pixels have the paint's hue -- their colour over its sum within ``tol`` of
    the paint's in every channel, however lit -- on a paint whose colour over its sum spreads at least
    ``min_chroma`` across the channels (a grey car's body cannot be told from its glass this way).
    A near car's cabin band runs past its glass: its bottom rows take the sunlit top of the body below
    the glass (the face's body top is measured at the end face), and where the silhouette is wider than
    the cabin, the body beside it; the shade's paint test (``vehicle_pillar_paint_diff``) does not see
    them, lit 80-90 levels brighter than the end face's paint (docs/proposals.md, "Nineteenth pass:
    vehicle panes at 512x256 -- the body in a near car's band"). Unchanged when it would keep under
    ``BODY_TRIM_KEEP`` of the pane (a car at the image border whose band is mostly body: no pane to trim)."""
    s = float(paint.sum())
    if tol <= 0 or s <= 0:
        return part
    pc = paint / s
    if float(pc.max() - pc.min()) < min_chroma:
        return part
    ys, xs = np.nonzero(part)
    r0, r1, c0, c1 = ys.min(), ys.max(), xs.min(), xs.max()
    sub = img[r0:r1 + 1, c0:c1 + 1]
    tot = np.maximum(sub.sum(-1), 1.0)
    body = _chan_max(np.abs(sub / tot[..., None] - pc)) <= tol
    pm = part[r0:r1 + 1, c0:c1 + 1]
    body &= pm
    n_r, n_c = pm.sum(1), pm.sum(0)
    rb, cb = body.sum(1) * 2 > n_r, body.sum(0) * 2 > n_c
    b = pm.shape[0]
    while b > 1 and rb[b - 1]:
        b -= 1
    lo, hi = 0, pm.shape[1]
    while lo < hi - 1 and cb[lo]:
        lo += 1
    while hi > lo + 1 and cb[hi - 1]:
        hi -= 1
    if b == pm.shape[0] and lo == 0 and hi == pm.shape[1]:
        return part
    out = np.zeros_like(part)
    out[r0:r0 + b, c0 + lo:c0 + hi] = pm[:b, lo:hi]
    return out if out.sum() >= BODY_TRIM_KEEP * pm.sum() else part


def _glass_below(img: np.ndarray, m: np.ndarray, part: np.ndarray, paint: np.ndarray, share: float) -> np.ndarray:
    """A pane grown down by the silhouette's row below it where that row is its glass: more than half of the
    pane's bottom columns there lie within ``share`` of the glass's departure from the paint (per channel,
    its median colour's) of that glass colour. Only for glass darker than the paint (its brightest channel
    under the paint's) and at least ``GLASS_BELOW_MIN`` levels off it: a band brighter than its paint holds
    sky or reflection, whose row below is no glass.

    The band ends ``PANE_INSET_M`` above the end face's body top; a cabin set back from the face has its
    glass end lower in the image than that on many cars, the glass's last row left out (512x256 default
    seed 0: two panes of a red car at 33 m two rows short, IoU 0.51 and 0.64; docs/proposals.md,
    "Nineteenth pass: vehicle panes at 512x256 -- the body in a near car's band, the glass's last row")."""
    if share <= 0:
        return part
    ys = np.flatnonzero(part.any(1))
    b = int(ys[-1])
    if b + 1 >= m.shape[0]:
        return part
    glass = median(pixels(img, part), axis=0)
    gp = float(_chan_max(np.abs(glass - paint)))
    if gp < GLASS_BELOW_MIN or float(glass.max()) >= float(paint.max()):
        return part
    cols = np.flatnonzero(part[b])
    c = cols[m[b + 1, cols]]
    near = c[_chan_max(np.abs(img[b + 1, c] - glass)) <= share * gp]
    if near.size * 2 <= cols.size:
        return part
    out = part.copy()
    out[b + 1, near] = True
    return out


def _rescore(conf: float, bias: float, weights: tuple[float, ...], feats: tuple[float, ...]) -> float:
    """A light's confidence from its rule confidence and features (docs/proposals.md, "Ninth pass: vehicle
    confidence"): at least 0.5 -> 0.5 + 0.5 sigmoid(bias + weights . feats), below 0.5 unchanged -- so the
    set kept at 0.5 stays the same and only the order within it changes."""
    if conf < 0.5:
        return conf
    t = bias + float(np.dot(weights, feats))
    return float(0.5 + 0.5 / (1.0 + np.exp(-t)))


def _vehicles(ctx: Context, min_instance_px: int | None = None):
    """(labelId, y0, x0, local mask) per vehicle: instance ids where given, else connected components
    split where depth jumps. Instances from ``min_instance_px`` pixels (default ``vehicle_min_area_px``)."""
    p = ctx.params
    min_px = p.vehicle_min_area_px if min_instance_px is None else min_instance_px
    # The vehicles' pixels from one pass over the frame; each class's and instance's from them (full-frame
    # masks and maps per class took a sixth of the proposer's time).
    # By flat index, split into rows and columns only for the instances' boxes (np.nonzero of a 2-D mask and
    # 2-D gathers are 2-3x slower).
    flat = np.flatnonzero((ctx.labels >= min(VEHICLE_GROUP)) & (ctx.labels <= max(VEHICLE_GROUP)))
    vlab = ctx.labels.reshape(-1)[flat]
    for cls in VEHICLE_GROUP:
        sel = vlab == cls
        if not sel.any():
            continue
        if ctx.instances is not None:
            # Each instance's box from one sort of its pixels (a full-image comparison per instance took
            # half the proposer's time on a street of 35 cars at 2048x1024).
            f = flat[sel]
            v = ctx.instances.reshape(-1)[f]
            own = v >= 1000
            f, v = f[own], v[own]
            order = np.argsort(v, kind="stable")
            f, v = f[order], v[order]
            ys, xs = np.divmod(f, ctx.shape[1])
            ids, starts, counts = np.unique(v, return_index=True, return_counts=True)
            for iid, a, n in zip(ids.tolist(), starts.tolist(), counts.tolist()):  # one object may show as
                if n < min_px:                                                      # several components
                    continue
                yy, xx = ys[a:a + n], xs[a:a + n]
                y0, y1, x0, x1 = int(yy.min()), int(yy.max()) + 1, int(xx.min()), int(xx.max()) + 1
                yield cls, y0, x0, (ctx.instances[y0:y1, x0:x1] == iid) & (ctx.labels[y0:y1, x0:x1] == cls)
            if own.all():
                continue
            rest = (ctx.labels == cls) & (ctx.instances < 1000)  # crowd regions / missing ids: components
        else:
            rest = ctx.labels == cls
        for y0, x0, m, _ in components(rest, p.vehicle_min_area_px):
            for part in _split_by_depth(ctx, y0, x0, m):
                yield (cls, *part)


def _split_by_depth(ctx: Context, y0: int, x0: int, m: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
    """Split one vehicle-label component where depth jumps (parked cars in a row touch in the image
    but not in depth): pixels next to a jump of more than ``vehicle_split_jump`` (relative) are cut,
    the pieces labelled and the cut pixels given back to the nearest piece."""
    from scipy import ndimage

    if ctx.depth is None:
        return [(y0, x0, m)]
    h, w = m.shape
    d = np.where(m, ctx.depth[y0:y0 + h, x0:x0 + w], np.nan).astype(np.float32)
    thr = ctx.params.vehicle_split_jump
    cut = np.zeros_like(m)
    k = max(2, int(round(2 * ctx.shape[1] / 512)))  # span: predicted depth softens edges over ~W/400 px
    with np.errstate(invalid="ignore"):
        for a, b, sl_a, sl_b in ((d[:, k:], d[:, :-k], (slice(None), slice(k, None)), (slice(None), slice(None, -k))),
                                 (d[k:], d[:-k], (slice(k, None), slice(None)), (slice(None, -k), slice(None)))):
            jump = np.abs(a - b) > thr * np.fmin(a, b)
            far_a = jump & (a > b)
            cut[sl_a] |= far_a
            cut[sl_b] |= jump & ~far_a
    keep = m & ~cut & np.isfinite(d)
    lab, n = ndimage.label(keep)
    if n <= 1:
        return [(y0, x0, m)]
    _, (iy, ix) = ndimage.distance_transform_edt(lab == 0, return_indices=True)
    full = np.where(m, lab[iy, ix], 0)
    out = []
    for k in range(1, n + 1):
        part = full == k
        if part.sum() < ctx.params.vehicle_min_area_px:
            continue
        ys, xs = np.nonzero(part)
        out.append((y0 + int(ys.min()), x0 + int(xs.min()), part[ys.min():ys.max() + 1, xs.min():xs.max() + 1]))
    return out or [(y0, x0, m)]


def _run(a: np.ndarray) -> tuple[int, int] | None:
    """First and last index (inclusive) of the longest run of True in a 1-D bool array."""
    if not a.any():
        return None
    d = np.diff(np.r_[0, a.astype(np.int8), 0])
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
    k = int(np.argmax(ends - starts))
    return int(starts[k]), int(ends[k] - 1)


def _step_column(ctx: Context, y0: int, x0: int, m: np.ndarray, r0: int, r1: int, lo: int, hi: int) -> int | None:
    """Local column j in [lo, hi) with the strongest shading step between columns j and j+1 over
    rows r0..r1 of the mask (where the end face meets the side face), None when no clear step."""
    h, w = m.shape
    lo, hi = max(0, lo), min(w - 1, hi)
    if hi - lo < 1:
        return None
    mm = m[r0:r1 + 1]
    cnt = mm.sum(0)
    prof = np.where(cnt > 0, (ctx.lum[y0 + r0:y0 + r1 + 1, x0:x0 + w] * mm).sum(0) / np.maximum(cnt, 1), np.nan)
    step = np.abs(np.diff(prof))[lo:hi]
    if not np.isfinite(step).any() or np.nanmax(step) <= 0.03:
        return None
    return lo + int(np.nanargmax(step))


def _nanpercentile_cols(d: np.ndarray, q: float) -> np.ndarray:
    """``np.nanpercentile(d, q, axis=0)`` (linear interpolation) by one sort: NaN sorts last, so each
    column's valid values come first (numpy's own goes column by column in Python). All-NaN columns give
    NaN, without a warning."""
    s = np.sort(d, axis=0)
    n = np.isfinite(s).sum(0)
    pos = q / 100.0 * np.maximum(n - 1, 0)
    lo = np.floor(pos).astype(np.int64)
    hi = np.minimum(lo + 1, np.maximum(n - 1, 0))
    cols = np.arange(d.shape[1])
    a, b = s[lo, cols], s[hi, cols]
    out = a + (pos - lo) * (b - a)
    return np.where(n > 0, out, np.nan)


def _near_columns(ctx: Context, y0: int, x0: int, m: np.ndarray, r0: int, r1: int) -> np.ndarray | None:
    """Columns whose body-row depth (30th percentile, running median over columns) is within
    ``max(vehicle_face_tol_m, vehicle_face_tol_rel x depth)`` of the densest depth among the nearer
    columns: the end face (a side face recedes)."""
    h, w = m.shape
    mm = m[r0:r1 + 1]
    d = np.where(mm, ctx.depth[y0 + r0:y0 + r1 + 1, x0:x0 + w], np.nan)
    enough = mm.sum(0) >= 2
    if enough.sum() < 3:
        return None
    col = np.full(w, np.inf)
    col[enough] = _nanpercentile_cols(d[:, enough], 30.0)  # all-NaN columns stay NaN, said below
    ok = np.isfinite(col)
    if not ok.any():
        return None
    # Predicted depth is noisy column to column: a running median over ~1/15 of the width.
    k = max(3, (w // 15) | 1)
    from scipy.ndimage import median_filter

    col = np.where(ok, median_filter(np.where(ok, col, np.nanmax(np.where(ok, col, np.nan))), size=k,
                                     mode="nearest"), np.inf)
    # The end face is the densest depth among the nearer columns (a plane across the vehicle: many
    # columns at one depth); not the nearest, which a nearer occluder's bleeding depth can own.
    c = np.sort(col[ok])
    tol = np.maximum(ctx.params.vehicle_face_tol_m, ctx.params.vehicle_face_tol_rel * c)
    count = np.searchsorted(c, c + tol, side="right") - np.arange(c.size)
    half = max(1, int(np.ceil(0.6 * c.size)))
    i = int(np.argmax(count[:half]))
    near, t = float(c[i]), float(tol[i])
    return ok & (col >= near - t) & (col <= near + t)


def _run_from(a: np.ndarray, start: int, step: int) -> int:
    """Last index of the run of True in ``a`` that starts at ``start`` going in direction ``step``."""
    i = start
    while 0 <= i + step < len(a) and a[i + step]:
        i += step
    return i


def _below_lid(ctx: Context, y0: int, x0: int, m: np.ndarray, c0: int, c1: int, r0: int, r1: int,
               z: float) -> int:
    """The end face's top row at or below ``r0`` (local): seen from above the body, the bonnet or boot
    lid shows over the end face and its depth grows row by row upward, while the face (a vertical plane)
    keeps one depth. Going up from the middle of rows r0..r1, the topmost row whose depth (median over
    the face's columns) is within ``vehicle_lid_tol_m`` (+3 % of the depth: predicted depth is warped)
    of the face's (the median over the lower half of rows r0..middle); moved at most
    ``vehicle_lid_max_m`` of height down from r0, not at all when the middle row is off the face's
    depth. (0.1 m + 1 % lost 0.04-0.14 recall: the warp reads a face 0.5-1 m deeper at one end.)"""
    p = ctx.params
    h, w = m.shape
    c0, c1 = max(c0, 0), min(c1, w - 1)
    mid = (r0 + r1) // 2
    if mid <= r0 or c1 < c0:
        return r0
    d = np.where(m[r0:mid + 1, c0:c1 + 1], ctx.depth[y0 + r0:y0 + mid + 1, x0 + c0:x0 + c1 + 1], np.nan)
    dz = nanmedian(d, 1)  # rows without valid depth stay NaN: not the face
    lower = dz[dz.size // 2:]
    if not np.isfinite(lower).any():
        return r0
    zf = float(median(lower[~np.isnan(lower)]))  # the face's depth: rows just above the middle
    ok = np.abs(dz - zf) <= max(p.vehicle_lid_tol_m, 0.03 * zf)
    if not ok[-1]:
        return r0
    top = r0 + _run_from(ok, ok.size - 1, -1)
    return int(min(top, r0 + int(round(p.vehicle_lid_max_m * float(ctx.intrinsics.fy) / z))))


def _cut_below(ctx: Context, y0: int, x0: int, m: np.ndarray, r: int, c0: int, c1: int) -> bool:
    """Whether the silhouette's full-width rows end at local row ``r`` because something nearer hides
    the rows below (the car in front of a parked row): over half of the columns c0..c1 the silhouette
    holds in row ``r`` and loses in row ``r + 1`` are, there, something other than background
    (``BACKGROUND``) at least ``CUT_NEARER_M`` nearer than the silhouette's median depth in row ``r + 1``
    (not the face's depth ``z``, which the occluder's depth bleeds into)."""
    h, w = m.shape
    if r + 1 >= h:
        return False
    lost = np.flatnonzero(m[r, c0:c1 + 1] & ~m[r + 1, c0:c1 + 1]) + c0
    if lost.size == 0:
        return False
    own = ctx.depth[y0 + r + 1, x0:x0 + w][m[r + 1]]
    own = own[np.isfinite(own)]
    if own.size == 0:
        return False
    lab = ctx.labels[y0 + r + 1, x0 + lost]
    with np.errstate(invalid="ignore"):  # NaN depth: not nearer
        nearer = ~np.isin(lab, BACKGROUND) & \
            (ctx.depth[y0 + r + 1, x0 + lost] < float(median(own)) - CUT_NEARER_M)
    return bool(nearer.mean() > 0.5)


def _hidden(ctx: Context, y0: int, x0: int, m: np.ndarray, z: float) -> np.ndarray:
    """Pixels of a box (image origin y0, x0; ``m`` the silhouette over it) that a nearer object hides: off
    the silhouette, something other than background (``BACKGROUND``) at least ``CUT_NEARER_M`` nearer
    than ``z`` (m; the car in front of a parked row)."""
    h, w = m.shape
    lab = ctx.labels[y0:y0 + h, x0:x0 + w]
    with np.errstate(invalid="ignore"):  # NaN depth: not nearer
        return ~m & ~np.isin(lab, BACKGROUND) & (ctx.depth[y0:y0 + h, x0:x0 + w] < z - CUT_NEARER_M)


def _body_rows(ctx: Context, y0: int, m: np.ndarray, c0: int, c1: int, z: float | None,
               x0: int | None = None) -> tuple[int, int]:
    """Rows (local, inclusive) of the body's end face over columns c0..c1: where the silhouette fills
    at least 95 % of its fullest row (the cabin above is narrower and set back, the wheels below
    are apart); failing that the lower 60 %; with depth, a top edge at an implausible height
    (``vehicle_body_top_m``) or on a face narrower than ``vehicle_small_face_px`` is put at
    ``vehicle_body_top_typical_m``."""
    p = ctx.params
    h, w = m.shape
    ys = np.flatnonzero(m.any(1))
    sil_h = int(ys[-1] - ys[0] + 1)
    c0, c1 = max(c0, 0), min(c1, w - 1)
    fill = m[:, c0:c1 + 1].sum(1)
    body = _run(fill >= 0.95 * max(1, fill.max()))
    if body is not None and body[1] - body[0] + 1 >= max(2, 0.15 * sil_h):
        r0, r1 = body
    else:
        r0, r1 = int(ys[0] + 0.4 * sil_h), int(ys[-1])
    if z is not None:
        top_h = float(ctx.height_above_ground(y0 + r0, z))
        lo_h, hi_h = p.vehicle_body_top_m
        # The cabin's inset is a pixel or less on a narrow face: there the typical height decides.
        if not lo_h <= top_h <= hi_h or c1 - c0 + 1 < p.vehicle_small_face_px:
            r0 = int(np.clip(round(_typical_top_row(ctx, z)) - y0, 0, h - 1))
            r1 = max(r1, r0 + 1)
        if x0 is not None and ctx.depth is not None and p.vehicle_lid_max_m > 0 and \
                c1 - c0 + 1 >= p.vehicle_small_face_px:  # (the typical height may fall on the lid too)
            r0 = _below_lid(ctx, y0, x0, m, c0, c1, r0, r1, z)
    return r0, r1


def _typical_top_row(ctx: Context, z: float) -> float:
    """The image row (continuous: a pixel's centre at its index) where a body top at the typical height
    ``vehicle_body_top_typical_m`` projects at depth ``z`` (m), the camera ``camera_height_m`` high and
    pitched down ``camera_pitch_rad``."""
    p = ctx.params
    return float(ctx.intrinsics.cy + ((p.camera_height_m - p.vehicle_body_top_typical_m) / np.cos(p.camera_pitch_rad)
                                      - z * np.tan(p.camera_pitch_rad)) * float(ctx.intrinsics.fy) / z)


def _glass_end(ctx: Context, y0: int, pr0: int, z: float) -> int:
    """The first row (local, box origin ``y0``) below a vehicle's cabin glass, which ends ``PANE_INSET_M``
    above the body top at row ``pr0`` (the face's first row, at depth ``z``).

    A body top found on the silhouette (its first full-width row) has its edge between ``pr0 - 1`` and
    ``pr0``: the glass ends ``PANE_INSET_M`` rows above that edge. A body top put at the typical height
    (a narrow face: far cars) is a projected line, not a pixel edge: ``pr0`` is that line's row rounded,
    the line runs through the row's pixels, and the glass holds the rows whose centres lie above it less
    the inset (docs/proposals.md, "Twelfth pass: far cars' panes"). Taking the rounded row for an edge
    put the band's bottom half a row to a row and a half too high on every far car (2048x1024 hard seeds
    0-2, cars beyond 80 m: 49 of 72 matched panes ended 1-3 rows above their true bottom, 16 on it)."""
    inset = PANE_INSET_M * float(ctx.intrinsics.fy) / z
    row = _typical_top_row(ctx, z) - y0
    if round(row) == pr0:
        return max(0, int(np.ceil(row - inset)))
    return max(0, pr0 - int(round(inset)))


def _cut_top(ctx: Context, y0: int, x0: int, m: np.ndarray, rows_cols: tuple[int, int], c0: int, c1: int,
             r0: int, z: float) -> int:
    """The end face's top row (local) when the car in front hides its lower rows: :func:`_body_rows` wants
    full-width rows over 0.15 of the silhouette's height and, failing that, took the lower 60 %, whose top
    is the cabin's or 0.1-0.2 m below the body's (2048x1024 hard seed 0: 18 full-width rows of 137 under
    the car in front). When
    the full-width run over the columns ``rows_cols`` (those :func:`_body_rows` judged) is shorter than
    that and ends at a nearer object (:func:`_cut_below`), the top is the run's, moved below the lid by
    its depth (:func:`_below_lid`) over the face's columns c0..c1 alone (over all the silhouette's, the
    face's depth below the cut is the side face's: the car in front hides the face's outer part); ``r0``
    unchanged otherwise, and when the result is at an implausible height (``vehicle_body_top_m``)
    (docs/proposals.md, "Ninth pass: vehicle lamps under the car in front")."""
    h, w = m.shape
    c0, c1 = max(c0, 0), min(c1, w - 1)
    a, b = max(rows_cols[0], 0), min(rows_cols[1], w - 1)
    if c1 - c0 + 1 < ctx.params.vehicle_small_face_px:
        return r0
    ys = np.flatnonzero(m.any(1))
    fill = m[:, a:b + 1].sum(1)
    body = _run(fill >= 0.95 * max(1, fill.max()))
    if body is None or not 2 <= body[1] - body[0] + 1 < 0.15 * (ys[-1] - ys[0] + 1) or \
            not _cut_below(ctx, y0, x0, m, body[1], a, b):
        return r0
    top = body[0]
    if ctx.params.vehicle_lid_max_m > 0:
        top = _below_lid(ctx, y0, x0, m, c0, c1, body[0], int(ys[-1]), z)
    top_h = float(ctx.height_above_ground(y0 + top, z))
    lo_h, hi_h = ctx.params.vehicle_body_top_m
    return int(top) if lo_h <= top_h <= hi_h else r0


def _end_face(ctx: Context, cls: int, y0: int, x0: int, m: np.ndarray
              ) -> tuple[int, int, int, int, float | None, bool] | None:
    """:func:`_end_face_in` over the columns the silhouette holds at body height (0.35-0.7 of its
    height from the top): a car behind a lower one shows its cabin over the other's bonnet, and those
    columns are not its end face (the face was laid out from the far end of the cabin strip, 2048x1024
    default seed 2)."""
    ys = np.flatnonzero(m.any(1))
    sil_h = int(ys[-1] - ys[0] + 1)
    band = m[ys[0] + int(0.35 * sil_h):ys[0] + int(np.ceil(0.7 * sil_h)) + 1]
    cols = np.flatnonzero(band.any(0))
    if cols.size == 0 or (cols[0] == 0 and cols[-1] == m.shape[1] - 1):
        return _end_face_in(ctx, cls, y0, x0, m)
    a, b = int(cols[0]), int(cols[-1])
    face = _end_face_in(ctx, cls, y0, x0 + a, m[:, a:b + 1])
    if face is None:
        return None
    r0, r1, c0, c1, z, placed = face
    return r0, r1, c0 + a, c1 + a, z, placed


def _end_face_in(ctx: Context, cls: int, y0: int, x0: int, m: np.ndarray
                 ) -> tuple[int, int, int, int, float | None, bool] | None:
    """Box (r0, r1, c0, c1 inclusive, local; c0/c1 may lie outside the mask's box when the face is cut
    by the image border or an occluder) of the body's end face the camera sees, its depth (m), and
    whether it is placed (False: cut by a nearer object beside it -- the car in front in a row of
    parked cars -- with no inner edge found, so the box is laid out from the occluder's edge and the
    lamps behind it are hidden; or a silhouette narrower than ``vehicle_min_face_share`` of the face,
    not cut by the image border: no lamps are proposed on it).

    Columns: the end face is a vertical plane across the vehicle, so it starts at the silhouette's
    nearer side (with depth: the side whose columns are nearer, by more than
    ``vehicle_face_tol_m`` / ``vehicle_side_tie_rel`` of depth; without, or within that: the side away
    from the image centre, as for vehicles parallel to the street) and spans the vehicle's width
    (``vehicle_width_m`` at that depth; without depth 1.2 silhouette heights). Rows: the body
    rows, where the silhouette fills at least 95 % of its fullest row over the face (the cabin
    above is narrower and set back, the wheels below are apart); failing that, the lower 60 %.
    The face's inner edge snaps to the shading step between end and side face; when its outer edge
    is not the vehicle's (the image border, or a nearer object right beside it), the face is laid
    out from the inner edge instead -- beside a nearer object, an inner edge from depth alone moves in to
    the pillar between end and side pane when the body shows no shading step (:func:`_pillar_edge`).
    """
    p = ctx.params
    H, W = ctx.shape
    h, w = m.shape
    ys = np.flatnonzero(m.any(1))
    sil_h = int(ys[-1] - ys[0] + 1)
    z = None
    left_side = x0 + (w - 1) / 2.0 < float(ctx.intrinsics.cx)  # left of the principal point: face on the left
    if ctx.depth is not None:
        d = np.where(m, ctx.depth[y0:y0 + h, x0:x0 + w], np.inf)
        col = d.min(0)
        ok = np.isfinite(col)
        if ok.sum() >= 2:
            k = max(1, w // 5)
            a_, b_ = col[:k][np.isfinite(col[:k])], col[-k:][np.isfinite(col[-k:])]
            if a_.size and b_.size:
                za, zb = float(median(a_)), float(median(b_))
                # Ends within the face's own depth tolerance are one depth to predicted depth (a far car's
                # side face blurs into its end face): the side away from the image centre, as without depth.
                if abs(za - zb) > max(p.vehicle_face_tol_m, p.vehicle_side_tie_rel * min(za, zb)):
                    left_side = za <= zb
            near = col[:k] if left_side else col[-k:]
            near = near[np.isfinite(near)]
            z = float(np.percentile(near if near.size else col[ok], 50))
    if z is not None:
        width_m = p.vehicle_width_m[0] if cls == 26 else p.vehicle_width_m[1]
        face_w = max(2, int(round(width_m * float(ctx.intrinsics.fx) / z)))
    else:
        face_w = max(2, int(round(1.2 * sil_h)))
    fw_in = min(w, face_w)
    c0, c1 = (0, fw_in - 1) if left_side else (w - fw_in, w - 1)
    r0, r1 = _body_rows(ctx, y0, m, c0, c1, z, x0)
    rows_cols = (c0, c1)
    # Is the outer edge the vehicle's own? Not at the image border, nor beside a nearer object.
    outer_g = x0 - 1 if left_side else x0 + w
    cut = not 0 <= outer_g < W
    at_border = cut
    if not cut and ctx.depth is not None and z is not None:
        cut = _nearer_beside(ctx, y0 + r0, y0 + r1, outer_g, z)
    outer = 0 if left_side else w - 1
    inner = None
    if p.vehicle_face_from_depth and z is not None:
        near = _near_columns(ctx, y0, x0, m, r0, r1)
        if near is not None:
            idx = np.flatnonzero(near)  # the run of near columns that starts on the face's side
            if idx.size:
                run_end = _run_from(near, int(idx[0] if left_side else idx[-1]), 1 if left_side else -1)
                if cut and not at_border:  # the face's run, not a few of its columns seen past the car in front
                    s_, e_ = _run(near)
                    if e_ - s_ > abs(run_end - (idx[0] if left_side else idx[-1])):
                        run_end = e_ if left_side else s_
                # Cut by the car in front or the frame's border, only a strip of the end face may show
                # A run ending at the silhouette's other end where a nearer object stands too (the car
                # ahead in our lane beside a parked car the car in front cuts) ends at no edge of the face.
                far_g = x0 + run_end + (1 if left_side else -1)
                other_cut = (cut and not at_border and run_end == (w - 1 if left_side else 0)
                             and 0 <= far_g < W and _nearer_beside(ctx, y0 + r0, y0 + r1, far_g, z))
                if abs(run_end - outer) + 1 >= (p.vehicle_cut_min_strip if cut else 0.3) * face_w and not other_cut:
                    inner = run_end
                    if cut and not at_border:
                        inner = _pillar_edge(ctx, y0, x0, m, r0, r1, inner, face_w, left_side, z)
    if inner is None and face_w >= 6:
        lo, hi = (outer + face_w // 3, outer + 2 * face_w) if left_side else (outer - 2 * face_w, outer - face_w // 3)
        if cut and not at_border:  # the strip left of the end face lies within a face width of the cut
            k = max(2, int(round(p.vehicle_cut_min_strip * face_w)))
            lo, hi = (outer + k, outer + face_w) if left_side else (outer - face_w, outer - k)
        j = _step_column(ctx, y0, x0, m, r0, r1, lo, hi)
        if j is not None:
            inner = j if left_side else j + 1
    found = inner
    if cut and inner is not None:
        outer = inner - face_w + 1 if left_side else inner + face_w - 1
    elif inner is None or not 0.6 * face_w <= abs(inner - outer) + 1 <= 1.3 * face_w:
        inner = outer + face_w - 1 if left_side else outer - face_w + 1
    c0, c1 = (outer, inner) if left_side else (inner, outer)
    if z is not None and ctx.depth is not None:
        r0 = _cut_top(ctx, y0, x0, m, rows_cols, c0, c1, r0, z)
    # Cut by a nearer object beside it and no inner edge found: the face's place is a guess laid out
    # from the occluder's edge, where the lamps are hidden (the car in front) -- say so.
    placed = not (cut and not at_border and found is None)
    # A silhouette much narrower than the face it must hold (a far car in a row, a strip beside the car
    # in front) places nothing either, unless the image border cut it.
    if not at_border and w < p.vehicle_min_face_share * face_w:
        placed = False
    return r0, r1, c0, c1, z, placed


def _nearer_beside(ctx: Context, ya: int, yb: int, g: int, z: float) -> bool:
    """Whether image column ``g`` over rows ``ya``..``yb`` holds a nearer object than depth ``z`` (m): its
    median depth more than 0.3 m nearer (the car in front beside a face)."""
    beside = ctx.depth[ya:yb + 1, g]
    beside = beside[np.isfinite(beside)]
    return bool(beside.size and median(beside) < z - 0.3)


def _pillar_edge(ctx: Context, y0: int, x0: int, m: np.ndarray, r0: int, r1: int, inner: int, face_w: int,
                 left_side: bool, z: float) -> int:
    """The end face's inner edge (local column) of a face laid out from it (its outer edge hidden by a
    nearer object), moved in to the pillar between end and side pane when the body rows' depth run
    ``inner`` overreaches: predicted depth blurs a side face that recedes a few metres into the end
    face's run, and one paint on both faces shows no shading step (2048x1024 lights seed 1: 27 px, a
    lamp placed beside its own). The cabin's glass does step where the rear window (or windscreen)
    meets the side window at the pillar: the strongest shading step (:func:`_step_column`) over the
    cabin rows (``PANE_INSET_M``..``vehicle_pillar_rows_m`` above the body top) within
    ``vehicle_pillar_reach`` of the face's width inward of ``inner``, with glass beyond it (the side
    pane: its luminance off the body's paint by more than the step, 0.03, over a pillar's width -- not the
    end pane's own edge, beyond which the pillar's paint follows); else ``inner`` as found."""
    p = ctx.params
    ppm = float(ctx.intrinsics.fy) / z
    ra = max(0, r0 - int(round(p.vehicle_pillar_rows_m * ppm)))
    rb = r0 - 1 - int(round(PANE_INSET_M * ppm))
    reach = int(round(p.vehicle_pillar_reach * face_w))
    if rb - ra < 1 or reach < 2 or PILLAR_M * ppm < p.vehicle_pillar_min_px:
        return inner  # a far car's pillar is a pixel or two: the pane's own edge steps as much
    strip = int(np.ceil(p.vehicle_cut_min_strip * face_w))  # as the run: a strip of the face stays in view
    lo, hi = (max(inner - reach, strip), inner) if left_side else (inner, min(inner + reach, m.shape[1] - 1 - strip))
    if hi - lo < 1:
        return inner
    if _step_column(ctx, y0, x0, m, r0, r1, lo, hi) is not None:
        return inner  # the body shows where its faces meet: depth's run is not the only cue
    j = _step_column(ctx, y0, x0, m, ra, rb, lo, hi)
    if j is None:
        return inner
    # A pillar, not the end pane's own edge: beyond the step the cabin holds glass (the side pane), not
    # the paint (the pillar itself, and the silhouette's end, when the face ends where the run does).
    k = max(1, int(round(PILLAR_M * ppm)))
    cols = np.arange(j + 1, j + 1 + k) if left_side else np.arange(j - k + 1, j + 1)
    cols = cols[(cols >= 0) & (cols < m.shape[1])]
    lum = ctx.lum[y0:y0 + m.shape[0], x0:x0 + m.shape[1]]
    beyond = m[ra:rb + 1][:, cols]
    body = m[r0:r1 + 1]
    if not beyond.any() or not body.any():
        return inner
    paint = float(median(lum[r0:r1 + 1][body]))
    if abs(float(median(lum[ra:rb + 1][:, cols][beyond])) - paint) <= 0.03:
        return inner
    return j if left_side else j + 1


def _centres_in(lo: float, hi: float) -> tuple[int, int]:
    """First and last integer whose pixel centre lies in [lo, hi] (the nearest one when none does)."""
    a, b = int(np.ceil(lo)), int(np.floor(hi))
    if b < a:
        a = b = int(round((lo + hi) / 2.0))
    return a, b


def _unblur(blob: np.ndarray, lamp_h: float, lamp_w: float) -> np.ndarray:
    """A small lamp's pixels from the blob of colour it leaves in the photo: the blob's box less a pixel
    at each end of every direction in which it is at least 3 px and more than 1.4 px thicker than the lamp
    (``lamp_h`` x ``lamp_w`` px): a lamp's colour bleeds a pixel around it (antialiasing, and the day
    render's edge blur), and its label holds the pixels whose centres it covers. The box, not the blob's
    own pixels eroded: a lamp whose rim stands out of the paint more than its middle (a bright rim about a
    lens dim by day) leaves a ring, whose eroded pixels are a pixel or two of the rim (docs/proposals.md,
    "Thirteenth pass: vehicle lamps")."""
    ys, xs = np.nonzero(blob)
    if ys.size == 0:
        return blob
    y_a, y_b, x_a, x_b = int(ys.min()), int(ys.max()), int(xs.min()), int(xs.max())
    if y_b - y_a + 1 >= max(3.0, lamp_h + 1.4):
        y_a, y_b = y_a + 1, y_b - 1
    if x_b - x_a + 1 >= max(3.0, lamp_w + 1.4):
        x_a, x_b = x_a + 1, x_b - 1
    out = np.zeros_like(blob)
    out[y_a:y_b + 1, x_a:x_b + 1] = True
    return out


def _lamp_core_widened(blob: np.ndarray, lamp_w: float, ok: np.ndarray) -> np.ndarray:
    """A far lamp snapped to fewer columns than it spans: the blob's rows over the columns whose centres lie
    within half the lamp's width (``lamp_w`` px, its metric 0.30 m) of the blob's middle, on the pixels
    ``ok`` (the car's, clear of the plate zone); the blob itself when it is no more than the blur (1.4 px, as
    :func:`_unblur`) narrower than the lamp, or when no such pixel is ``ok``. By day a far lamp departs from
    the paint by the snap's 40 levels only in its brightest column or two (a lens lit at its middle, or a
    rim): the label holds the whole lens (512x256 hard seed 2, a 3 x 2-px lamp snapped to its middle
    column, and its mate mirrored from it -- docs/proposals.md, "Fifteenth pass: vehicle lamps at
    512x256")."""
    cols = np.flatnonzero(blob.any(0))
    if cols.size == 0 or cols[-1] - cols[0] + 1 >= lamp_w - 1.4:
        return blob
    mid = float(cols.mean())
    a, b = _centres_in(mid - lamp_w / 2.0, mid + lamp_w / 2.0)
    wide = np.zeros_like(blob)
    wide[blob.any(1), max(a, 0):b + 1] = True
    wide &= ok
    return wide if wide.any() else blob


def _with_rim(blob: np.ndarray, dep: np.ndarray, ok: np.ndarray, share: float) -> np.ndarray:
    """A lamp snapped to the pixels departing from the paint by the snap's 40 levels, trimmed to its edge:
    its full pixels and the rim beside them.

    ``dep``: per pixel the largest channel difference from the paint; the lamp's own departure is its
    90th percentile over ``blob``, and its full pixels those at ``RIM_FULL`` of that or more. A lamp's
    edge pixel holds part lamp and part paint (antialiasing, and the day render's 3x3 blur of the ambient
    light at edges), so the label's outermost pixels are those beside a full pixel, and the blur's reach
    beyond them departs less again:
    * the pixels 8-adjacent to a full pixel, ``ok`` (the car's, clear of the plate zone) and departing by
      ``share`` to ``RIM_MIXED`` of the lamp are added -- a sharp edge half covering its pixel departs
      by about half, under the snap's 40 levels on a lamp of 60-90 (512x256 hard seeds 0-1: 70-96-px red
      lamps proposed a pixel short on every side, IoU 0.57-0.69);
    * the blob's own outermost pixels beside no full pixel and under ``RIM_MIXED`` of the lamp are
      dropped -- a bright lamp's blur past its edge departs by half of 110 levels, over the 40 (512x256
      default seed 4, hard seed 3: 8 x 4-px lamps a pixel too large on every side, IoU 0.57-0.58).
    The trimmed pixel must lie outside a pixel of the blob's inside departing ``RIM_STEP`` of the lamp more
    than it does (the edge's ramp falling outward: a dim lamp between brighter paint, whose strong pixels are the blob's ends, is
    left alone -- 2048x1024 hard seed 5, a 3 x 7-px lamp), and a blob the trim would empty is kept whole.
    docs/proposals.md, "Fifteenth pass: vehicle lights at
    512x256 -- the touch-ups"."""
    import cv2

    if not blob.any():
        return blob
    k3 = np.ones((3, 3), np.uint8)
    top = float(np.percentile(dep[blob], 90))
    full = blob & (dep >= RIM_FULL * top)
    near = cv2.dilate(full.astype(np.uint8), k3).astype(bool)
    out = blob | (near & ~blob & ok & (dep >= share * top) & (dep <= RIM_MIXED * top))
    inner = cv2.erode(blob.astype(np.uint8), k3, borderType=cv2.BORDER_CONSTANT, borderValue=0).astype(bool)
    # the blur past the edge: an outermost pixel beside no full pixel, clearly weaker than the rim inside it
    rim_in = cv2.dilate(np.where(inner, dep, 0.0).astype(np.float32), k3) >= dep + RIM_STEP * top
    kept = out & ~(blob & ~inner & ~near & rim_in & (dep < RIM_MIXED * top))
    return kept if kept.any() else out


def _blob_at(mask: np.ndarray, r: float, c: float) -> np.ndarray:
    """The connected part of ``mask`` nearest to (row r, column c) (a lamp, not the shading beside it)."""
    import cv2

    if not mask.any():
        return mask
    n, lab, stats, cent = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 2:
        return mask
    d = np.hypot(cent[1:, 0] - c, cent[1:, 1] - r) / np.sqrt(stats[1:, cv2.CC_STAT_AREA])
    return lab == 1 + int(np.argmin(d))


def _small_face_top(m: np.ndarray, c0: int, c1: int, r0: int) -> int:
    """A narrow end face's top row (local): the silhouette's first full-width row over columns c0..c1 when
    it is at most ``SMALL_TOP_MOVE`` rows from ``r0`` (the typical body height's row, a row or two off at
    50-60 m), else ``r0``."""
    fill = m[:, c0:c1 + 1].sum(1)
    body = _run(fill >= 0.95 * max(1, fill.max()))
    return int(body[0]) if body is not None and abs(body[0] - r0) <= SMALL_TOP_MOVE else r0


def _lamp_pair(ctx: Context, y0: int, x0: int, m: np.ndarray, img: np.ndarray, paint: np.ndarray,
               face: tuple[int, int, int, int], z: float | None) -> tuple[list[np.ndarray], int]:
    """The two lamps of an end face (local masks; fewer when hidden or beyond the frame) and how many
    were snapped to pixels that differ from the paint.

    A lamp box sits ``vehicle_lamp_rows_m`` below the body top and ``vehicle_lamp_cols_m`` in from
    each side of the face (fractions without depth). Each box is snapped to the pixels within a
    window around it (half its rows, at least two, above and below) that differ from the paint, never in the plate zone (``vehicle_plate_half_m``
    either side of the face's axis: plates are never lamps). The pair is then made symmetric about
    the vehicle's vertical axis: the point between the two snapped lamps (else the face's centre);
    two snapped lamps that agree (rows and columns overlapping by half) take their mean rows and
    distances from the axis (a lamp under ``SMALL_LAMP_PX`` tall: the pixel centres its mean rows span), two that disagree stay as found (their pixels), and a lamp that does
    not stand out mirrors the one that does (each snapped to the blob nearest its box); a lamp mostly off the
    silhouette (``vehicle_lamp_min_visible``: hidden, or beyond the border) is dropped. Empty boxes
    are never returned. A lamp under ``SMALL_LAMP_PX`` tall is laid out by pixel centres and a blob it
    snaps to is trimmed of the colour bled around it (:func:`_centres_in`, :func:`_unblur`), and one narrower
    than the lamp by more than that blur (its brightest column) widened to the lamp's width about its middle
    (:func:`_lamp_core_widened`), and it is never snapped to pixels none of which lies as low as a lamp's top
    (``vehicle_small_lamp_top_m`` under the body top: the body's top edge stands out by day); a larger lamp's
    blob takes its antialiased rim (:func:`_with_rim`). A blob is
    taken when it holds at least a third of the box's pixels not hidden by a nearer object
    (:func:`_hidden`); for boxes of ``OPEN_LAMP_PX`` rows or more, from the off-paint pixels after a 3x3
    opening (the 1-px seam a car in front bleeds along the silhouette's edge joined the lamp).
    """
    p = ctx.params
    h, w = m.shape
    r0, r1, c0, c1 = face
    fh, fw = r1 - r0 + 1, c1 - c0 + 1
    cc0, cc1 = max(c0, 0), min(c1, w - 1)
    small = z is not None and 0.15 * float(ctx.intrinsics.fy) / z < SMALL_LAMP_PX
    if small:
        # A lamp of a few pixels: the pixels whose centres lie in its metric box, as the photo's labels
        # are (docs/proposals.md, "Seventh pass: far vehicle lamps"), under the body's top edge: the
        # silhouette's first full-width row (a narrow face's r0 is the typical body height, a row or two
        # off at 50-60 m) when near r0.
        ppm = float(ctx.intrinsics.fy) / z
        top = _small_face_top(m, cc0, cc1, r0) - 0.5
        lr0, lr1 = _centres_in(top + p.vehicle_lamp_rows_m[0] * ppm, top + p.vehicle_lamp_rows_m[1] * ppm)
        a, b = _centres_in(-0.5 + p.vehicle_lamp_cols_m[0] * ppm, -0.5 + p.vehicle_lamp_cols_m[1] * ppm)
        plate = p.vehicle_plate_half_m * ppm
    elif z is not None:
        ppm = float(ctx.intrinsics.fy) / z
        lr0 = r0 + int(np.floor(p.vehicle_lamp_rows_m[0] * ppm))
        lr1 = max(lr0, r0 + int(np.ceil(p.vehicle_lamp_rows_m[1] * ppm)) - 1)
        a = int(np.floor(p.vehicle_lamp_cols_m[0] * ppm))
        b = max(a, int(np.ceil(p.vehicle_lamp_cols_m[1] * ppm)) - 1)
        plate = p.vehicle_plate_half_m * ppm
    else:
        lr0 = r0 + int(np.floor(p.vehicle_lamp_rows[0] * fh))
        lr1 = max(lr0, r0 + int(np.ceil(p.vehicle_lamp_rows[1] * fh)) - 1)
        a = int(np.floor(p.vehicle_lamp_cols[0] * fw))
        b = max(a, int(np.ceil(p.vehicle_lamp_cols[1] * fw)) - 1)
        plate = p.vehicle_plate_half_frac * fw
    axis = (c0 + c1) / 2.0
    cols = np.arange(w)
    off_plate = np.abs(cols + 0.5 - (axis + 0.5)) > plate            # columns clear of the plate zone
    dep = _chan_max(np.abs(img - paint))
    diff = dep > 40.0
    if (lr1 - lr0 + 1) >= OPEN_LAMP_PX:
        # A lamp this tall survives a 3x3 opening; the 1-px seams of colour bled from a car in front along
        # the silhouette's edge do not, and no longer join a lamp beside the cut (2048x1024 hard seed 0).
        import cv2

        diff = cv2.morphologyEx((diff & m).astype(np.uint8), cv2.MORPH_OPEN,
                                np.ones((3, 3), np.uint8)).astype(bool)
    boxes: list[tuple[int, int, int, int, bool] | None] = []          # rows, cols (face coords), snapped?
    blobs: list[np.ndarray | None] = []                                # the snapped pixels
    for side in (0, 1):
        bc0, bc1 = (c0 + a, c0 + b) if side == 0 else (c1 - b, c1 - a)
        br0, br1 = lr0, lr1
        win = np.zeros_like(m)
        # Faces are placed to a lamp's width; their top to a row or two (the cabin's 0.1 m inset is a pixel
        # or two on a far car, and hidden where the car in front cuts the face): the window reaches at
        # least two rows beyond the box. Not stopped at the face's last row r1: that is where its fill drops,
        # and a car in front hiding the face's other side from some row down drops it there too, while the
        # lamp on the side still seen runs on below (512x256 default seed 0: a 15 x 8-px lamp snapped to its
        # upper 5 rows, IoU 0.52). The window keeps to the silhouette (``m``) as before.
        pad_r, pad_c = max(2, (br1 - br0 + 1) // 2), max(1, bc1 - bc0 + 1)
        wr0, wr1 = max(r0, br0 - pad_r, 0), min(br1 + pad_r, h - 1)
        wc0, wc1 = max(cc0, bc0 - pad_c, 0), min(cc1, bc1 + pad_c, w - 1)
        snapped = False
        blob = None
        if wr1 >= wr0 and wc1 >= wc0:
            win[wr0:wr1 + 1, wc0:wc1 + 1] = True
            win &= m & off_plate[None, :]
            cand = _blob_at(win & diff, (br0 + br1) / 2.0, (bc0 + bc1) / 2.0)
            # A lamp half hidden by the car in front is judged by the box's pixels not hidden by it
            # (2048x1024 hard seed 2: a red lamp of 196 px in a 612-px box, 154 px of it behind the car).
            ya, yb, xa, xb = max(br0, 0), min(br1, h - 1) + 1, max(bc0, 0), min(bc1, w - 1) + 1
            full = max(1, (yb - ya) * (xb - xa))
            if z is not None and ctx.depth is not None and yb > ya and xb > xa:
                full = max(1, full - int(_hidden(ctx, y0 + ya, x0 + xa, m[ya:yb, xa:xb], z).sum()))
            n = int(cand.sum())
            rows = np.flatnonzero(cand.any(1))
            tall = rows.size and rows[-1] - rows[0] + 1 > LAMP_TALL_RATIO * (br1 - br0 + 1) + 2
            top_m = p.vehicle_small_lamp_top_m
            if small and top_m > 0 and rows.size and rows[-1] - top < top_m * ppm:
                # No pixel centre as low as a lamp's top (0.07 m under the body top): the body's top edge (the
                # deck's, the cabin seam's) by day (512x256 default seed 0: a 3-px false lamp on the body's top
                # row, two rows above the lamp).
                n = 0
            if n and small and p.vehicle_small_lamp_edge_bleed and _edge_bleed(ctx, y0, x0, m, cand):
                n = 0  # the background's colour bled into the silhouette's last column, not a lamp
            if n and p.vehicle_border_dark_levels > 0 and _dark_at_border(img, cand, paint, x0, ctx.shape[1],
                                                                         p.vehicle_border_dark_levels):
                n = 0  # the dark trim or glass of a near car's end the frame cuts, not a lamp
            if n >= max(1, full // 3) and n <= 3 * full and not tall:
                if small:
                    inside = _unblur(cand, 0.15 * ppm, 0.30 * ppm) & m
                    cand = inside if inside.any() else cand
                    cand = _lamp_core_widened(cand, 0.30 * ppm, m & off_plate[None, :])
                else:
                    cand = _with_rim(cand, dep, m & off_plate[None, :], p.vehicle_lamp_rim_share)
                ys, xs = np.nonzero(cand)
                br0, br1, bc0, bc1 = int(ys.min()), int(ys.max()), int(xs.min()), int(xs.max())
                snapped, blob = True, cand
        boxes.append((br0, br1, bc0, bc1, snapped))
        blobs.append(blob)
    if boxes[0][4] and boxes[1][4]:  # the vehicle's axis lies between its two lamps
        axis = ((boxes[0][2] + boxes[0][3]) / 2.0 + (boxes[1][2] + boxes[1][3]) / 2.0) / 2.0
    # (rows, outer and inner distance from the axis) per side, from its own box
    own = [(bx[0], bx[1], axis - bx[2] if k == 0 else bx[3] - axis, axis - bx[3] if k == 0 else bx[2] - axis)
           for k, bx in enumerate(boxes)]
    snapped = [k for k in (0, 1) if boxes[k][4]]
    pair = False
    if len(snapped) == 2:
        (a0, a1, ao, ai), (b0, b1, bo, bi) = own
        rows_agree = min(a1, b1) - max(a0, b0) + 1 >= 0.5 * min(a1 - a0 + 1, b1 - b0 + 1)
        cols_agree = min(ao, bo) - max(ai, bi) >= 0.5 * min(ao - ai, bo - bi)
        if rows_agree and cols_agree:  # one lamp pair: the mean rows and distances for both
            mean = tuple(float(np.mean([own[0][q], own[1][q]])) for q in range(4))
            own = [mean, mean]
            pair = True
        # else each keeps what it snapped to (one of them caught something else; both stay as found)
    elif len(snapped) == 1:  # the other lamp mirrors the one that stands out
        own = [own[snapped[0]], own[snapped[0]]]
    lamps: list[np.ndarray] = []
    n_snapped = 0
    for side in (0, 1):
        if boxes[side][4] and not pair:  # a lamp that stands out on its own: its pixels, as found
            lamps.append(blobs[side])
            n_snapped += 1
            continue
        if small:  # the pair's mean rows (half-pixel ends) as the pixel centres they span, not each end rounded
            rr0, rr1 = _centres_in(own[side][0] - 0.5, own[side][1] + 0.5)
        else:
            rr0, rr1 = int(round(own[side][0])), int(round(own[side][1]))
        d_out, d_in = own[side][2], max(own[side][3], 0.5)
        lo_c = int(round(axis - d_out)) if side == 0 else int(round(axis + d_in))
        hi_c = int(round(axis - d_in)) if side == 0 else int(round(axis + d_out))
        full = max(0, rr1 - rr0 + 1) * max(0, hi_c - lo_c + 1)
        box = np.zeros_like(m)
        y_a, y_b, x_a, x_b = max(rr0, 0), min(rr1, h - 1), max(lo_c, 0), min(hi_c, w - 1)
        if full == 0 or y_b < y_a or x_b < x_a:
            continue  # that lamp is beyond the image border
        box[y_a:y_b + 1, x_a:x_b + 1] = True
        box &= m & off_plate[None, :]
        if box.sum() < max(1.0, p.vehicle_lamp_min_visible * full):
            continue  # mostly hidden (by the vehicle in front, or the box left the silhouette)
        lamps.append(box)
        n_snapped += int(boxes[side][4])
    return lamps, n_snapped


def _edge_bleed(ctx: Context, y0: int, x0: int, m: np.ndarray, blob: np.ndarray) -> bool:
    """Whether every pixel of a small lamp's snapped blob (local bool mask at image row ``y0``, column ``x0``)
    lies in the silhouette's last column beside background (``BACKGROUND``: road, pavement, building, sky...
    -- not another vehicle or an occluder): the background's colour bled into the car's edge by antialiasing
    and blur departs from the paint as a lamp does (512x256 default seed 5: a red car at 56 m whose left lamp
    box snapped to its edge column, grey of the street on 84 / 25 / 25 paint, two rows below the lamp; its mate
    mirrored it, both false). At a cut by the car in front the sliver there is the lamp's (512x256 default seed 11)."""
    H, W = ctx.shape
    h, w = m.shape
    ys, xs = np.nonzero(blob)
    if ys.size == 0:
        return False
    beside_bg = np.zeros(ys.size, bool)
    for dx in (-1, 1):
        lx, gx = xs + dx, x0 + xs + dx
        off_sil = (lx < 0) | (lx >= w) | ~m[ys, np.clip(lx, 0, w - 1)]
        in_frame = (gx >= 0) & (gx < W)
        beside_bg |= off_sil & in_frame & np.isin(ctx.labels[y0 + ys, np.clip(gx, 0, W - 1)], BACKGROUND)
    return bool(beside_bg.all())


def _dark_at_border(img: np.ndarray, blob: np.ndarray, paint: np.ndarray, x0: int, width: int,
                    levels: float) -> bool:
    """Whether a lamp box's snapped blob (local bool mask at image column ``x0``) reaches the image's left or
    right border column and its mean colour lies more than ``levels`` (8-bit) below the paint in every
    channel: a near car the frame cuts shows its end's dark trim or glass there (512x256 default seed 3: a
    106-px blob of 63 / 72 / 84 on 112 / 118 / 126 paint at the right border), while a lamp by day is red
    or brighter than the paint -- and one the frame clips shows no shape to judge it by."""
    cols = np.flatnonzero(blob.any(0))
    if cols.size == 0 or not (x0 + cols[0] == 0 or x0 + cols[-1] == width - 1):
        return False
    return bool(np.all(pixels(img, blob).mean(0) < np.asarray(paint, np.float32) - levels))


def _lamp_coloured(c: np.ndarray, paint: np.ndarray, red_share: float, red_only: bool = False) -> np.ndarray:
    """Whether colours (..., 3; 8-bit RGB) departing from the paint look like a lamp's: red by day, or
    departing toward red (``red_share``, as the rear-lamp rule), or brighter than the paint (a white
    or amber lamp; not with ``red_only``) -- not the dark glass of a side window, a shadow or a wheel arch."""
    c = np.asarray(c, np.float32)
    r, g, b = c[..., 0], c[..., 1], c[..., 2]
    d = c - np.asarray(paint, np.float32)
    dn = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2])  # (d * d).sum(-1)
    # ... and has a colour: a black wheel or grey shadow on blue paint departs "towards red" too (its red
    # drops least), but a lamp's colour, bled into the paint around it, keeps some saturation
    leans_red = (d[..., 0] - np.maximum(d[..., 1], d[..., 2]) > red_share * dn) & \
        (_chan_max(c) - np.minimum(np.minimum(r, g), b) > LAMP_MIN_CHROMA)
    red = ((r > 1.5 * np.maximum(g, b)) & (r > 50)) | ((dn > 10.0) & leans_red)
    # (the channels' mean as numpy's mean over them: their sum over 3, elementwise)
    return red if red_only else red | ((d[..., 0] + d[..., 1] + d[..., 2]) / 3 > 20.0)


def _cut_band(ctx: Context, y0: int, x0: int, m: np.ndarray, z: float, centre_side: bool = False
              ) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, int] | None:
    """Where :func:`_sliver_lamp` looks: (pixels per metre at depth ``z``, the rows at lamp heights
    (``SLIVER_H_M``, a bool per row of the local box), their indices, per row the silhouette's end on the cut
    side (local column), the step outward from it: -1 or 1), or None when the vehicle is not cut there (at
    least half of those rows with the pixel beyond the end off the frame or a nearer thing than background),
    has no depth, or its whole lamp would be under ``SLIVER_MIN_LAMP_PX`` tall."""
    H, W = ctx.shape
    h, w = m.shape
    ppm = float(ctx.intrinsics.fy) / z
    if ctx.depth is None or 0.15 * ppm < SLIVER_MIN_LAMP_PX:
        return None
    has = m.any(1)
    hts = ctx.height_above_ground(y0 + np.arange(h), z)
    band = has & (hts >= SLIVER_H_M[0]) & (hts <= SLIVER_H_M[1])
    br = np.flatnonzero(band)
    if br.size < 2:
        return None
    left = (x0 + w / 2.0 < float(ctx.intrinsics.cx)) != centre_side  # the cut side: away from the centre
    end = np.where(has, m.argmax(1), w) if left else np.where(has, w - 1 - m[:, ::-1].argmax(1), -1)
    out_step = -1 if left else 1
    k = max(1, int(round(W / 512)))
    beyond, inside = x0 + end[br] + out_step, x0 + end[br] - out_step * 2 * k
    off = (beyond < 0) | (beyond >= W)
    bd = ctx.depth[y0 + br, np.clip(beyond + out_step * (k - 1), 0, W - 1)]
    own = ctx.depth[y0 + br, np.clip(inside, 0, W - 1)]
    thing = ~np.isin(ctx.labels[y0 + br, np.clip(beyond, 0, W - 1)], BACKGROUND)
    with np.errstate(invalid="ignore"):  # NaN depth: not nearer
        if float((off | (thing & (bd < own))).mean()) < 0.5:
            return None
    return ppm, band, br, end, out_step


def _sliver_lamp(ctx: Context, y0: int, x0: int, m: np.ndarray, img: np.ndarray, z: float,
                 centre_side: bool = False) -> np.ndarray | None:
    """The visible part of a lamp of a vehicle cut on its side away from the image centre -- by the
    car in front of a parked row, which stands further out, or by the frame's border -- or None
    (local mask). The car in front hides all of the end face but a strip at its inner end, whose
    inner lamp shows as a sliver right beside the occluder's edge; the face laid out in metres is a
    few pixels off on predicted depth, so the lamp is looked for at the cut itself
    (docs/proposals.md, "Sixth pass: vehicle lamps beside the cut").

    The cut: over the rows at lamp heights (``SLIVER_H_M`` above the ground at depth ``z``), at least
    half of the pixels just beyond the silhouette's outer end are off the frame or something other
    than background (``BACKGROUND``) nearer than the silhouette two pixels (x W/512) inside. Per row,
    a window from the silhouette's outer end inward over ``SLIVER_REACH_M``; its median colour is the
    paint there (the end face's, not a lit side face's). Lamp pixels depart from it by more than
    ``SLIVER_DIFF`` and look like a lamp (:func:`_lamp_coloured`: red, or brighter -- not glass, a
    shadow or a wheel arch). The lamp is the connected part of them with the most pixels within
    ``SLIVER_MAX_GAP`` of the cut, as tall as a lamp (``SLIVER_ROWS_M``, at least 2 px) and at most a
    lamp wide (0.3 m): its bounding box within the window. None on vehicles whose whole lamp would be
    under ``SLIVER_MIN_LAMP_PX`` tall, without depth, or when nothing fits.

    ``centre_side``: the cut on the side toward the image centre instead -- a car parked beside the lane
    that the car driving ahead (or an oncoming one) hides but a strip, its centre-side lamp showing beside
    that car's edge (2048x1024 lights seed 2) -- where only red lamp pixels count (``_lamp_coloured``'s
    ``red_only``: a parked row beside our lane is seen from behind when parked with the traffic, and a
    white sliver there is as often the glass or bright paint bled at the cut)."""
    import cv2

    p = ctx.params
    cut = _cut_band(ctx, y0, x0, m, z, centre_side)
    if cut is None:
        return None
    ppm, band, br, end, out_step = cut
    w = m.shape[1]
    reach = max(2, int(np.ceil(SLIVER_REACH_M * ppm)))
    ra, rb = int(br[0]), int(br[-1]) + 1  # (the window lies on the band's rows: the rest is never looked at)
    dist = (np.arange(w)[None, :] - end[ra:rb, None]) * -out_step     # pixels inward from the cut, per row
    win, by_cut = np.zeros_like(m), np.zeros_like(m)
    win[ra:rb] = (dist >= 0) & (dist < reach) & band[ra:rb, None] & m[ra:rb]
    by_cut[ra:rb] = dist <= SLIVER_MAX_GAP
    if win.sum() < 4:
        return None
    paint = median(pixels(img, win), axis=0)
    ry, rx = np.flatnonzero(win.any(1)), np.flatnonzero(win.any(0))   # the window's box: colours only there
    box = (slice(ry[0], ry[-1] + 1), slice(rx[0], rx[-1] + 1))
    sub = img[box]
    cand = np.zeros_like(win)
    cand[box] = win[box] & (_chan_max(np.abs(sub - paint)) > SLIVER_DIFF) & \
        _lamp_coloured(sub, paint, p.vehicle_rear_red_share, red_only=centre_side)
    if not cand.any():
        return None
    n, lab, stats, _ = cv2.connectedComponentsWithStats(cand.astype(np.uint8), connectivity=8)
    lo_h = max(2, int(np.floor(SLIVER_ROWS_M[0] * ppm)))
    hi_h = int(np.ceil(SLIVER_ROWS_M[1] * ppm)) + 1
    beside = np.bincount(lab[cand & by_cut], minlength=n)  # per part: pixels by the cut
    best, best_n = None, 0
    for q in range(1, n):
        bh, bw = int(stats[q, cv2.CC_STAT_HEIGHT]), int(stats[q, cv2.CC_STAT_WIDTH])
        if lo_h <= bh <= hi_h and bw <= 0.3 * ppm + 1 and beside[q] > best_n:
            best, best_n = q, int(beside[q])
    if best is None:
        return _sliver_grown(lab, stats, beside, win, box, sub, paint, ppm, (lo_h, hi_h),
                             p.vehicle_sliver_grow_share, p.vehicle_sliver_grow_max_px)
    x, y, bw, bh = (int(v) for v in stats[best, :4])
    out = np.zeros_like(m)
    out[y:y + bh, x:x + bw] = True
    return out & win


def _sliver_under_box(box: np.ndarray, sliver: np.ndarray, tol: int) -> bool:
    """Whether a lamp box laid out by the face's geometry (snapped to nothing) and the sliver found beside
    the cut are one lamp: the sliver's columns within the box's (``tol`` px either way; < 0: never) and its
    rows none of the box's -- the face's top taken rows off under the car in front, the box above or below
    the lamp the image shows (512x256 default seed 0: a red car cut by the car in front, its box 3 rows
    above the sliver, docs/proposals.md "Eighteenth pass: vehicle lamps"). The sliver is then that lamp
    and the box goes."""
    if tol < 0:
        return False
    bx, sx = np.flatnonzero(box.any(0)), np.flatnonzero(sliver.any(0))
    by, sy = np.flatnonzero(box.any(1)), np.flatnonzero(sliver.any(1))
    if not (bx.size and sx.size):
        return False
    return bool(sx[0] >= bx[0] - tol and sx[-1] <= bx[-1] + tol and (sy[0] > by[-1] or sy[-1] < by[0]))


def _sliver_blend(ctx: Context, y0: int, x0: int, m: np.ndarray, z: float, face_top: int) -> np.ndarray | None:
    """A lamp 1 px across at the cut by the car in front, blended with that car's colour (local mask), or
    None: what :func:`_sliver_lamp` does not see when the lamp departs from the paint by less than its 40
    levels (2048x1024 hard seeds 0-2: 10 of the 14 visible lamps missed, 15-47 levels; docs/proposals.md
    "Nineteenth pass: vehicle lamps").

    By day the photo's 3x3 blur spreads such a lamp -- its own edge -- over the cut column and the column
    either side of it alike, the occluder's last and the car's next: over the lamp's rows the three shift
    together by a third of the lamp's departure from the paint (5-16 levels), while the columns two away on
    either side, the occluder's and the car's own, do not. So, over the rows at lamp heights
    (:func:`_cut_band`), per row the cut column's colour less its median over those rows, less the mean of
    the same for the columns two pixels either side: a run of rows where it exceeds
    ``vehicle_sliver_blend_levels`` in some channel, on average over the run too (not rows of a feature the
    neighbours share, nor noise changing sign), as tall as a lamp (``SLIVER_ROWS_M``, at least 3 rows), its top and bottom
    within ``vehicle_sliver_blend_rows_m`` below the end face's top row ``face_top`` (local; under the body
    top the lamp row band, not the body's top edge nor the bumper). The three columns' shifts over the run
    (against as many rows above and below it) must agree -- each within ``vehicle_sliver_blend_spread`` of
    their mean's length from the mean --, the mean be ``vehicle_sliver_blend_shift`` levels long, and be a
    lamp's: brighter in every channel (2 levels' tolerance) or leaning red (red over green and blue by a
    fifth of its length). The mask: the cut column over the run's rows; of several runs, the largest shift.
    A real frame's blur is softer but of the same kind (the lens's, the JPEG's): a thin lamp at an
    occluder's edge shows as a faint band across the edge, not as a colour of its own."""
    p = ctx.params
    lv = p.vehicle_sliver_blend_levels
    if lv <= 0:
        return None
    cut = _cut_band(ctx, y0, x0, m, z)
    if cut is None:
        return None
    ppm, _, br, end, out_step = cut
    H, W = ctx.shape
    xc = x0 + end[br]
    cols = [xc - out_step * d for d in (-2, -1, 0, 1, 2)]  # from the occluder's side inward
    if min(int(c.min()) for c in cols) < 0 or max(int(c.max()) for c in cols) >= W:
        return None
    ys = y0 + br
    P = [ctx.image[ys, c].astype(np.float32) for c in cols]
    dv = [q - median(q, axis=0) for q in P]
    res = dv[2] - 0.5 * (dv[0] + dv[4])
    on = _chan_max(np.abs(res)) > lv
    lo_h = max(3, int(np.floor(SLIVER_ROWS_M[0] * ppm)))
    hi_h = int(np.ceil(SLIVER_ROWS_M[1] * ppm)) + 1
    top_m, bot_m = p.vehicle_sliver_blend_rows_m
    shift_lo, shift_hi = p.vehicle_sliver_blend_shift
    best, best_n = None, 0.0
    i = 0
    while i < on.size:
        if not on[i]:
            i += 1
            continue
        j = i
        while j + 1 < on.size and on[j + 1] and br[j + 1] == br[j] + 1:
            j += 1
        n, a, b = j - i + 1, i, j + 1
        i = j + 1
        top, bot = (br[a] - face_top) / ppm, (br[b - 1] + 1 - face_top) / ppm
        if not (lo_h <= n <= hi_h and top >= top_m and bot <= bot_m):
            continue
        if float(np.abs(res[a:b].mean(0)).max()) <= lv:
            continue
        around = np.r_[np.arange(max(0, a - n), a), np.arange(b, min(on.size, b + n))]
        shifts = [q[a:b].mean(0) - (q[around].mean(0) if around.size else median(q, axis=0)) for q in P[1:4]]
        u = (shifts[0] + shifts[1] + shifts[2]) / 3.0
        nu = float(np.linalg.norm(u))
        if not shift_lo <= nu <= shift_hi:
            continue
        if max(float(np.linalg.norm(v - u)) for v in shifts) >= p.vehicle_sliver_blend_spread * nu:
            continue
        if not ((u.min() > -2.0 and u.sum() > 0) or u[0] - max(u[1], u[2]) > 0.2 * nu):
            continue  # darker, not red: a seam, a shadow, a gap
        if nu > best_n:
            best, best_n = (a, b), nu
    if best is None:
        return None
    out = np.zeros_like(m)
    rr = br[best[0]:best[1]]
    out[rr, end[rr]] = True
    return out & m


def _cut_strip_lamp(ctx: Context, y0: int, x0: int, m: np.ndarray, z: float, face_top: int) -> np.ndarray | None:
    """The part of a cut vehicle's inner lamp its end face's visible strip holds, laid out from the
    silhouette's other end (local mask), or None (docs/proposals.md "Twentieth pass: vehicle lamps")."""
    p = ctx.params
    length = p.vehicle_cut_strip_length_m
    if length <= 0:
        return None
    cut = _cut_band(ctx, y0, x0, m, z)
    if cut is None:
        return None
    ppm, _, br, end, out_step = cut
    if 0.15 * ppm < p.vehicle_cut_lamp_max_px:
        return None  # a far lamp: :func:`_cut_lamp`'s, from the same geometry with the image's test
    h, w = m.shape
    H, W = ctx.shape
    cx = float(ctx.intrinsics.cx)
    if x0 - 0.5 < cx < x0 + w - 0.5:
        return None  # astride the principal point: no side face on one side only
    has = m.any(1)
    # per row the silhouette's end on the centre side: the side face's far end, a vertical edge over the body
    far = np.where(has, w - 1 - m[:, ::-1].argmax(1), -1) if out_step < 0 else np.where(has, m.argmax(1), w)
    hts = ctx.height_above_ground(y0 + np.arange(h), z + length)
    body = has & (hts >= 0.35) & (hts <= p.vehicle_body_top_m[1])
    if not body.any():
        return None
    ext = int(far[body].max() if out_step < 0 else far[body].min())
    at = np.flatnonzero(body & (far == ext))
    r_bt = int(at[0])  # the body's top row at the far end (the cabin above ends short of it, and inset)
    bt_h = float(ctx.height_above_ground(y0 + r_bt - 0.5, z + length))
    lo_h, hi_h = p.vehicle_cut_strip_top_m
    if not lo_h <= bt_h <= hi_h:
        return None
    fy = float(ctx.intrinsics.fy)
    top = float(ctx.intrinsics.cy + ((p.camera_height_m - bt_h) / np.cos(p.camera_pitch_rad)
                                     - z * np.tan(p.camera_pitch_rad)) * fy / z) - y0  # the end face's top edge
    ra, rb = _centres_in(top + p.vehicle_lamp_rows_m[0] * ppm, top + p.vehicle_lamp_rows_m[1] * ppm)
    ra, rb = max(ra, 0), min(rb, h - 1)
    if rb < ra:
        return None
    rows = np.arange(ra, rb + 1)
    rows = rows[has[rows]]
    if rows.size == 0:
        return None
    e = x0 + ext + (0.5 if out_step < 0 else -0.5)
    inner = cx + (e - cx) * (z + length) / z  # the end face's inner edge: the side face spans z..z+length
    a_m, b_m = p.vehicle_lamp_cols_m
    lo, hi = (inner - b_m * ppm, inner - a_m * ppm) if out_step < 0 else (inner + a_m * ppm, inner + b_m * ppm)
    c_a, c_b = max(int(np.ceil(lo - x0)), 0), min(int(np.floor(hi - x0)), w - 1)
    if c_b < c_a:
        return None
    cut_c = end[rows]
    if ((x0 + cut_c + out_step < 0) | (x0 + cut_c + out_step >= W)).any():
        return None  # cut by the frame's border
    c_cut = int(np.round(median(cut_c)))
    # the lamp's inner end past the cut's pixel centre (px): under the margin it may lie behind the cut -- the
    # side face's length (3.9-4.8 m on the streets) moves the inner edge by a tenth of its width either way
    margin_px, margin_share = p.vehicle_cut_strip_margin
    if ((hi - x0 - c_cut) if out_step < 0 else (x0 + c_cut - lo)) < max(margin_px, margin_share * abs(inner - e)):
        return None
    out = np.zeros_like(m)
    out[rows[:, None], np.arange(c_a, c_b + 1)[None, :]] = True
    out &= m
    if not out.any():
        return None
    # a part of the lamp beside the cut: the whole lamp's columns not all on the silhouette
    if np.abs(np.flatnonzero(out.any(0))[:, None] - cut_c[None, :]).min() > 1:
        return None
    return out

def _sliver_grown(lab: np.ndarray, stats: np.ndarray, beside: np.ndarray, win: np.ndarray, box: tuple,
                  sub: np.ndarray, paint: np.ndarray, ppm: float, rows: tuple[int, int],
                  share: float, max_px: float) -> np.ndarray | None:
    """A far lamp beside the cut whose pixels over ``SLIVER_DIFF`` are fewer rows than a lamp's (``rows``,
    :func:`_sliver_lamp`'s lo_h..hi_h), or None: on a vehicle whose whole lamp (0.15 m at ``ppm`` pixels per
    metre) is under ``max_px`` tall the photo's 3x3 blur leaves only the lamp's middle row that far off the
    paint (2048x1024 hard seeds 0, 2: 4 x 3-px lamps at 115 m, 41-42 levels in two pixels of their middle
    row, 27-30 in the rest, 16-26 in the rim the blur spreads a pixel around them).

    Such a part (``lab``'s, by the cut: ``beside`` > 0) is grown to the connected pixels of the window ``win``
    departing from the paint by at least ``share`` of its own peak. That blob must show the blur's rim above
    and below the lamp (at least 1.4 px more rows than the lamp, and 3: else it is a seam's or an edge's
    pixels), and is trimmed of it (:func:`_unblur`); what is left must be a lamp's rows, at most a lamp wide
    (0.3 m + 1 px), with the part in its middle -- not on its top or bottom row: the blur of a lamp falls off
    about its middle (a seam's run of colour, 2048x1024 hard seed 5, does not). Of such parts the one with
    most pixels by the cut. ``box``: the window's box, ``sub`` the image there, ``paint`` the window's paint
    (local to the vehicle's box as ``win``). docs/proposals.md, "Sixteenth pass: vehicle lamps at 2048x1024
    on the hard street"."""
    import cv2

    if share <= 0 or share >= 1 or 0.15 * ppm >= max_px:
        return None
    lo_h, hi_h = rows
    dev = np.zeros(win.shape, np.float32)
    dev[box] = _chan_max(np.abs(sub - paint))
    best, best_n = None, 0
    for q in range(1, stats.shape[0]):
        if int(stats[q, cv2.CC_STAT_HEIGHT]) >= lo_h or beside[q] <= best_n:
            continue
        part = lab == q
        region = (win & (dev >= share * float(dev[part].max()))).astype(np.uint8)
        _, rl = cv2.connectedComponents(region, connectivity=8)
        grown = np.isin(rl, np.unique(rl[part & (rl > 0)]))
        g_rows = np.flatnonzero(grown.any(1))
        if g_rows[-1] - g_rows[0] + 1 < max(3.0, 0.15 * ppm + 1.4):
            continue  # no blur above and below it: a seam's or an edge's pixels, not a lamp's
        lamp = _unblur(grown, 0.15 * ppm, 0.30 * ppm) & win
        ys, xs = np.nonzero(lamp)
        if ys.size == 0 or not lo_h <= ys.max() - ys.min() + 1 <= hi_h or xs.max() - xs.min() + 1 > 0.3 * ppm + 1:
            continue
        p_rows = np.flatnonzero(part.any(1))
        if not ys.min() < p_rows[0] <= p_rows[-1] < ys.max():
            continue  # its strong pixels not its middle row: the blur is not a lamp's about them
        best, best_n = lamp, int(beside[q])
    return best


def _red_lamps(ctx: Context, y0: int, x0: int, m: np.ndarray, img: np.ndarray, z: float) -> list[np.ndarray]:
    """Red rear lamps found by colour alone on a vehicle whose end face gave none (local masks, at most
    two, largest first): on the silhouette's rows at lamp heights (``RED_LAMP_H_M`` above the ground at
    depth ``z``), pixels red by day (red over 1.5 times green and blue, over 50) and departing from
    those rows' median colour by more than ``SLIVER_DIFF``, in connected parts of a lamp's size (0.3-2
    times a whole lamp's 0.30 x 0.15 m, at most 0.25 m tall and 0.45 m wide, + 2 px of blur). For
    far cars in a parked row, whose face depth places a few pixels off (docs/proposals.md, "Tenth
    pass: vehicle lamps"); none on vehicles whose lamp would be under ``SMALL_LAMP_PX`` tall."""
    import cv2

    ppm = float(ctx.intrinsics.fy) / z
    if 0.15 * ppm < SMALL_LAMP_PX:
        return []
    h, w = m.shape
    hts = ctx.height_above_ground(y0 + np.arange(h), z)
    sel = m & ((hts >= RED_LAMP_H_M[0]) & (hts <= RED_LAMP_H_M[1]))[:, None]
    if sel.sum() < 4:
        return []
    paint = median(pixels(img, sel), axis=0)
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    red = sel & (r > 1.5 * np.maximum(g, b)) & (r > 50) & (_chan_max(np.abs(img - paint)) > SLIVER_DIFF)
    n, lab, stats, _ = cv2.connectedComponentsWithStats(red.astype(np.uint8), connectivity=8)
    whole = 0.30 * 0.15 * ppm * ppm
    found = [(int(stats[q, cv2.CC_STAT_AREA]), q) for q in range(1, n)
             if 0.3 * whole <= stats[q, cv2.CC_STAT_AREA] <= 2.0 * whole
             and stats[q, cv2.CC_STAT_HEIGHT] <= 0.25 * ppm + 2 and stats[q, cv2.CC_STAT_WIDTH] <= 0.45 * ppm + 2]
    return [lab == q for _, q in sorted(found, reverse=True)[:2]]


def _on_side_face(ctx: Context, y0: int, x0: int, lamp: np.ndarray) -> bool:
    """Whether a lamp box lies on a surface receding from the camera (a vehicle's side, or across an
    edge onto something else) rather than on its end face: the depth of its columns (median over
    its rows) rises or falls by more than ``vehicle_lamp_max_slope`` metres per metre across it
    (between the median depths of its two halves, its outermost columns left out).
    Boxes with fewer than ``vehicle_lamp_slope_min_px`` columns (at 512 px image width, scaled with
    the width: predicted depth is blurred over a share of the image) left once the outermost ones are
    left out (W/512 each side) are not judged: 8 px wide at 512x256, 32 px at 2048x1024 (judging from
    ``vehicle_lamp_slope_min_px`` before trimming lost 0.02-0.09 recall, docs/proposals.md)."""
    p = ctx.params
    h, w = lamp.shape
    scale = max(1.0, ctx.shape[1] / 512.0)  # predicted depth bleeds over ~W/400 px at edges
    min_px = int(round(p.vehicle_lamp_slope_min_px * scale))
    cols = np.flatnonzero(lamp.any(0))
    if cols.size < min_px:
        return False
    rows = np.flatnonzero(lamp.any(1))
    d = ctx.depth[y0 + rows.min():y0 + rows.max() + 1, x0 + cols]
    d = np.where(lamp[rows.min():rows.max() + 1][:, cols], d, np.nan)
    zc = nanmedian(d, 0)  # a column without valid depth stays NaN, left out below
    trim = int(round(scale))  # the outermost columns bleed into what lies beside the vehicle
    zc, cols = zc[trim:-trim], cols[trim:-trim]
    ok = np.isfinite(zc)
    if ok.sum() < min_px:
        return False
    zc, cols = zc[ok], cols[ok].astype(np.float64)
    z = float(median(zc))
    k = zc.size // 2  # the median depth of each half: robust to noise and to one bled column
    slope_px = (float(median(zc[-k:])) - float(median(zc[:k]))) / (cols[-k:].mean() - cols[:k].mean())
    return bool(abs(slope_px) * float(ctx.intrinsics.fx) / z > p.vehicle_lamp_max_slope)


def _in_traffic(ctx: Context, y0: int, x0: int, m: np.ndarray, face: tuple[int, int, int, int],
                z: float | None) -> bool:
    """Whether a vehicle is driving rather than parked: nothing of the kerb side (sidewalk, parking,
    terrain, building...) within ``vehicle_kerb_m`` of either side of its silhouette along its
    lowest rows, and its lateral offset from the camera at most ``vehicle_lane_max_m`` (the ego
    lane and the lanes beside it). Without depth: parked (a still frame cannot tell)."""
    if z is None or ctx.depth is None:
        return False
    p = ctx.params
    H, W = ctx.shape
    h, w = m.shape
    r0, r1, c0, c1 = face
    ppm = float(ctx.intrinsics.fx) / z
    centre = x0 + (c0 + c1) / 2.0
    if abs((centre - ctx.intrinsics.cx) / ppm) > p.vehicle_lane_max_m:
        return False
    rows = np.flatnonzero(m.any(1))
    if rows.size == 0:
        return False
    reach = max(2, int(round(p.vehicle_kerb_m * ppm)))
    for r in rows[-max(1, rows.size // 6):]:  # the lowest sixth: wheels on the ground
        xs = np.flatnonzero(m[r])
        lo, hi = x0 + int(xs.min()), x0 + int(xs.max())
        band = np.r_[ctx.labels[y0 + r, max(0, lo - reach):lo], ctx.labels[y0 + r, hi + 1:min(W, hi + 1 + reach)]]
        if np.isin(band, KERBSIDE).any():
            return False
    return True


def _cut_lamp(ctx: Context, y0: int, x0: int, m: np.ndarray) -> tuple[np.ndarray, bool] | None:
    """The visible part of a far vehicle's inner lamp beside the cut of the car in front, laid out from the
    geometry where the image shows next to nothing (local mask), or None (docs/proposals.md "Twentieth pass:
    vehicle lamps at 512x256").

    On a vehicle whose whole lamp (0.15 m) is under ``vehicle_cut_lamp_max_px`` tall, at depth ``z`` (the silhouette's
    outer columns, away from the principal point), cut on that side by a nearer object (not background,
    ``CUT_NEARER_M`` nearer two pixels beyond): the silhouette's last column on the rows whose pixel centres
    lie at the lamp's heights (``vehicle_cut_lamp_h_m`` above the ground at ``z``; at least the nearest row).
    Kept when the end face's strip left of the cut holds a lamp's pixel: the end face's inner edge lies where
    a side face ``vehicle_cut_lamp_length_m`` long ending at the silhouette's inner end (over those rows and
    two either side) would start at depth ``z``; the lamp begins ``vehicle_lamp_cols_m[0]`` in from it and
    must reach ``vehicle_cut_lamp_vis_px`` pixels past it toward the cut. And when the image does not deny
    it: some pixel of the column departs by ``vehicle_cut_lamp_blend_levels`` (8-bit, largest channel) or
    more from every blend of the occluder's colour (two pixels beyond the cut) and the car's paint (its
    pixels' median) -- what the blur leaves of a cut vehicle without a lamp there. With the mask, whether it
    is a rear lamp: what the blend leaves of the most departing pixel is darker (its channels' mean) or leans
    red by more than ``vehicle_cut_lamp_red_levels`` (a rear lamp's dark red lens by day), not brighter."""
    p = ctx.params
    if ctx.depth is None or p.vehicle_cut_lamp_conf <= 0:
        return None
    H, W = ctx.shape
    h, w = m.shape
    fy, cx = float(ctx.intrinsics.fy), float(ctx.intrinsics.cx)
    d = np.where(m, ctx.depth[y0:y0 + h, x0:x0 + w], np.inf)
    col = d.min(0)
    ok = np.isfinite(col)
    if not ok.any():
        return None
    left = x0 + float(np.nonzero(m)[1].mean()) < cx  # left of the principal point: cut on the left
    k = max(1, w // 5)
    near = col[:k] if left else col[-k:]
    near = near[np.isfinite(near)]
    z = float(median(near)) if near.size else float(median(col[ok]))
    if not z > 0:
        return None
    ppm = fy / z
    if 0.15 * ppm >= p.vehicle_cut_lamp_max_px:
        return None

    def row_at(height: float) -> float:
        return float(ctx.intrinsics.cy + ((p.camera_height_m - height) / np.cos(p.camera_pitch_rad)
                                          - z * np.tan(p.camera_pitch_rad)) * fy / z)

    lo_h, hi_h = p.vehicle_cut_lamp_h_m
    ra, rb = row_at(hi_h), row_at(lo_h)
    r_a, r_b = int(np.ceil(ra - 0.5)), int(np.floor(rb + 0.5 - 1e-9))
    if r_b < r_a:
        r_a = r_b = int(round((ra + rb) / 2.0))
    step = -1 if left else 1
    rows, cols = [], []
    for r in range(r_a, r_b + 1):
        rr = r - y0
        if not 0 <= rr < h or not m[rr].any():
            continue
        e = int(np.argmax(m[rr])) if left else w - 1 - int(np.argmax(m[rr, ::-1]))
        b, bb = x0 + e + step, x0 + e + 2 * step
        if not (0 <= b < W and 0 <= bb < W) or int(ctx.labels[r, b]) in BACKGROUND:
            continue
        if not ctx.depth[r, bb] < z - CUT_NEARER_M:  # (NaN: not nearer)
            continue
        rows.append(rr)
        cols.append(e)
    if not rows:
        return None
    # the end face's strip between its inner edge and the cut, from the side face's far end
    band = m[max(min(rows) - 2, 0):max(rows) + 3]
    bc = np.flatnonzero(band.any(0))
    u_in = x0 + (bc[-1] + 0.5 if left else bc[0] - 0.5)
    corner = cx + (u_in - cx) * (z + p.vehicle_cut_lamp_length_m) / z
    c_cut = x0 + float(np.mean(cols))
    strip = (corner - (c_cut - 0.5)) if left else ((c_cut + 0.5) - corner)
    if strip - p.vehicle_lamp_cols_m[0] * ppm < p.vehicle_cut_lamp_vis_px:
        return None
    # the image: a pixel no blend of the occluder and the paint explains
    img = ctx.image
    paint = median(pixels(img[y0:y0 + h, x0:x0 + w].astype(np.float32), m), axis=0)
    ys = y0 + np.asarray(rows)
    xs = x0 + np.asarray(cols)
    c = img[ys, xs].astype(np.float32)
    o = img[ys, np.clip(xs + 2 * step, 0, W - 1)].astype(np.float32)
    ab = paint[None, :] - o
    t = np.clip(((c - o) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-6), 0.0, 1.0)
    res = c - (o + t[:, None] * ab)
    dev = _chan_max(np.abs(res))
    if float(dev.max()) < p.vehicle_cut_lamp_blend_levels:
        return None
    out = np.zeros_like(m)
    out[np.asarray(rows), np.asarray(cols)] = True
    # What the blend leaves is the lamp's: darker or redder, a rear lamp's dark red lens; brighter, a front lamp
    q = res[int(np.argmax(dev))]
    rear = float(q.mean()) < 0 or float(q[0] - max(q[1], q[2])) > p.vehicle_cut_lamp_red_levels
    return out, rear


def _cut_lamp_light(ctx: Context, y0: int, x0: int, lamp: np.ndarray, rear: bool) -> Light:
    """:func:`_cut_lamp`'s lamp as a parked vehicle's light: its rear lamp when its pixels are red by day or the
    rule says so, else its front lamp; the rule's confidence ``vehicle_cut_lamp_conf``, not rescored (a guess
    from the geometry: under the editor's slider)."""
    p = ctx.params
    h, w = lamp.shape
    r, g, bl = pixels(ctx.image[y0:y0 + h, x0:x0 + w].astype(np.float32), lamp).mean(0)
    rear = rear or (r > 1.5 * max(g, bl) and r > 50)
    return Light(PARKED_REAR if rear else PARKED_FRONT, y0, x0, lamp, float(p.vehicle_cut_lamp_conf))

def propose(ctx: Context) -> list[Group]:
    """Per car/truck/bus: two lamps on the visible end face and the dark window panes above its body.

    Lamps sit in the upper part of the body's end face near both sides (``vehicle_lamp_rows`` /
    ``vehicle_lamp_cols`` fractions); a lamp box whose colour differs from the paint is snapped to
    those pixels. Facing comes from colour: lamps red by day, or departing from the paint towards
    red (``vehicle_rear_red_share``: in shade, far away), are rear lamps, else front lamps. A lamp box
    on a face receding from the camera (:func:`_on_side_face`) is dropped, and a face that is not
    placed (:func:`_end_face`: mostly hidden by the car in front) gets none. Confidence 0.75 with
    depth (0.55 without), +0.15 when both lamps stand out from the paint, -0.3 when the face is
    narrower than 1 m (a side view).
    Panes: the cabin band (above the body face, its top and bottom 0.07 m trimmed), split into the end
    pane (windscreen or rear window) and the side pane at the end face's edge; confidence 0.6.
    Each light at least 0.5 confident is then rescored from how it stands out of the vehicle around it
    (:func:`_ring_contrast`), its size and kind (:func:`_rescore`, ``vehicle_lamp_conf_*`` /
    ``vehicle_pane_conf_*``): the set kept at 0.5 is unchanged, the order within it is not.
    """
    p = ctx.params
    fy = float(ctx.intrinsics.fy)
    out: list[Group] = []
    cut_min = min(p.vehicle_min_area_px, p.vehicle_cut_lamp_min_px) if p.vehicle_cut_lamp_conf > 0 \
        else p.vehicle_min_area_px
    for cls, y0, x0, m in _vehicles(ctx, cut_min):
        h, w = m.shape
        if cut_min < p.vehicle_min_area_px and int(m.sum()) < p.vehicle_min_area_px:
            # a vehicle too small for the end face and panes: only the lamp beside the car in front's cut
            cut = _cut_lamp(ctx, y0, x0, m)
            if cut is not None:
                lamp = _cut_lamp_light(ctx, y0, x0, *cut)
                out.append(Group(VEHICLE_GROUP[cls], [lamp], lamp.confidence))
            continue
        face = _end_face(ctx, cls, y0, x0, m)
        if face is None:
            continue
        r0, r1, c0, c1, z, placed = face
        fh, fw = r1 - r0 + 1, c1 - c0 + 1
        if fh < 2 or fw < 3:
            continue
        img = ctx.image[y0:y0 + h, x0:x0 + w].astype(np.float32)
        face_mask = np.zeros_like(m)
        cc0, cc1 = max(c0, 0), min(c1, w - 1)  # the face's part inside the box (slicing)
        face_mask[r0:r1 + 1, cc0:cc1 + 1] = m[r0:r1 + 1, cc0:cc1 + 1]
        paint = median(pixels(img, face_mask), axis=0) if face_mask.any() else pixels(img, m).mean(0)
        conf = 0.75 if z is not None else 0.55
        if z is not None and fw * z / fy < 1.0:
            conf -= 0.3
        geo = None  # a lamp laid out from the geometry alone (:func:`_cut_strip_lamp`)
        lamps, distinct = _lamp_pair(ctx, y0, x0, m, img, paint, (r0, r1, c0, c1), z) if placed else ([], 0)
        n_pair = len(lamps)
        if z is not None:
            lamps = [b for b in lamps if not _on_side_face(ctx, y0, x0, b)]
            n_pair = len(lamps)
            if len(lamps) < 2:  # a cut end face: the visible part of the lamp beside the cut
                sliver = _sliver_lamp(ctx, y0, x0, m, img, z)
                if sliver is None:  # cut on its centre side by a car in the lane: a red lamp's sliver there
                    sliver = _sliver_lamp(ctx, y0, x0, m, img, z, centre_side=True)
                if sliver is None:  # a lamp at the cut too faint for the sliver: its blur across the cut
                    sliver = _sliver_blend(ctx, y0, x0, m, z, r0)
                if sliver is None and not lamps:  # nothing the image shows: the strip's lamp from the geometry
                    sliver = geo = _cut_strip_lamp(ctx, y0, x0, m, z, r0)
                if sliver is not None and distinct == 0 and len(lamps) == 1 and \
                        _sliver_under_box(lamps[0], sliver, p.vehicle_sliver_box_tol_px):
                    lamps, n_pair = [], 0  # the box laid out over the sliver is that lamp, rows off
                if sliver is not None and not any((sliver & b).any() for b in lamps):
                    lamps.append(sliver)
            if n_pair == 0 and placed:  # nothing where the face puts its lamps: red ones by colour alone
                red = [q for q in _red_lamps(ctx, y0, x0, m, img, z) if not _on_side_face(ctx, y0, x0, q)]
                if red:  # a sliver on one of them is its better mask; one elsewhere is dropped
                    kept = [b for b in lamps if any((b & q).any() for q in red)]
                    lamps = kept + [q for q in red if not any((q & b).any() for b in kept)]
        if distinct == len(lamps) == 2:
            conf += 0.15
        conf = float(np.clip(conf, 0, 1))
        members: list[Light] = []
        if lamps:  # (none when the face is hidden: the panes may still show)
            lamp_px = np.concatenate([pixels(img, b) for b in lamps])
            r, g, bl = lamp_px.mean(0) if lamp_px.size else (0.0, 0.0, 0.0)
            # Rear lamps are red by day; in shade or far away they only depart from the paint towards red.
            dr, dg, db = float(r - paint[0]), float(g - paint[1]), float(bl - paint[2])
            dn = float(np.sqrt(dr * dr + dg * dg + db * db))
            rear = (r > 1.5 * max(g, bl) and r > 50) or (dn > 10.0 and dr - max(dg, db) > p.vehicle_rear_red_share * dn)
            if p.vehicle_cut_strip_rear_right and geo is not None and len(lamps) == 1 and lamps[0] is geo and \
                    x0 > float(ctx.intrinsics.cx):  # its pixels are the occluder's blend: the row's side tells
                rear = True
            # A face not placed (laid out from a nearer object's edge) says nothing of where the vehicle
            # stands sideways -- it may lie in our lane while the car is parked beyond the car ahead
            # (2048x1024 lights seeds 1, 2) --: parked, as without depth.
            moving = placed and _in_traffic(ctx, y0, x0, m, (r0, r1, c0, c1), z)
            lamp_cls = (MOVING_REAR if rear else MOVING_FRONT) if moving else (PARKED_REAR if rear else PARKED_FRONT)
            pair = float(distinct == len(lamps) == 2)
            members = [Light(lamp_cls, y0, x0, b, _rescore(
                conf, p.vehicle_lamp_conf_bias, p.vehicle_lamp_conf_weights,
                (min(_ring_contrast(img, m, b) / SLIVER_DIFF, 3.0), pair, float(i >= n_pair),
                 float(np.log(_lamp_size_px(b)))))) for i, b in enumerate(lamps)]
        if not lamps and p.vehicle_cut_lamp_conf > 0:  # nothing on the face: a far lamp beside the cut
            cut = _cut_lamp(ctx, y0, x0, m)
            if cut is not None:
                members.append(_cut_lamp_light(ctx, y0, x0, *cut))
        # Window panes: the cabin band above the body face.
        # On a narrow face r0 is the typical body height's row; the panes, as its lamps, sit on the
        # silhouette's own body top when near (512x256 seeds 0-2: panes matched at IoU >= 0.7 64 -> 67).
        pr0 = _small_face_top(m, cc0, cc1, r0) if z is not None and fw < p.vehicle_small_face_px else r0
        cab = m.copy()
        cab[pr0:, :] = False
        if z is not None:
            trim = max(0, int(round(PANE_INSET_M * fy / z)))
            cab_rows = np.flatnonzero(cab.any(1))
            if cab_rows.size:
                cab[:cab_rows.min() + trim, :] = False
                cab[_glass_end(ctx, y0, pr0, z):pr0, :] = False
        # The whole band: on the synthetic streets (512x256, seeds 0-2) band panes matched a true pane at
        # IoU >= 0.5 0.78 of the time, against 0.62 for its darker pixels alone (reflections and frames
        # split them), which the older rule preferred whenever 30 % of the band was darker than the paint.
        panes, pane_conf = cab, 0.6
        end = np.zeros_like(m)
        end[:, cc0:cc1 + 1] = True
        cut_by_border = _cut_by_border(m, x0, ctx.image.shape[1])
        parts, parted = _pane_parts(img, panes, end, paint, p.vehicle_pillar_paint_diff,
                                    fy / z if z is not None else None)
        for is_end, part, sliver in parts:
            if z is not None and fy / z >= p.vehicle_pane_body_min_ppm and part.any():
                part = _body_trim(img, part, paint, p.vehicle_pane_body_tol, p.vehicle_pane_body_chroma)
                part = _glass_below(img, m, part, paint, p.vehicle_pane_glass_below_share)
            if part.sum() >= 2:
                members.append(Light(WINDOW_TRANSPORT if cls == 28 else WINDOW_PARKED, y0, x0, part, pane_conf
                                     if sliver else _rescore(
                    pane_conf, p.vehicle_pane_conf_bias, p.vehicle_pane_conf_weights,
                    (min(_ring_contrast(img, m, part) / SLIVER_DIFF, 3.0), is_end,
                     float(np.log(int(part.sum()))), float(len(lamps)),
                     float(not is_end and cut_by_border), float(parted)))))
        if members:
            out.append(Group(VEHICLE_GROUP[cls], members, conf if lamps else pane_conf))
    return out
