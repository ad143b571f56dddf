"""The measure of the windows' confidence (benchmarks/window_confidence.py; docs/proposals.md "Ninth pass:
window confidence")."""

from __future__ import annotations

import math

import numpy as np

from benchmarks.window_confidence import calibration, roc_auc, window_outcomes
from npsim_core.synthetic import street_scene


def test_roc_auc_is_the_share_of_pairs_ordered_right_ties_half():
    """Positives 0.9, 0.8 against negatives 0.8, 0.1: three pairs ordered right, one tie (half)."""
    assert roc_auc([0.9, 0.8, 0.8, 0.1], [True, True, False, False]) == 3.5 / 4
    assert roc_auc([0.1, 0.2], [True, False]) == 0.0
    assert math.isnan(roc_auc([0.5, 0.6], [True, True]))


def test_calibration_bins_are_half_open_and_empty_bins_are_nan():
    conf = np.array([0.5, 0.59, 0.6, 0.95, 1.0])
    label = np.array([True, False, True, True, False])
    got = calibration(conf, label, bins=((0.5, 0.6), (0.6, 0.7), (0.7, 0.8), (0.95, 1.01)))
    assert got[0] == (2, 0.5) and got[1] == (1, 1.0) and got[3] == (2, 0.5)
    assert got[2][0] == 0 and math.isnan(got[2][1])


def test_window_outcomes_are_the_windows_kept_at_half_with_their_match():
    """On a fixture street: one confidence and one IoU per window kept at 0.5, IoU 0 or >= 0.5."""
    conf, iou = window_outcomes(street_scene(256, 128, 0))
    assert conf.size == iou.size > 0
    assert (conf >= 0.5).all() and (conf < 1.0).all()
    assert ((iou == 0) | (iou >= 0.5)).all() and (iou >= 0.5).any()


# --- the façade grid's support (npsim_core/proposals/window_confidence.py; docs/proposals.md "Tenth pass")

from dataclasses import replace  # noqa: E402

from benchmarks.window_confidence import design, fit_logistic, window_records  # noqa: E402
from npsim_core.proposals.params import ProposalParams  # noqa: E402
from npsim_core.proposals.window_confidence import front_shares, grid_mates, window_confidence  # noqa: E402


def _lattice(rows=3, cols=4, y=10.0, x=10.0, h=8.0, w=5.0, dy=20.0, dx=12.0):
    return [[y + r * dy, x + c * dx, h, w] for r in range(rows) for c in range(cols)]


def test_a_lattice_pane_has_row_and_column_mates_an_isolated_fleck_none():
    """A 3 x 4 lattice of like panes: an inner pane has 3 row-mates (its floor) and 2 column-mates (its
    bay); a fleck of like size off the grid (between floors, out of the bays) has none."""
    boxes = np.array(_lattice() + [[20.0, 70.0, 8.0, 5.0]])
    row, col, adj = grid_mates(boxes, np.full(len(boxes), 20.0))
    assert row[5] == 3 and col[5] == 2 and adj[5] == 0
    assert row[-1] == 0 and col[-1] == 0


def test_mates_must_be_of_like_size_aligned_and_on_the_same_wall():
    """Beside a pane: a slab as wide as three panes, a pane half a pane lower, and a pane on a wall
    40 % nearer are no row-mates; a piece of a pane touching it is counted as adjacent."""
    pane = [10.0, 10.0, 8.0, 5.0]
    boxes = np.array([pane, [10.0, 22.0, 8.0, 15.0], [14.0, 40.0, 8.0, 5.0], [10.0, 52.0, 8.0, 5.0],
                      [10.0, 16.0, 3.0, 2.0]])
    z = np.array([20.0, 20.0, 20.0, 12.0, 20.0])
    row, col, adj = grid_mates(boxes, z)
    assert row[0] == 0 and col[0] == 0 and adj[0] == 1
    row, _, _ = grid_mates(boxes, np.full(5, np.nan))  # without depth the wall is not judged
    assert row[0] == 1  # the pane on the nearer wall now counts


def test_grid_mates_of_no_windows_are_empty():
    row, col, adj = grid_mates(np.zeros((0, 4)), np.zeros(0))
    assert row.size == col.size == adj.size == 0


def _dense_grid_mates(boxes, depth):
    """The definition of ``grid_mates`` written out over all n x n pairs (what it computed before it
    compared each window only with those near enough)."""
    from npsim_core.proposals import window_confidence as wc
    b, z = np.asarray(boxes, float), np.asarray(depth, float)
    y0, x0, h, w = b.T
    y1, x1 = y0 + h, x0 + w
    hr, wr = h[None, :] / h[:, None], w[None, :] / w[:, None]
    th = np.maximum(h[:, None], h[None, :])
    h_ov = (np.minimum(x1[:, None], x1[None, :]) - np.maximum(x0[:, None], x0[None, :])) / np.minimum(w[:, None], w[None, :])
    with np.errstate(invalid="ignore"):
        same = ~np.isfinite(z[:, None]) | ~np.isfinite(z[None, :]) | (np.abs(z[None, :] - z[:, None]) <= wc.MATE_DEPTH_TOL * z[:, None])
    tol = wc.ROW_EDGE_TOL * th + 0.5
    row = ((hr >= 1 / wc.ROW_HEIGHT_RATIO) & (hr <= wc.ROW_HEIGHT_RATIO) & (wr >= 1 / wc.ROW_WIDTH_RATIO)
           & (wr <= wc.ROW_WIDTH_RATIO) & (np.abs(y0[:, None] - y0[None, :]) <= tol) & (np.abs(y1[:, None] - y1[None, :]) <= tol)
           & (h_ov <= 0) & (np.abs((x0 + x1)[:, None] - (x0 + x1)[None, :]) / 2 <= wc.ROW_REACH * np.maximum(w[:, None], w[None, :]) + 2)
           & same)
    dy = np.abs((y0 + y1)[:, None] - (y0 + y1)[None, :]) / 2
    col = ((wr >= 1 / wc.ROW_HEIGHT_RATIO) & (wr <= wc.ROW_HEIGHT_RATIO) & (hr >= 1 / wc.ROW_WIDTH_RATIO) & (hr <= wc.ROW_WIDTH_RATIO)
           & (h_ov >= wc.COL_MIN_OVERLAP) & (dy >= wc.COL_SPAN[0] * th) & (dy <= wc.COL_SPAN[1] * th) & same)
    gap = np.maximum(np.maximum(y0[None, :] - y1[:, None], y0[:, None] - y1[None, :]),
                     np.maximum(x0[None, :] - x1[:, None], x0[:, None] - x1[None, :]))
    eye = np.eye(len(b), dtype=bool)
    return (row & ~eye).sum(1), (col & ~eye).sum(1), ((gap <= 1) & ~eye).sum(1)


def test_grid_mates_counts_every_pair_the_dense_definition_counts():
    """``grid_mates`` compares a window only with those near enough for each test (a textured wall
    without depth gives ten thousand windows); on lattices, jittered and random boxes of mixed sizes, more
    than one block of them, with and without depth, its counts are those of all n x n pairs."""
    rng = np.random.default_rng(7)
    for trial in range(12):
        n_lat = int(rng.integers(0, 300))
        lat = np.array(_lattice(rows=20, cols=15, h=float(rng.uniform(2, 12)), w=float(rng.uniform(1, 8)),
                                dy=float(rng.uniform(8, 25)), dx=float(rng.uniform(4, 15))))[:n_lat]
        lat = lat + rng.normal(0, 0.7, lat.shape) * [1, 1, 0.3, 0.3]
        n_rand = int(rng.integers(1, 400))
        rand = np.c_[rng.uniform(0, 400, (n_rand, 2)), rng.uniform(1, 30, (n_rand, 2))]
        boxes = np.round(np.vstack([lat, rand]).clip(0.5, None)) if trial % 2 else np.vstack([lat, rand]).clip(0.5, None)
        z = rng.uniform(5, 60, len(boxes))
        if trial % 3 == 0:
            z[rng.random(len(boxes)) < 0.3] = np.nan
        got = grid_mates(boxes, z)
        want = _dense_grid_mates(boxes, z)
        for g, wnt in zip(got, want):
            np.testing.assert_array_equal(g, wnt)


def _x(**kw):
    x = {"ring_lum": 1.5, "ring_chroma": 1.0, "area_px": 12.0, "h_m": 1.2, "row_mates": 0, "col_mates": 0,
         "adjacent": 0, "fill": 1.0, "bottom_m": 7.0, "front_near": 0.0, "front_touch": 0.0, "edge": 1.5}
    x.update(kw)
    return x


def test_a_window_the_grid_backs_is_more_confident_than_the_same_window_alone():
    """Same pane, same contrast: with row- and column-mates it passes the editor's slider (0.9), alone or
    touched by another window it does not (the seventh pass's rule scored all three alike)."""
    p = ProposalParams()
    grid = window_confidence(p, 0.7, _x(row_mates=3, col_mates=2))
    alone = window_confidence(p, 0.7, _x())
    touched = window_confidence(p, 0.7, _x(adjacent=1))
    assert grid >= 0.9 > alone > touched >= 0.5
    old = replace(p, window_conf_bias=-7.85, window_conf_weights=(6.4, 0.35, 1.4, 0.65, 0.27))
    assert window_confidence(old, 0.7, _x(row_mates=3, col_mates=2)) == window_confidence(old, 0.7, _x())


def test_where_a_pane_is_moves_its_confidence_across_the_slider():
    """Eleventh pass: the same well-backed pane (contrast, size, mates) passes the slider on an upper floor
    with a rectangular mask standing out on all four sides; on the ground floor, over 2 m tall, as a ragged
    blob (fill 0.6), with a trunk touching its box or with one side in glass or wall of its own colour it
    does not (the tenth pass's rule scored all five alike). With trees all around it
    (its mates hidden) the same pane without mates gains."""
    p = ProposalParams()
    x = dict(ring_lum=1.5, ring_chroma=0.5, row_mates=1, col_mates=0, area_px=150.0, edge=1.0)
    up = window_confidence(p, 0.8, _x(**x))
    assert up >= 0.9
    for kw in (dict(bottom_m=1.0), dict(h_m=3.0), dict(fill=0.6), dict(front_touch=0.8), dict(edge=0.1)):
        assert window_confidence(p, 0.8, _x(**{**x, **kw})) < 0.9, kw
    alone = dict(x, row_mates=0, col_mates=0)
    assert window_confidence(p, 0.8, _x(**alone, front_near=0.6)) > window_confidence(p, 0.8, _x(**alone)) + 0.02
    tenth = replace(p, window_conf_bias=-4.85, window_conf_weights=(3.67, 0.42, 1.30, 0.56, 0.03, 0.74, 0.90, -0.82))
    assert len({window_confidence(tenth, 0.8, _x(**{**x, **kw})) for kw in
                (dict(), dict(bottom_m=1.0), dict(fill=0.6), dict(front_touch=0.8), dict(front_near=0.6))}) == 1


def test_front_shares_read_what_stands_in_front_around_and_on_a_pane():
    """A 4 x 6 pane on open wall has nothing in front around it; a trunk along its left side fills its
    ring's left column (8 of the ring's 24 pixels, corners included) and a share of its neighbourhood; the image border
    clips both."""
    front = np.zeros((40, 60), bool)
    boxes = np.array([[10.0, 10.0, 6.0, 4.0], [10.0, 40.0, 6.0, 4.0], [0.0, 0.0, 6.0, 4.0]])
    front[:, 39] = True  # a trunk along the second pane's left edge
    near, touch = front_shares(front, boxes)
    assert near[0] == 0.0 and touch[0] == 0.0 and touch[2] == 0.0
    assert touch[1] == 8 / 24
    # neighbourhood rows 10-9-1=0 .. 10+6+9+1=26, columns 40-12-2=26 .. 40+4+12+2=58: the trunk's 26 pixels
    assert near[1] == 26 / (26 * 32)
    assert front_shares(front, np.zeros((0, 4)))[0].size == 0


def test_the_set_kept_at_half_does_not_change():
    p = ProposalParams()
    assert window_confidence(p, 0.45, _x(row_mates=5, col_mates=5)) == 0.45
    assert 0.5 <= window_confidence(p, 0.5, _x(ring_lum=0.0, ring_chroma=0.0, adjacent=1, area_px=3.0)) <= 0.6
    assert window_confidence(p, 0.99, _x(row_mates=9, col_mates=9, area_px=4.0)) <= p.window_tiny_max_confidence


def test_the_fit_tool_reads_the_rule_s_own_terms():
    """``benchmarks.window_confidence --fit`` fits on ``design``: with the rule's weights it reproduces every
    logged window's confidence (tiny windows aside), and the Newton fit recovers known weights."""
    p = ProposalParams()
    recs = [r for r in window_records(street_scene(256, 128, 0)) if r["conf0"] >= 0.5 and r["area_px"] >= 6]
    assert recs
    z = p.window_conf_bias + design(recs) @ np.asarray(p.window_conf_weights)
    assert np.allclose(0.5 + 0.5 / (1 + np.exp(-z)), [r["conf"] for r in recs])
    rng = np.random.default_rng(0)
    X = rng.normal(size=(4000, 2))
    y = (rng.random(4000) < 1 / (1 + np.exp(-(0.5 + X @ [1.5, -2.0])))).astype(float)
    assert np.allclose(fit_logistic(X, y), [0.5, 1.5, -2.0], atol=0.25)


def test_on_a_facade_the_lattice_s_panes_are_more_confident_than_a_lone_row_of_the_same_panes():
    """Through the proposer: a 3 x 3 lattice of faint panes and, on the same wall, a row of three such
    panes at another level out of the lattice's bays. The same pane, contrast, size and floor of three:
    the seventh pass's rule scored them alike (0.92); the bay's column-mates now raise the lattice's."""
    from proposal_helpers import FLAT, canvas

    from npsim_core.camera import Intrinsics
    from npsim_core.proposals import propose_lights

    img, lab = canvas(H=160, W=240)
    lab[20:150, 10:230], img[20:150, 10:230] = 11, (170, 150, 120)  # building at 20 m, 10 px a metre
    lab[150:, :] = 7
    lattice = [(35 + 35 * r, 25 + 30 * c) for r in range(3) for c in range(3)]
    row = [(52, 150 + 25 * c) for c in range(3)]
    for y, x in lattice + row:
        img[y:y + 12, x:x + 9] = (135, 120, 98)  # a faint 0.9 x 1.2 m pane
    props = propose_lights(img, lab, np.full(lab.shape, 20.0, np.float32),
                           Intrinsics(fx=200.0, fy=200.0, cx=119.5, cy=79.5, width=240, height=160),
                           params=replace(FLAT, categories=("windows",)))
    conf = [props.confidence.get(int(props.annotation.instance_map[y + 6, x + 4]), 0.0) for y, x in lattice + row]
    assert len(props.annotation.instance_ids()) == 12 and min(conf) >= 0.5
    assert min(conf[:9]) > max(conf[9:]) + 0.02


def test_edge_contrast_finds_the_side_of_a_pane_traced_short():
    """A dark 6 x 8 pane on a light wall: its box stands out on all four sides; the box of its left half
    has its right side inside the glass (no contrast there); a box at the image border reads only the
    sides inside the image."""
    from npsim_core.proposals.window_confidence import edge_contrast

    p = ProposalParams()
    feat = np.zeros((30, 40, 3), np.float32)
    feat[..., 0] = np.log(0.5)
    feat[10:16, 10:18, 0] = np.log(0.1)  # ln 5 darker: 4.9 window thresholds
    t = -np.log(p.window_dark_ratio)
    assert abs(edge_contrast(feat, 10, 10, 6, 8, p) - np.log(5) / t) < 1e-5
    assert edge_contrast(feat, 10, 10, 6, 4, p) == 0.0
    feat[0:6, 0:8, 0] = np.log(0.1)
    assert abs(edge_contrast(feat, 0, 0, 6, 8, p) - np.log(5) / t) < 1e-5


# --- panes the frame cuts (docs/proposals.md "Twelfth pass: panes the frame cuts")

def _receding_pane(h=40, w=24, slant=14):
    """A pane on a receding wall: a parallelogram ``h`` rows tall per column whose top and bottom edges
    fall ``slant`` rows across its ``w`` columns (its box ``h + slant`` rows)."""
    m = np.zeros((h + slant, w), bool)
    for c in range(w):
        top = round(slant * c / (w - 1))
        m[top:top + h, c] = True
    return m


def test_edge_contrast_reads_a_receding_pane_along_its_mask_and_a_ragged_blob_along_its_box():
    """A dark receding pane (a parallelogram: its top and bottom edges fall 8 rows across its 24 columns)
    on a light wall stands out on all four sides; its box's top and bottom rows are mostly wall inside and
    out (the default and lights streets' seed 2 pane at 26 m: weakest side 0.07-0.17, 0.898 under the
    slider at IoU 0.99). Read along its mask's own edge it is the pane's full contrast; a blob filling
    under ``window_edge_mask_min_fill`` of its box (an L of shade beside a dark object, default seed 3 at
    0.92 with it) keeps its box's reading, and so does every mask with the rule off."""
    from npsim_core.proposals.window_confidence import edge_contrast

    p = ProposalParams()
    t = -np.log(p.window_dark_ratio)
    m = _receding_pane(slant=8)
    feat = np.zeros((80, 50, 3), np.float32)
    feat[..., 0] = np.log(0.5)
    y0, x0 = 10, 12
    feat[y0:y0 + m.shape[0], x0:x0 + m.shape[1], 0][m] = np.log(0.1)
    h, w = m.shape
    assert m.mean() >= p.window_edge_mask_min_fill
    assert edge_contrast(feat, y0, x0, h, w, p) < 0.05  # the box: wall against wall above and below
    assert abs(edge_contrast(feat, y0, x0, h, w, p, m) - np.log(5) / t) < 1e-5
    assert edge_contrast(feat, y0, x0, h, w, replace(p, window_edge_mask_min_fill=1.01), m) < 0.05
    ell = np.zeros((20, 8), bool)  # an L: fill 0.4
    ell[:, 5:] = True
    ell[:3, :] = True
    feat[...] = 0.0
    feat[..., 0] = np.log(0.5)
    feat[40:60, 30:38, 0][ell] = np.log(0.1)
    assert ell.mean() < p.window_edge_mask_min_fill
    assert edge_contrast(feat, 40, 30, 20, 8, p, ell) == edge_contrast(feat, 40, 30, 20, 8, p) < 0.05


def test_a_receding_pane_the_frame_top_cuts_is_judged_on_its_fill_beyond_the_frame():
    """The lowest 21 rows of a receding pane, the frame's top cutting it (the lights street's seed 0 pane at
    40 m): its box is filled 0.70 where the whole pane's is 0.74; judged beyond the frame to a pane's least
    height it is filled like the whole. The same mask away from the frame, a triangle's apex on the frame,
    a box already a pane's height tall, or no depth: the fill its box shows."""
    from npsim_core.proposals.window_confidence import frame_cut_fill

    whole = _receding_pane()
    cut = whole[-21:]  # the frame's top at the pane's 33rd row of 54
    f_whole, f_cut = whole.mean(), cut.mean()
    assert f_cut < f_whole - 0.03
    got = frame_cut_fill(cut, 0, 1024, 26.0)
    assert abs(got - f_whole) < abs(f_cut - f_whole) / 2 and got > f_cut
    assert frame_cut_fill(cut[::-1], 1024 - 21, 1024, 26.0) == got  # the frame's bottom, mirrored
    assert frame_cut_fill(cut, 5, 1024, 26.0) == f_cut  # not on the frame's edge
    assert frame_cut_fill(cut, 0, 1024, 21.0) == f_cut and frame_cut_fill(cut, 0, 1024, float("nan")) == f_cut
    tri = np.tri(12, 12, dtype=bool)  # apex on the frame's top: one pixel of the edge row
    assert frame_cut_fill(tri, 0, 1024, 30.0) == tri.mean()


def test_a_pane_the_frame_top_cuts_scores_like_its_uncut_row_mates():
    """The lights street's seed 0 pane at 40 m the frame's top cuts (IoU 0.95 with its truth): the
    proposer's first confidence 0.496 read its box's 0.70 fill, under the 0.5 that decides which proposals
    exist. Judged on its fill beyond the frame (0.75) it is kept, rescored like a pane of that contrast; the
    old rule left it at 0.496. Features without ``fill_seen`` (the fit's records of uncut panes) as before."""
    p = ProposalParams()
    x = _x(ring_lum=0.90, ring_chroma=2.0, area_px=353.0, h_m=0.37, fill=0.75, fill_seen=0.70,
           bottom_m=8.35, edge=0.01)
    assert window_confidence(p, 0.496, x) >= 0.5
    assert window_confidence(p, 0.496, {**x, "fill": 0.70}) == 0.496
    uncut = {k: v for k, v in x.items() if k != "fill_seen"}
    assert window_confidence(p, 0.45, uncut) == 0.45


def test_the_fit_tool_scores_the_fitted_weights_with_the_rule_tiny_windows_cap_and_all():
    """``--fit``'s "fit" column is the rule itself with the fitted weights (``rule_confidences``), so its AUC
    compares like with like with the committed weights' "now": with the committed weights it reproduces every
    logged window's confidence, the tiny ones held at ``window_tiny_max_confidence`` too (the linear score the
    column read before left the cap out: at 512x256 that alone read 0.006-0.017 more AUC)."""
    from benchmarks.window_confidence import rule_confidences

    p = ProposalParams()
    recs = [r for r in window_records(street_scene(256, 128, 0)) if r["conf0"] >= 0.5]
    tiny = [r["area_px"] < p.window_tiny_px for r in recs]
    assert any(tiny) and not all(tiny)
    got = rule_confidences(recs, p)
    assert np.allclose(got, [r["conf"] for r in recs])
    assert np.all(got[np.array(tiny)] <= p.window_tiny_max_confidence)


def test_the_edge_contrasts_of_all_windows_at_once_are_each_window_s_own():
    """``edge_contrasts`` (every window's sides' medians by one sort per feature: docs/proposals.md
    "Twenty-second pass: the textured street's time") gives ``edge_contrast`` of each window, the same
    floats: boxes on the frame's edges, masks read along their edge or their box, even and odd sides,
    a window with no side inside the frame."""
    from npsim_core.proposals.core import Light
    from npsim_core.proposals.window_confidence import edge_contrast, edge_contrasts

    rng = np.random.default_rng(5)
    p = ProposalParams()
    H, W = 40, 60
    feat = (rng.normal(0, 1, (H, W, 3)) * (0.5, 6, 6)).astype(np.float32)
    feat[10:20, 10:30] = feat[10, 10]  # ties
    lights = [Light(1, 0, 0, np.ones((H, W), bool), 0.5)]  # the whole frame: no side inside
    for _ in range(200):
        h, w = (int(v) for v in rng.integers(1, 15, 2))
        y0, x0 = int(rng.integers(0, H - h + 1)), int(rng.integers(0, W - w + 1))
        m = rng.random((h, w)) < rng.uniform(0.3, 1.0)
        m[rng.integers(0, h), rng.integers(0, w)] = True
        lights.append(Light(1, y0, x0, m, 0.5))
    want = [edge_contrast(feat, li.y0, li.x0, li.mask.shape[0], li.mask.shape[1], p, li.mask) for li in lights]
    got = edge_contrasts(feat, lights, p)
    assert got == want and want[0] == 0.0 and len(set(want)) > 100
    assert edge_contrasts(feat, [], p) == []
