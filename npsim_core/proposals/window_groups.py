"""Window groups an annotator keeps: one windows_group per floor of each building (docs/proposals.md,
"Window groups").

The windows proposer (:mod:`.windows`) groups per floor of each *wall piece*: a façade is cut where its
plane steps or its colour changes, and a tree, a pole or a car in front cuts it into pieces. An
annotator (and the synthetic street's truth) groups per floor of each *building*. This joins the
proposer's groups of one floor across such cuts when they lie on one wall plane, in one wall colour,
and what lies between them is that wall (or something in front of it).
"""

from __future__ import annotations

import cv2
import numpy as np

from .core import Context, Group, Light, median, pixels

BUILDING = 11


def _window_table(ctx: Context, lights: list[Light], feat: np.ndarray) -> dict[str, np.ndarray]:
    """Per window: box (rows, columns), centre, median depth (m, NaN without), floor level (m above the
    ground with depth, else centre row), the wall colour around it (median of ``feat`` over the
    building pixels of the box grown by half its height, other windows left out) and the median depth of
    those wall pixels (``wz``, m; NaN without): a depth network reads glass off its wall (on the synthetic
    streets' simulated prediction the panes' median depth lies 3-10 % in front of the wall around them),
    so whether the wall between two panes is one wall is judged on the wall's depth beside them
    (:func:`_gap_is_wall`; docs/proposals.md "Twelfth pass: window groups")."""
    H, W = ctx.shape
    n = len(lights)
    occ = np.zeros((H, W), bool)
    for li in lights:
        h, w = li.mask.shape
        occ[li.y0:li.y0 + h, li.x0:li.x0 + w] |= li.mask
    wall = (ctx.labels == BUILDING) & ~occ
    t = {k: np.zeros(n) for k in ("y0", "y1", "x0", "x1", "cu", "cv", "z", "level")}
    t["wz"] = np.full(n, np.nan)
    t["wall"] = np.full((n, 3), np.nan)

    def median_depth(d: np.ndarray) -> float:
        d = d[np.isfinite(d)]
        return float(median(d)) if d.size else np.nan

    for i, li in enumerate(lights):
        h, w = li.mask.shape
        ys, xs = np.nonzero(li.mask)
        t["y0"][i], t["y1"][i], t["x0"][i], t["x1"][i] = li.y0, li.y0 + h, li.x0, li.x0 + w
        t["cu"][i], t["cv"][i] = li.x0 + xs.mean(), li.y0 + ys.mean()
        z = median_depth(ctx.depth[li.y0:li.y0 + h, li.x0:li.x0 + w][li.mask]) if ctx.depth is not None else np.nan
        t["z"][i] = z
        t["level"][i] = float(ctx.height_above_ground(t["cv"][i], z)) if np.isfinite(z) else t["cv"][i]
        r = max(2, h // 2)
        ya, yb, xa, xb = max(li.y0 - r, 0), min(li.y0 + h + r, H), max(li.x0 - r, 0), min(li.x0 + w + r, W)
        sel = wall[ya:yb, xa:xb]
        if sel.any():
            t["wall"][i] = median(pixels(feat[ya:yb, xa:xb], sel), axis=0)
            if ctx.depth is not None:
                t["wz"][i] = median_depth(ctx.depth[ya:yb, xa:xb][sel])
    return t


def _median_colour(c: np.ndarray) -> np.ndarray:
    """Median wall colour of windows (rows of ``c``; NaN rows: no wall seen around that window)."""
    ok = np.all(np.isfinite(c), axis=1)
    return median(c[ok], axis=0) if ok.any() else np.full(3, np.nan)


def _same_colour(a: np.ndarray, b: np.ndarray, lum: float, chroma: float) -> bool:
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return False
    return abs(float(a[0] - b[0])) <= lum and float(np.hypot(a[1] - b[1], a[2] - b[2])) <= chroma


def _shadow_pair(a: np.ndarray, b: np.ndarray, lum: float, p) -> bool:
    """Whether two wall colours (log luminance, a, b) are one wall in sun and in a cast shadow: of one hue
    (chroma within ``window_chroma_delta``), their luminance ``window_group_shadow_lum`` apart (log; a
    margin over ``lum``: two grey buildings a little apart are not a shadow's edge; (0, 0): never)."""
    lo, hi = (float(v) for v in p.window_group_shadow_lum)
    if hi <= 0 or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return False
    dl = abs(float(a[0] - b[0]))
    return max(lo, lum) < dl <= hi and float(np.hypot(a[1] - b[1], a[2] - b[2])) <= p.window_chroma_delta


def _wall_depth(t: dict) -> dict:
    """``t`` with each window's depth the wall's beside it (``wz``; its own where no wall shows): a far pane's
    depth bleeds from what stands beside it (512x256 default seed 1: a pane at 69 m on a wall at 81-88 m)."""
    return {**t, "z": np.where(np.isfinite(t["wz"]), t["wz"], t["z"])}


def _on_one_plane(t: dict, idx: np.ndarray, tol: float) -> bool:
    """Whether the windows ``idx`` lie on one plane: inverse depth is affine in the image coordinates
    on a plane, so fit 1/z = a + b u + c v and allow ``tol`` of the depth off it."""
    z = t["z"][idx]
    if not np.all(np.isfinite(z)) or idx.size < 4:
        ok = np.isfinite(z)
        if ok.sum() < 2:
            return True
        # too few for a plane: a line along the row (a wall is vertical, the row nearly level)
        A = np.stack([np.ones(ok.sum()), t["cu"][idx][ok]], 1)
    else:
        A = np.stack([np.ones(idx.size), t["cu"][idx], t["cv"][idx]], 1)
        ok = np.ones(idx.size, bool)
    iz = 1.0 / z[ok]
    if A.shape[0] <= A.shape[1]:
        return True
    coef, *_ = np.linalg.lstsq(A, iz, rcond=None)
    return bool(np.max(np.abs(A @ coef - iz) * z[ok]) <= tol)


def _gap_is_wall(ctx: Context, feat: np.ndarray, t: dict, i: int, j: int, colour: np.ndarray,
                 lum: float, chroma: float, tol: float, colour2: np.ndarray | None = None) -> tuple[bool, float]:
    """Whether the wall between window ``i`` (left) and ``j`` (right) along their floor is one wall:
    its building pixels (others are something in front) mostly of ``colour`` (or of ``colour2``: the
    wall in sun and in a cast shadow, :func:`_shadow_pair`, whose depth is not judged here) and, with depth, on the
    line of inverse depth between the two windows (read beyond ``window_gap_bleed_frac`` of the image width
    from anything in front, whose depth bleeds onto the wall beside it); and the share of that band the
    building shows (1: nothing in front)."""
    H, W = ctx.shape
    xa, xb = int(t["x1"][i]), int(t["x0"][j])
    if xb <= xa:
        return True, 1.0
    cols = np.arange(xa, xb)
    f = (cols - (t["x1"][i] - 1)) / max(t["x0"][j] - t["x1"][i] + 1, 1.0)
    # the floor's band grown by half a pane up and down: the wall between floors, not only between panes
    top = t["y0"][i] + f * (t["y0"][j] - t["y0"][i])
    bot = t["y1"][i] + f * (t["y1"][j] - t["y1"][i])
    grow = 0.5 * (bot - top)
    top0, bot0 = np.round(top).astype(int), np.round(bot).astype(int)
    top, bot = np.round(top - grow).astype(int), np.round(bot + grow).astype(int)
    ya, yb = max(int(top.min()), 0), min(int(bot.max()), H)
    if yb <= ya:
        return True, 1.0
    rows = np.arange(ya, yb)[:, None]
    band = (rows >= top[None]) & (rows < bot[None])
    bld = band & (ctx.labels[ya:yb, xa:xb] == BUILDING)
    shown = float(bld.sum()) / max(float(band.sum()), 1.0)
    if shown < VISIBLE_SHARE:
        # beside something in front the wall's edge pixels mix with it (colour, depth bleed)
        bld = cv2.erode(bld.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    if bld.sum() < 2:
        return True, shown  # all hidden: a tree, a pole or a car in front
    # the wall colour above and below the floor's panes (between the floors), where panes nobody proposed
    # do not lie; the whole band where that shows too little
    spandrel = bld & ~((rows >= top0[None]) & (rows < bot0[None]))
    judge = spandrel if spandrel.sum() >= max(2, SPANDREL_SHARE * bld.sum()) else bld
    fv = pixels(feat[ya:yb, xa:xb], judge)
    off = (np.abs(fv[:, 0] - colour[0]) > lum) | (np.hypot(fv[:, 1] - colour[1], fv[:, 2] - colour[2]) > chroma)
    if colour2 is not None:
        off &= (np.abs(fv[:, 0] - colour2[0]) > lum) | (np.hypot(fv[:, 1] - colour2[1], fv[:, 2] - colour2[2]) > chroma)
    if off.mean() > 0.5:  # another wall between, or panes nobody proposed (whole band)
        return False, shown
    zi, zj = (float(t["wz"][k]) if np.isfinite(t["wz"][k]) else float(t["z"][k]) for k in (i, j))
    if ctx.depth is not None and np.isfinite(zi) and np.isfinite(zj) and colour2 is None:
        # (a sun/shadow pair's plane was judged on the wall's depth beside all its panes: :func:`_wall_depth`)
        # on the line of inverse depth between the walls beside the two panes (the panes' own where no
        # wall shows around one), at their centres
        fc = (cols - t["cu"][i]) / max(t["cu"][j] - t["cu"][i], 1.0)
        iz = 1.0 / zi + (1.0 / zj - 1.0 / zi) * fc
        d = ctx.depth[ya:yb, xa:xb]
        sel = bld
        b = int(ctx.params.window_gap_bleed_frac * W)
        if b > 0:
            # the depth of something in front (a pole, a trunk) bleeds a few pixels onto the wall beside it:
            # not judged there while two pixels of the gap's wall are left (docs/proposals.md "Eighteenth pass")
            near = cv2.dilate((ctx.labels[ya:yb, xa:xb] != BUILDING).astype(np.uint8),
                              np.ones((2 * b + 1, 2 * b + 1), np.uint8)) > 0
            if (bld & ~near).sum() >= 2:
                sel = bld & ~near
        want = np.broadcast_to(1.0 / iz[None], d.shape)[sel]
        got = d[sel]
        good = np.isfinite(got)
        if good.sum() >= 2 and (np.abs(got[good] - want[good]) > tol * want[good]).mean() > 0.3:
            return False, shown
    return True, shown


def _along(t: dict, fx: float, cx: float) -> np.ndarray:
    """(n, 2) top-view positions of the windows' centres (sideways, forward in metres; with no depth the
    centre column and 0)."""
    z = t["z"]
    has = np.isfinite(z)
    x = np.where(has, (t["cu"] - cx) * np.where(has, z, 0.0) / fx, t["cu"])
    return np.stack([x, np.where(has, z, 0.0)], 1)


def _spacing(pos: np.ndarray, idx: np.ndarray, cu: np.ndarray) -> float:
    """Median distance between neighbouring windows (along the row) of ``idx``; NaN for one window."""
    if idx.size < 2:
        return float("nan")
    o = idx[np.argsort(cu[idx])]
    return float(median(np.hypot(*np.diff(pos[o], axis=0).T)))


def _split_at_blanks(ctx: Context, feat: np.ndarray, t: dict, pos: np.ndarray, idx: np.ndarray,
                     lum: float, chroma: float, tol: float, floors: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """Cut one group's windows (sorted along the row) between two buildings: where the wall colour
    around neighbouring windows changes (``lum`` / ``chroma``), or where the step to the next window
    is over ``SPLIT_STEPS`` x the group's median step over wall that shows (nothing in front; the
    blank wall between two blocks of one plane and colour, which an occluder's gap does not show;
    panes under ``SPLIT_MIN_PX`` wide are too quantised to tell alone: their step is cut only where the
    gap is ``BLANK_MIN_GAP_PX`` wide, blank on the other floors too (:func:`_blank_column`) and the wall's
    luminance changes across it by ``BLANK_WALL_LUM``); and, with ``floors`` (every proposed floor's panes), at
    a building's end seen in the image columns (:func:`_building_end`)."""
    if idx.size < 2:
        return [idx]
    o = idx[np.argsort(t["cu"][idx])]
    c = t["wall"][o]
    dl = np.abs(np.diff(c[:, 0]))
    dc = np.hypot(*np.diff(c[:, 1:], axis=0).T)
    cut = (dl > lum) | (dc > chroma)  # NaN (no wall seen) compares False: no cut
    if floors is not None and idx.size >= 3:
        for k in range(o.size - 1):
            if not cut[k] and _building_end(t, o, k, floors, idx, tol, ctx.params.window_end_px_ratio):
                _, shown = _gap_is_wall(ctx, feat, t, int(o[k]), int(o[k + 1]), c[k], lum, chroma, tol)
                cut[k] = shown >= VISIBLE_SHARE
    if idx.size >= 4:
        wide = median(t["x1"][idx] - t["x0"][idx]) >= SPLIT_MIN_PX
        step = np.hypot(*np.diff(pos[o], axis=0).T)
        for k in np.nonzero(step > SPLIT_STEPS * float(median(step)))[0]:
            i, j = int(o[k]), int(o[k + 1])
            if not wide and not (t["x0"][j] - t["x1"][i] >= BLANK_MIN_GAP_PX and _blank_column(t, i, j, idx, tol)
                                 and _side_colour_step(t, o, k) >= BLANK_WALL_LUM):
                continue  # narrow panes: a step too quantised to tell alone (docs/proposals.md, tenth pass)
            _, shown = _gap_is_wall(ctx, feat, t, i, j, c[k], lum, chroma, tol)
            cut[k] |= shown >= VISIBLE_SHARE and not _bay_in_gap(t, i, j, idx, tol)
    ends = np.nonzero(cut)[0] + 1
    return np.split(o, ends)


def _px_step_ratio(cu: np.ndarray, k: int) -> float:
    """Step ``k`` between neighbouring centre columns ``cu`` (sorted) against the median of the steps either side
    of it (NaN without one)."""
    d = np.diff(cu)
    nb = [d[m] for m in (k - 1, k + 1) if 0 <= m < d.size]
    return float(d[k] / median(nb)) if nb and median(nb) > 0 else float("nan")


def _building_end(t: dict, o: np.ndarray, k: int, floors: list[np.ndarray], idx: np.ndarray, tol: float,
                  ratio: float) -> bool:
    """Whether the step between the panes ``o[k]`` and ``o[k + 1]`` of a floor (``o``: its panes sorted along it)
    is the end of one building and the start of the next on one plane and in one colour: the gap is
    ``BLANK_MIN_GAP_PX`` wide at least, ``ratio`` (``window_end_px_ratio``) x the floor's neighbouring steps in
    image columns (a ratio of columns, not of metres: a receding wall's depth drifts), blank on the building's
    other floors (:func:`_blank_column`) and ``ratio`` x their neighbouring steps there too (the median over the
    other proposed floors -- ``floors``: the windows proposer's groups, each sorted along it -- whose step spans
    the gap's middle column between two panes on the wall's plane). A pane missing on one floor leaves a bay
    on the others; a building's end leaves its margins, 0.75 m and more of blank wall either side, on every
    floor."""
    i, j = int(o[k]), int(o[k + 1])
    if t["x0"][j] - t["x1"][i] < BLANK_MIN_GAP_PX or not _px_step_ratio(t["cu"][o], k) >= ratio:
        return False
    gap = _other_floors_panes(t, i, j, idx, tol)
    if gap is None or not _blank_column(t, i, j, idx, tol):
        return False
    other, a, b, _ = gap
    mid = 0.5 * (a + b)
    ratios = []
    for f in floors:
        if f.size < 3:
            continue
        cu = t["cu"][f]
        m = int(np.searchsorted(cu, mid)) - 1
        if 0 <= m < f.size - 1 and other[f[m]] and other[f[m + 1]]:
            r = _px_step_ratio(cu, m)
            if np.isfinite(r):
                ratios.append(r)
    return bool(ratios) and float(median(ratios)) >= ratio


def _end_between(ctx: Context, feat: np.ndarray, t: dict, i: int, j: int, both: np.ndarray, level: float,
                 level_tol: float, floors: list[np.ndarray], colour: np.ndarray, lum: float, chroma: float,
                 tol: float) -> bool:
    """Whether a building's end (:func:`_building_end`, over wall that shows) lies between panes ``i`` (left) and
    ``j`` of a join of the panes ``both``: along the floor made of ``both`` and the panes between ``i`` and ``j``
    at its level (within ``level_tol`` of ``level``) on the wall's plane -- a join may pass over a part of the
    floor that did not join, and the end may lie on either side of it."""
    gap = _other_floors_panes(t, i, j, both, tol)
    if gap is None:
        return False
    other, a, b, _ = gap
    cu = t["cu"]
    btw = np.nonzero(other & (cu > a) & (cu < b) & (np.abs(t["level"] - level) <= level_tol))[0]
    u = np.concatenate([both, btw])
    u = u[np.argsort(cu[u], kind="stable")]
    ki, kj = int(np.nonzero(u == i)[0][0]), int(np.nonzero(u == j)[0][0])
    for k in range(ki, kj):
        if _building_end(t, u, k, floors, u, tol, ctx.params.window_end_px_ratio):
            _, shown = _gap_is_wall(ctx, feat, t, int(u[k]), int(u[k + 1]), colour, lum, chroma, tol)
            if shown >= VISIBLE_SHARE:
                return True
    return False


def _blank_column(t: dict, i: int, j: int, idx: np.ndarray, tol: float) -> bool:
    """Whether the wall between neighbouring panes ``i`` (left) and ``j`` of one floor is blank on the
    building's other floors too: a building's end runs down the whole facade, a pane the proposer missed
    does not (bays repeat from floor to floor). True when other panes (not in ``idx``) on the wall's plane
    (depth within ``2 tol`` of the inverse-depth line from ``i`` to ``j``; any without depth) lie in the
    bays of both ``i`` and ``j`` (centre column within a quarter of the gap of theirs) and none in the
    middle half of the gap."""
    gap = _other_floors_panes(t, i, j, idx, tol)
    if gap is None:
        return False
    other, a, b, q = gap
    cu = t["cu"]
    near_i = other & (np.abs(cu - a) <= max(q, 1.0))
    near_j = other & (np.abs(cu - b) <= max(q, 1.0))
    inside = other & (cu > a + q) & (cu < b - q)
    return bool(near_i.any() and near_j.any() and not inside.any())


def _bay_in_gap(t: dict, i: int, j: int, idx: np.ndarray, tol: float) -> bool:
    """Whether the wall between neighbouring panes ``i`` (left) and ``j`` of one floor holds a bay of the
    building's other floors: a pane not in ``idx``, on the wall's plane (as :func:`_blank_column`), whose
    centre column lies in the middle half of the gap. Bays repeat from floor to floor, so a wide step there
    is a pane the proposer missed (or a tree's shadow), not the blank wall of a building's end
    (docs/proposals.md "Twelfth pass: window groups")."""
    gap = _other_floors_panes(t, i, j, idx, tol)
    if gap is None:
        return False
    other, a, b, q = gap
    cu = t["cu"]
    return bool((other & (cu > a + q) & (cu < b - q)).any())


def _other_floors_panes(t: dict, i: int, j: int, idx: np.ndarray,
                        tol: float) -> tuple[np.ndarray, float, float, float] | None:
    """(panes not in ``idx`` on the wall's plane between panes ``i`` (left) and ``j`` -- depth within ``2 tol``
    of the inverse-depth line from ``i`` to ``j``, any without depth --, the two panes' centre columns
    ``a`` < ``b``, a quarter of the gap); None when ``j`` is not right of ``i``."""
    cu, z = t["cu"], t["z"]
    a, b = float(cu[i]), float(cu[j])
    q = 0.25 * (b - a)
    if q <= 0:
        return None
    other = np.ones(cu.size, bool)
    other[idx] = False
    if np.isfinite(z[i]) and np.isfinite(z[j]):
        f = np.clip((cu - a) / (b - a), -1.0, 2.0)
        want = 1.0 / (1.0 / z[i] + (1.0 / z[j] - 1.0 / z[i]) * f)
        other &= ~(np.abs(z - want) > 2.0 * tol * want)  # NaN depth: kept
    return other, a, b, q


def _side_colour_step(t: dict, o: np.ndarray, k: int) -> float:
    """Log luminance step (absolute) of the wall colour between the panes ``o[k]`` and ``o[k + 1]`` of a floor
    sorted along it: the median wall luminance of up to three panes on each side (NaN-free; 0 without)."""
    a, b = t["wall"][o[max(0, k - 2):k + 1], 0], t["wall"][o[k + 1:k + 4], 0]
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    return float(abs(median(a) - median(b))) if a.size and b.size else 0.0


#: A step along a floor over this many of its median steps, over visible wall, is a building's end.
BLANK_STEPS = 1.6
SPLIT_STEPS = 1.6
#: Median pane width (px) at least, for a cut at a blank step.
SPLIT_MIN_PX = 3
#: Narrower panes are cut at a blank step only where the gap is this wide (px) at least, the wall is blank in
#: that column on the building's other floors too (:func:`_blank_column`) and its luminance changes across
#: the gap by this much (log) at least (:func:`_side_colour_step`): the end of a building, not a pane missed.
BLANK_MIN_GAP_PX = 4
BLANK_WALL_LUM = 0.1
#: The gap's colour is judged on the wall above and below the floor's panes when it is this share of the
#: building pixels of the band at least.
SPANDREL_SHARE = 0.25
#: The share of a gap's band the building shows for the gap to count as visible wall.
VISIBLE_SHARE = 0.6
#: Steps at most this many median steps are joined across something in front.
HIDDEN_STEPS = 4.0
#: Two groups whose median floor levels differ by up to this many floor tolerances are compared at the
#: panes nearest the gap (``END_PANES`` of each side): along a long wall the level read from depth drifts.
LEVEL_GATE = 2.0
END_PANES = 2
#: A single pane inside a cluster's span fills a bay of it (:func:`_join_inside_panes`) when its steps to its two
#: neighbours are at most this many times the cluster's other steps along the floor (image columns): one bay, or
#: two beside a pane nobody proposed.
INSIDE_STEPS = 2.0


def _bay_of_wall(step: np.ndarray, colour: np.ndarray, x0: np.ndarray, x1: np.ndarray, xa: float, xb: float,
                 c: np.ndarray, lum: float, chroma: float) -> float:
    """The bay of a wall (m along it; px without depth): the median step between neighbouring panes
    (``step``, per group; NaN for a group of one pane) of the groups whose columns (``x0``-``x1``)
    overlap ``xa``-``xb`` and whose wall colour is ``c`` (within ``lum`` / ``chroma``) -- the building's
    other floors, whose bays repeat. NaN when no such group has two panes."""
    ok = np.isfinite(step) & (np.minimum(x1, xb) > np.maximum(x0, xa))
    ok &= (np.abs(colour[:, 0] - c[0]) <= lum) & (np.hypot(colour[:, 1] - c[1], colour[:, 2] - c[2]) <= chroma)
    return float(median(step[ok])) if ok.any() else float("nan")


def _candidate_pairs(level: np.ndarray, pane_h: np.ndarray, x0: np.ndarray, x1: np.ndarray,
                     floor_tol: float | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs of parts (a < b) :func:`regroup_windows` tries to join, nearest first: floor levels within
    ``LEVEL_GATE`` floor tolerances (``floor_tol``; without depth half the lower pane height) and columns
    apart (gap >= 0 px). A sweep over the parts sorted by level, so O(n log n + pairs) rather than n x n
    tables; the same pairs in the same order (gap, then a, then b) as sorting the n x n table's pairs.
    Returns a, b and their gaps (px)."""
    n = level.size
    o = np.argsort(level, kind="stable")
    ls = level[o]
    # a window of levels wide enough for every partner of a (the exact gate below picks them)
    half = LEVEL_GATE * (floor_tol if floor_tol is not None else 0.5 * pane_h)
    half = np.broadcast_to(np.asarray(half, float), (n,)) * (1.0 + 1e-9) + 1e-9
    lo = np.searchsorted(ls, level - half, "left")
    hi = np.searchsorted(ls, level + half, "right")
    cnt = np.maximum(hi - lo, 0)
    a = np.repeat(np.arange(n), cnt)
    start = np.repeat(lo - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt)
    b = o[start + np.arange(a.size)] if a.size else a
    keep = a < b
    a, b = a[keep], b[keep]
    tol_ab = floor_tol if floor_tol is not None else 0.5 * np.minimum(pane_h[a], pane_h[b])
    gap = np.maximum(x0[b] - x1[a], x0[a] - x1[b])
    keep = (np.abs(level[a] - level[b]) <= LEVEL_GATE * tol_ab) & (gap >= 0)
    a, b, gap = a[keep], b[keep], gap[keep]
    order = np.lexsort((b, a, gap))
    return a[order], b[order], gap[order]


def _ends(t: dict, idx: np.ndarray) -> tuple[int, float, int, float, float]:
    """A cluster's ends along its floor: its rightmost pane and the median level of its ``END_PANES``
    rightmost, its leftmost pane and that of its ``END_PANES`` leftmost, and half its median pane height
    (rows; the floor tolerance without depth)."""
    r = idx[np.argsort(t["x1"][idx])[-END_PANES:]]
    q = idx[np.argsort(t["x0"][idx])[:END_PANES]]
    return (int(idx[np.argmax(t["x1"][idx])]), float(median(t["level"][r])),
            int(idx[np.argmin(t["x0"][idx])]), float(median(t["level"][q])),
            0.5 * float(median(t["y1"][idx] - t["y0"][idx])))


def _single_on_row_line(t: dict, part: np.ndarray, pane: int, share: float) -> bool:
    """Whether the pane ``pane`` lies on the floor of ``part`` (two panes or more) in the image: its centre row
    within ``share`` of the part's median pane height (rows) of the straight line fit through the part's pane
    centres (row against column; a level floor is a straight line in the image, whatever the depth reads)."""
    if part.size < 2 or share <= 0:
        return False
    cu, cv = t["cu"][part], t["cv"][part]
    if np.ptp(cu) <= 0:
        return False
    b, a = np.polyfit(cu, cv, 1)
    h = float(median(t["y1"][part] - t["y0"][part]))
    return bool(abs(a + b * float(t["cu"][pane]) - float(t["cv"][pane])) <= share * h)


def _join_inside_panes(t: dict, idx_of: dict[int, np.ndarray], col_of: dict[int, np.ndarray], roots: list[int],
                       share: float, lum: float, chroma: float, tol: float, has_depth: bool) -> dict[int, int]:
    """The single panes left inside another cluster's span along the floor, and the cluster each joins: a join
    over an overlap is refused (two walls one behind the other, or two floors), so a pane whose neighbours on
    both sides joined first across it (the level read from one pane's depth off by 0.5-1 m, the join order) is
    left alone in the middle of its floor. It joins the cluster (``idx_of``: its windows per root in ``roots``)
    whose bay it fills: in the gap between two neighbouring panes of it (no column shared with either, its steps
    to them at most ``INSIDE_STEPS`` x the cluster's other steps in image columns: a cluster of three panes at
    least), on the
    straight row line through them and their outer neighbours (:func:`_single_on_row_line`, ``share``), in the
    cluster's wall colour (``col_of``) and on its plane; of several, the one whose two panes' mean centre row
    is nearest. Returns {single pane's root: the cluster's root}."""
    res: dict[int, int] = {}
    order: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # a cluster's windows along the floor, sorted once
    for r in roots:
        if idx_of[r].size != 1:
            continue
        q = int(idx_of[r][0])
        best, best_d = None, np.inf
        for r2 in roots:
            ib = idx_of[r2]
            if r2 == r or ib.size < 2:
                continue
            if r2 not in order:
                o = ib[np.argsort(t["cu"][ib])]
                order[r2] = (o, t["cu"][o])
            o, cu = order[r2]
            m = int(np.searchsorted(cu, t["cu"][q])) - 1
            if not (0 <= m < o.size - 1 and t["x1"][o[m]] <= t["x0"][q] and t["x1"][q] <= t["x0"][o[m + 1]]):
                continue
            # it fills a bay: its steps to the two at most INSIDE_STEPS x the cluster's other steps (image columns)
            rest = np.delete(np.diff(cu), m)
            if not rest.size or max(t["cu"][q] - cu[m], cu[m + 1] - t["cu"][q]) > INSIDE_STEPS * float(median(rest)):
                continue
            if not _single_on_row_line(t, o[max(0, m - 1):m + 3], q, share):
                continue
            if not _same_colour(t["wall"][q], col_of[r2], lum, chroma):
                continue
            if has_depth and not _on_one_plane(t, np.concatenate([ib, [q]]), tol):
                continue
            dv = abs(float(t["cv"][q]) - 0.5 * float(t["cv"][o[m]] + t["cv"][o[m + 1]]))
            if dv < best_d:
                best, best_d = r2, dv
        if best is not None:
            res[r] = best
    return res


def _fails_as_split(ends: np.ndarray, pos: np.ndarray, a: np.ndarray, b: np.ndarray, x0: np.ndarray,
                    x1: np.ndarray, colour: np.ndarray, step: np.ndarray, floor_tol: float | None, lum: float,
                    chroma: float, p=None) -> np.ndarray:
    """Per pair of parts (``a``, ``b``) as :func:`_split_at_blanks` left them: whether one of
    :func:`regroup_windows`' cheap tests rejects it (levels at the gap, wall colour, the step against the
    parts' own bays), all pairs at once. ``ends``: (n, 5) :func:`_ends` per part; ``colour``, ``step``:
    the parts' wall colours and steps. A small margin keeps a pair on the edge for the exact test."""
    eps = 1e-9
    left = np.where(x1[a] <= x0[b], a, b)
    right = np.where(x1[a] <= x0[b], b, a)
    thr = floor_tol if floor_tol is not None else ends[a, 4]
    fail = np.abs(ends[left, 1] - ends[right, 3]) > thr * (1.0 + eps) + eps
    ok = np.all(np.isfinite(colour), axis=1)
    dc = colour[a] - colour[b]
    fail |= ~(ok[a] & ok[b])
    off = (np.abs(dc[:, 0]) > lum + eps) | (np.hypot(dc[:, 1], dc[:, 2]) > chroma + eps)
    if p is not None and p.window_group_shadow_lum[1] > 0:
        # a sun/shadow pair of one hue (_shadow_pair), parts of two panes or more: left to the exact test
        with np.errstate(invalid="ignore"):
            off &= ~((np.abs(dc[:, 0]) <= p.window_group_shadow_lum[1] + eps)
                     & (np.hypot(dc[:, 1], dc[:, 2]) <= p.window_chroma_delta + eps)
                     & np.isfinite(step[a]) & np.isfinite(step[b]))
    fail |= off
    i, j = ends[left, 0].astype(int), ends[right, 2].astype(int)
    d = np.hypot(pos[i, 0] - pos[j, 0], pos[i, 1] - pos[j, 1])
    st = np.fmax(step[a], step[b])  # NaN for two single panes: their bay is found pair by pair
    with np.errstate(invalid="ignore"):
        fail |= np.isfinite(st) & (d > max(BLANK_STEPS, HIDDEN_STEPS) * st * (1.0 + eps) + eps)
    return fail


def regroup_windows(ctx: Context, groups: list[Group], feat: np.ndarray | None = None,
                    pairwise: bool = False) -> list[Group]:
    """Regroup the proposed windows into one windows_group per floor of each building.

    Parameters
    ----------
    ctx : Context
        The proposers' inputs (image, labels, depth in metres or None, camera).
    groups : list of Group
        The windows proposer's groups (one per floor of each wall piece); their lights, masks and
        confidences are kept as they are.
    feat : (H, W, 3) float, optional
        Log linear luminance and centred Lab a, b (``windows._features``); computed when None.

    Returns
    -------
    list of Group
        First each group is cut between two buildings: where the wall colour around neighbouring
        windows changes, or where the step along the row exceeds ``SPLIT_STEPS`` x its median step
        over wall nothing hides (:func:`_split_at_blanks`). Then two groups are joined,
        nearest first, when their floor levels are within ``window_floor_tol_m`` (m above the
        ground, compared at the ``END_PANES`` panes of each nearest the gap, as the level read from
        depth drifts along a long wall; without depth half a pane's height in rows), the wall around
        them is of one colour (``window_block_lum`` / ``window_block_chroma``), their windows lie on one plane (inverse
        depth affine in the image, within 5 % of the depth), the building pixels between the nearest
        two along the floor are that wall (:func:`_gap_is_wall`) and that step is at most
        ``BLANK_STEPS`` (visible wall) or ``HIDDEN_STEPS`` (something in front) x the median step
        (of the groups; for two without a step of their own, single panes, the bay of the building's
        other floors over those columns, :func:`_bay_of_wall`; else 2.5 pane widths). Then, of the clusters those
        joins made, two of two panes or more whose walls are one wall in sun and in a cast shadow
        (:func:`_shadow_pair`, ``window_group_shadow_lum``) join on the same tests, their plane by the wall's depth
        beside the panes (:func:`_wall_depth`), the gap's wall of either colour, the gap at most ``BLANK_STEPS`` x
        the smaller step. Group confidence: the mean of its members'.

        The pairs are found by a sweep along the floor levels and cheap tests (level, colour, step)
        run before the costly ones (plane, the gap's pixels), for every pair at once while both of its
        parts are as the split left them: near-linear in the windows (a textured facade without depth
        gives thousands). ``pairwise``: the n x n pair table and the tests in their first order (the
        same groups, slowly; for tests).
    """
    if not groups:
        return groups
    p = ctx.params
    if feat is None:
        from .windows import _features
        feat = _features(ctx)
    lights = [li for g in groups for li in g.members]
    t = _window_table(ctx, lights, feat)
    pos = _along(t, float(ctx.intrinsics.fx), float(ctx.intrinsics.cx))
    lum, chroma = p.window_block_lum, p.window_block_chroma
    tol = 0.05
    has_depth = ctx.depth is not None
    gof0 = np.repeat(np.arange(len(groups)), [len(g.members) for g in groups])
    parts: list[np.ndarray] = []
    cls: list[int] = []
    first = np.concatenate([[0], np.cumsum([len(g.members) for g in groups])])
    floors = [np.arange(first[g], first[g + 1]) for g in range(len(groups))]
    floors = [f[np.argsort(t["cu"][f])] for f in floors]
    for g in range(len(groups)):
        members = np.nonzero(gof0 == g)[0] if pairwise else np.arange(first[g], first[g + 1])
        for part in _split_at_blanks(ctx, feat, t, pos, members, lum, chroma, tol, floors):
            parts.append(part)
            cls.append(groups[g].class_id)
    n = len(parts)
    level = np.array([median(t["level"][q]) for q in parts])
    pane_h = np.array([median(t["y1"][q] - t["y0"][q]) for q in parts])
    width_m = np.where(np.isfinite(t["z"]), (t["x1"] - t["x0"]) * t["z"] / float(ctx.intrinsics.fx),
                       t["x1"] - t["x0"])
    parent = np.arange(n)
    # per cluster root: its windows, wall colour and column range (updated on a join)
    idx_of = {k: parts[k] for k in range(n)}
    col_of = {k: _median_colour(t["wall"][parts[k]]) for k in range(n)}
    span_of = {k: (t["x0"][parts[k]].min(), t["x1"][parts[k]].max()) for k in range(n)}
    step_of = {k: _spacing(pos, parts[k], t["cu"]) for k in range(n)}
    # the parts' own steps and wall colours, for the bay of a wall (_bay_of_wall)
    part_step = np.array([step_of[k] for k in range(n)])
    part_col = np.array([col_of[k] for k in range(n)]).reshape(n, 3)

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return int(a)

    floor_tol = p.window_floor_tol_m if has_depth else None
    x0 = np.array([span_of[k][0] for k in range(n)])
    x1 = np.array([span_of[k][1] for k in range(n)])
    if pairwise:
        la, lb = np.meshgrid(level, level, indexing="ij")
        tol_ab = floor_tol if floor_tol is not None else 0.5 * np.minimum.outer(pane_h, pane_h)
        gap = np.maximum(x0[None] - x1[:, None], x0[:, None] - x1[None])
        cand = np.triu((np.abs(la - lb) <= LEVEL_GATE * tol_ab) & (gap >= 0), 1)
        pairs = sorted(zip(*np.nonzero(cand)), key=lambda ab: gap[ab])
        skip = skip_shadow = [False] * len(pairs)
    else:
        pa, pb, _ = _candidate_pairs(level, pane_h, x0, x1, floor_tol)
        pairs = list(zip(pa.tolist(), pb.tolist()))
        ends_of = {k: _ends(t, parts[k]) for k in range(n)}
        ends_arr = np.array([ends_of[k] for k in range(n)], float).reshape(n, 5)
        skip = _fails_as_split(ends_arr, pos, pa, pb, x0, x1, part_col, part_step, floor_tol, lum, chroma).tolist()
        skip_shadow = _fails_as_split(ends_arr, pos, pa, pb, x0, x1, part_col, part_step, floor_tol, lum, chroma,
                                      p).tolist()
    pristine = [True] * n  # the part as the split left it: its own root, nothing joined to it
    # the joins of one wall colour first; then, of the clusters they made, those across a cast shadow's edge
    # (_shadow_pair): a sun/shadow join made early would leave the rest of the floor to compare with its mix
    for shadow_pass in ((False, True) if p.window_group_shadow_lum[1] > 0 else (False,)):
        for (a, b), sk in zip(pairs, skip_shadow if shadow_pass else skip):
            if sk and pristine[a] and pristine[b]:
                continue  # fails a cheap test on the parts as split (_fails_as_split): as the slow path would
            ra, rb = root(int(a)), root(int(b))
            if ra == rb:
                continue
            ia, ib = idx_of[ra], idx_of[rb]
            (xa0, xa1), (xb0, xb1) = span_of[ra], span_of[rb]
            if min(xa1, xb1) - max(xa0, xb0) > 0:
                continue  # overlapping along the floor: two walls one behind the other, or two floors
            left, right = (ia, ib) if xa1 <= xb0 else (ib, ia)
            # the floor at the gap: its level read from depth drifts along a long wall (docs/proposals.md)
            if pairwise:
                i, lev_l = _ends(t, left)[:2]
                j, lev_r = _ends(t, right)[2:4]
                half_pane = _ends(t, ia)[4]
            else:
                (i, lev_l), (j, lev_r) = ends_of[ra if left is ia else rb][:2], ends_of[rb if left is ia else ra][2:4]
                half_pane = ends_of[ra][4]
            if abs(lev_l - lev_r) > (floor_tol if floor_tol is not None else half_pane):
                continue
            ca, cb = col_of[ra], col_of[rb]
            # one colour in the first pass; in the second, the wall in sun and in a cast shadow: one hue, and the
            # bays of both parts to go on (two panes each)
            shadow = shadow_pass
            if not (_shadow_pair(ca, cb, lum, p) and np.isfinite(step_of[ra]) and np.isfinite(step_of[rb])
                    if shadow_pass else _same_colour(ca, cb, lum, chroma)):
                continue
            both = np.concatenate([ia, ib])
            steps = [s for s in (step_of[ra], step_of[rb]) if np.isfinite(s)]
            if steps:
                step = max(steps)
            else:  # single panes: the bay of the building's other floors over these columns
                step = _bay_of_wall(part_step, part_col, x0, x1, min(xa0, xb0), max(xa1, xb1), (ca + cb) / 2.0,
                                    lum, chroma)
                if not np.isfinite(step):
                    step = 2.5 * float(median(width_m[both]))
            d = float(np.hypot(*(pos[i] - pos[j])))
            if not pairwise and d > max(BLANK_STEPS, HIDDEN_STEPS) * step:
                continue  # too far whatever the gap shows: the costly tests below are not needed
            if has_depth and not _on_one_plane(_wall_depth(t) if shadow else t, both, tol):
                continue
            if shadow:
                wall, shown = _gap_is_wall(ctx, feat, t, i, j, ca, lum, chroma, tol, colour2=cb)
            else:
                wall, shown = _gap_is_wall(ctx, feat, t, i, j, (ca + cb) / 2.0, lum, chroma, tol)
            if not wall:
                continue
            blank = shown >= VISIBLE_SHARE and not _bay_in_gap(t, i, j, both, tol)
            if d > (BLANK_STEPS if blank or shadow else HIDDEN_STEPS) * (min(steps) if shadow else step):
                continue
            if both.size >= 3 and _end_between(ctx, feat, t, i, j, both, 0.5 * (lev_l + lev_r),
                                               floor_tol if floor_tol is not None else half_pane, floors,
                                               (ca + cb) / 2.0, lum, chroma, tol):
                continue  # a building's end between the two (the split's cut), maybe beside a part passed over
            parent[rb] = ra
            idx_of[ra] = both
            col_of[ra] = _median_colour(t["wall"][both])
            span_of[ra] = (min(xa0, xb0), max(xa1, xb1))
            step_of[ra] = max(steps) if steps else float("nan")  # the step across the join is a gap, not a bay
            pristine[ra] = pristine[rb] = False
            if not pairwise:
                ends_of[ra] = _ends(t, both)
    if p.window_inside_row_tol > 0:
        roots = sorted({root(k) for k in range(n)})
        for r, r2 in _join_inside_panes(t, idx_of, col_of, roots, p.window_inside_row_tol, lum, chroma, tol,
                                        has_depth).items():
            parent[r] = r2
    clusters: dict[int, list[int]] = {}
    for k in range(n):
        clusters.setdefault(root(k), []).append(k)
    res = []
    for ks in clusters.values():
        idx = np.concatenate([parts[k] for k in ks])
        if len(ks) == 1 and idx.size == len(groups[int(gof0[idx[0]])].members):
            res.append(groups[int(gof0[idx[0]])])  # unchanged
            continue
        ms = sorted((lights[k] for k in idx), key=lambda li: (li.x0, li.y0))
        res.append(Group(cls[ks[0]], ms, float(np.mean([li.confidence for li in ms]))))
    return res
