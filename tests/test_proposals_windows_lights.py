"""Window rules from the lights street at 2048x1024 (issue #26; docs/proposals.md "Twelfth pass: windows
on the lights street"): a floor of larger panes judged against its own panes, and strips narrower along
their wall than any pane. Painted facades as in tests/test_proposals_windows.py.
"""

from __future__ import annotations

import numpy as np
from test_proposals_windows import (K, PARAMS, WALL, _canvas, _floors_of_panes, _iou, _pane, _run, _u, _v, _wall,
                                    _windows)

from npsim_core.proposals.core import Context, Light
from npsim_core.proposals.windows import _strip_width_m

OFF = PARAMS.__class__(**{**PARAMS.__dict__, "window_min_width_m": 0.0})


def _floors_and_a_top_floor_of_tall_panes():
    img, labels, depth, noise = _canvas()
    z = 20.0
    _wall(img, labels, depth, -6.0, 6.0, 9.5, z)
    gt = {}
    for fl, y0 in enumerate((1.0, 4.0)):
        for b, x in enumerate((-5.0, -2.6, -0.2, 2.2, 4.6)):
            _pane(img, gt, (fl, b), x, x + 0.8, y0, y0 + 1.0, z)
    for b, x in enumerate((-3.8, 1.0)):
        _pane(img, gt, ("top", b), x, x + 0.8, 6.4, 8.6, z)
    return img, labels, depth, noise, gt


def test_two_tall_panes_alone_on_their_floor_are_judged_against_each_other():
    """Ten small panes (0.8 m^2) on two floors and two 2.2 m tall panes alone on the top floor: with
    fewer than three windows on its floor a window was judged against the wall's median alone and the
    two tall panes (2.2x) were dropped as "a merged row" -- 4 true panes so on the lights street at
    2048x1024 seeds 0-2 (IoU 0.6-0.99 with their truth), 2 on the hard one. Judged against their floor
    mates (not themselves), both stay."""
    img, labels, depth, noise, gt = _floors_and_a_top_floor_of_tall_panes()
    wins, _ = _windows(_run(img, labels, depth, noise))
    for b in range(2):
        assert any(_iou(gt[("top", b)], w) >= 0.7 for w in wins.values()), b
    assert sum(any(_iou(g, w) >= 0.7 for w in wins.values()) for g in gt.values()) == 12


def test_a_merged_pair_beside_a_pane_on_its_floor_is_still_too_large():
    """The floor mate is a reference, not a licence: a blob two panes wide beside one pane of the same
    floor is twice its mate's size and goes (as before), the pane stays."""
    img, labels, depth, noise, gt = _floors_and_a_top_floor_of_tall_panes()
    z = 20.0
    img2 = img.copy()
    # the top floor: one small pane and a blob of two small panes joined (2 x 0.8 m wide, 1 m tall)
    img2[labels == 11] = (172, 152, 128)
    for fl, y0 in enumerate((1.0, 4.0)):
        for b, x in enumerate((-5.0, -2.6, -0.2, 2.2, 4.6)):
            _pane(img2, gt, (fl, b), x, x + 0.8, y0, y0 + 1.0, z)
    _pane(img2, gt, "one", -3.8, -3.0, 6.6, 7.6, z)
    _pane(img2, gt, "pair", 1.0, 3.4, 6.6, 7.6, z)
    wins, _ = _windows(_run(img2, labels, depth, noise))
    assert any(_iou(gt["one"], w) >= 0.7 for w in wins.values())
    assert not any(_iou(gt["pair"], w) >= 0.5 for w in wins.values())


def _receding_wall(slope: float):
    """A wall receding to the right (depth 20 m + ``slope`` m per column), columns 60-200, rows 20-100."""
    H, W = K.height, K.width
    labels = np.full((H, W), 23, np.uint8)
    depth = np.full((H, W), np.nan, np.float32)
    labels[20:100, 60:200] = 11
    cols = np.arange(W, dtype=np.float32)
    depth[20:100, 60:200] = (20.0 + slope * (cols[60:200] - 60))[None, :]
    return labels, depth


def _ctx(labels, depth):
    return Context(np.zeros(labels.shape + (3,), np.uint8), labels, depth, K, None, PARAMS)


def test_a_strip_narrower_along_its_wall_than_any_pane_is_measured_so():
    """A 1-px strip 30 rows tall on a wall facing the camera at 20 m spans 0.13 m of wall (a downpipe's,
    a crease's width: under ``window_min_width_m``); on a wall receding 0.5 m per column the same strip
    spans half a metre (a pane's strip down a receding wall); beside a pole it is a pane's visible part
    and not judged."""
    strip = Light(1, 40, 120, np.ones((30, 1), bool), 0.9)
    labels, depth = _receding_wall(0.0)
    w_flat = _strip_width_m(_ctx(labels, depth), strip)
    assert w_flat is not None and w_flat < PARAMS.window_min_width_m
    labels, depth = _receding_wall(0.5)
    w_rec = _strip_width_m(_ctx(labels, depth), strip)
    assert w_rec is not None and w_rec > 0.4
    labels, depth = _receding_wall(0.0)
    labels[20:100, 121:123] = 17  # a pole just right of the strip
    assert _strip_width_m(_ctx(labels, depth), strip) is None
    # at a building's corner the wall beyond is another plane: the receding side's width counts
    labels, depth = _receding_wall(0.5)
    depth[20:100, 123:200] = 60.0
    assert _strip_width_m(_ctx(labels, depth), strip) > 0.4


def test_a_downpipe_on_a_wall_is_not_a_window_but_the_panes_are():
    """A dark downpipe 0.2 m wide, 2 m of it, beside a floor's panes on a wall at 15 m (2 px wide at this
    focal length): it departs from the wall like glass, is three times as tall as wide and was proposed
    as a window (the lights street's tall 1-3 px false windows at 2048x1024: 4 at seeds 0-2, 7 on the
    default street); its width along the wall says it is none. The panes stay."""
    img, labels, depth, noise = _canvas()
    z = 15.0
    _wall(img, labels, depth, -4.0, 4.0, 5.5, z)
    gt = {}
    for fl, y0 in enumerate((1.0, 3.8)):
        for b, x in enumerate((-3.6, -2.2, -0.8, 1.6, 3.0)):
            _pane(img, gt, (fl, b), x, x + 0.8, y0, y0 + 1.0, z)
    u = int(round(_u(0.6, z)))
    v0, v1 = int(round(_v(3.2, z))), int(round(_v(1.2, z)))
    img[v0:v1, u:u + 2] = (40, 44, 50)
    pipe = np.zeros(labels.shape, bool)
    pipe[v0:v1, u:u + 2] = True
    wins, _ = _windows(_run(img, labels, depth, noise))
    assert not any(_iou(pipe, w) >= 0.3 for w in wins.values())
    assert sum(any(_iou(g, w) >= 0.7 for w in wins.values()) for g in gt.values()) == len(gt)
    from npsim_core.proposals import propose_lights
    old = propose_lights(np.clip(img.astype(int) + noise, 0, 255).astype(np.uint8), labels, depth, K, None, OFF)
    old_wins, _ = _windows(old)
    assert any(_iou(pipe, w) >= 0.3 for w in old_wins.values())  # without the rule: proposed


def _shop_under_a_fascia(monkeypatch):
    """A shop front (dark glass 0.3-2.4 m up, 3.2 m wide) on a wall at 25 m, and above it 0.6 m of the wall
    itself that the wall reference takes for different: the smooth reference, pulled by the large glass
    below, departs from the wall there (as on the lights street at 2048x1024, where the fascia, awning
    and sign above a shop front joined its glass in one blob: seed 1's two fronts at 27-34 m, IoU 0.52
    and 0.26 with their truth). The reference is set so here (the wall's own features elsewhere)."""
    import npsim_core.proposals.windows as wm

    img, labels, depth, noise = _canvas()
    z = 25.0
    _wall(img, labels, depth, -9.0, 9.0, 7.0, z)
    gt = {}
    _pane(img, gt, "shop", -1.6, 1.6, 0.3, 2.4, z)
    uu, vv = np.arange(img.shape[1])[None, :], np.arange(img.shape[0])[:, None]
    fascia = (uu >= _u(-1.6, z)) & (uu < _u(1.6, z)) & (vv >= _v(3.0, z)) & (vv < _v(2.4, z))
    real = wm.wall_reference

    def pulled(feat, building, params):
        ref = real(feat, building, params).copy()
        ref[fascia, 0] -= 2.0 * -np.log(params.window_dark_ratio)  # darker than the wall by twice the threshold
        return ref

    monkeypatch.setattr(wm, "wall_reference", pulled)
    return (img, labels, depth, noise), gt, fascia


def test_a_shop_fronts_glass_is_proposed_without_the_wall_above_it(monkeypatch):
    """The glass and the strip of wall above it are one blob departing from the reference; the strip has
    the colour of the wall around the blob (windows._wall_coloured), the glass does not (its inside, which
    the pulled reference calls wall, is a hole in the blob: not the wall around it): the glass is the window
    (IoU 0.87: the two fascia rows next to it grown back by ``_extend_ends``, which reads the same
    reference), and a shop front, not the glass and the whole strip (without the rule: IoU 0.73)."""
    scene, gt, fascia = _shop_under_a_fascia(monkeypatch)
    ann = _run(*scene).above(0.5)
    m = ann.instance_map
    ids = [int(i) for i in np.unique(m) if i // 1000 == 1]
    wins = [m == i for i in ids]
    assert max(_iou(gt["shop"], w) for w in wins) >= 0.85
    assert not any((w & fascia).sum() > 0.5 * fascia.sum() for w in wins)
    # glazing found under its fascia is a shop front (not capped as a window, not in the 1.5x rule)
    best = ids[int(np.argmax([_iou(gt["shop"], w) for w in wins]))]
    assert ann.meta["light_kinds"][str(best)] == "shop"
    off = PARAMS.__class__(**{**PARAMS.__dict__, "window_trim_wall_share": 1.0})
    from npsim_core.proposals import propose_lights
    img, labels, depth, noise = scene
    old = propose_lights(np.clip(img.astype(int) + noise, 0, 255).astype(np.uint8), labels, depth, K, None, off)
    m = old.above(0.5).instance_map
    old_wins = [m == i for i in np.unique(m) if i // 1000 == 1]
    assert max(_iou(gt["shop"], w) for w in old_wins) < 0.8
    assert any((w & fascia).sum() == fascia.sum() for w in old_wins)


def test_a_pane_on_an_upper_floor_is_not_trimmed_to_its_part_unlike_the_wall():
    """Only ground-floor glazing is trimmed so (windows._on_ground_floor): an upper floor's pane whose
    reflection takes the wall's colour over part of it stays whole (the default street at 2048x1024: three
    110 m panes cut to a third of their width when every floor was trimmed)."""
    from npsim_core.proposals.core import Context
    from npsim_core.proposals.windows import _on_ground_floor

    img, labels, depth, noise = _canvas()
    z = 16.0
    _wall(img, labels, depth, -7.0, 7.0, 7.0, z)
    ctx = Context(img, labels, depth, K, None, PARAMS)
    m = np.ones((10, 20), bool)
    for bottom_m, low in ((0.3, True), (2.9, True), (3.6, False), (5.5, False)):
        y = int(round(_v(bottom_m, z))) - 10
        assert _on_ground_floor(ctx, y, int(_u(-1.0, z)), m) is low, bottom_m
    assert not _on_ground_floor(Context(img, labels, None, K, None, PARAMS), 40, 100, m)


def _shops_with_raised_sills():
    """A wall at 30 m: two floors of four 1.2 x 1.5 m panes and, on the ground floor, three 2.8 m wide
    glazings from 1.2 m to 3.1 m -- a sill over ``window_shop_max_sill_m`` (a step, a car's roof or the
    ground's estimate puts it there), so :func:`windows._kind` calls them windows."""
    img, labels, depth, noise = _canvas()
    z = 30.0
    _wall(img, labels, depth, -10.0, 10.0, 10.0, z)
    gt = {}
    _floors_of_panes(img, gt, (4.0, 7.0), -8.0, 4.4, 1.2, 1.5, z)
    for b in range(3):
        x = -8.5 + 6.0 * b
        _pane(img, gt, ("shop", b), x, x + 2.8, 1.2, 3.1, z)
    return img, labels, depth, noise, gt


def test_ground_floor_glazing_larger_than_the_windows_above_is_a_shop_front():
    """Three ground-floor glazings three times the panes above: a floor of three windows of their own
    size, so the area rule (judged against the floor's median) kept them as windows -- on the default
    street at 2048x1024 seed 1 shop fronts at 1.55-2.28x their facade's median window, on the lights
    street seed 2 one at 1.69x (docs/proposals.md "Thirteenth pass: the 1.5x rule"). Against the
    windows above they are shop fronts: proposed, of kind ``shop``; the panes above stay windows."""
    img, labels, depth, noise, gt = _shops_with_raised_sills()
    props = _run(img, labels, depth, noise)
    ann = props.above(0.5)
    kinds = ann.meta.get("light_kinds", {})
    m = ann.instance_map
    for b in range(3):
        ids = [int(i) for i in np.unique(m[gt[("shop", b)]]) if i // 1000 == 1
               and _iou(gt[("shop", b)], m == i) >= 0.7]
        assert ids and all(kinds.get(str(i)) == "shop" for i in ids), (b, ids, kinds)
    wins, _ = _windows(props)
    for fl in range(2):
        for b in range(4):
            assert any(_iou(gt[(fl, b)], w) >= 0.7 for w in wins.values()), (fl, b)


def _panes_under_shaded_lintels():
    """A wall at 20 m with a floor of five 1.2 x 1.5 m panes, each under a lintel two rows tall in the
    wall's colour at 0.62 of its brightness (a recessed window's head in shade): past the window
    thresholds, so one blob with the pane, but far nearer the wall than the glass."""
    img, labels, depth, noise = _canvas()
    z = 20.0
    _wall(img, labels, depth, -8.0, 8.0, 6.5, z)
    gt = {}
    for b in range(5):
        x = -7.0 + 3.0 * b
        _pane(img, gt, b, x, x + 1.2, 2.5, 4.0, z)
        ys, xs = np.nonzero(gt[b])
        img[ys.min() - 2:ys.min(), xs.min():xs.max() + 1] = (np.array(WALL) * 0.62).astype(np.uint8)
    return img, labels, depth, noise, gt


def test_a_panes_shaded_lintel_is_not_glass():
    """The lintel's rows depart from the wall by under half the pane's median row (``window_unblur_ratio``):
    they are taken off (``windows._trim_ends``), the window is the pane (old code: the pane and its two
    lintel rows, IoU 0.85; the lights street at 512x256 seed 0 had such a far pane three rows taller
    than its truth, IoU 0.24)."""
    img, labels, depth, noise, gt = _panes_under_shaded_lintels()
    wins, _ = _windows(_run(img, labels, depth, noise))
    for b in range(5):
        best = max(wins.values(), key=lambda w: _iou(gt[b], w))
        assert _iou(gt[b], best) >= 0.95, (b, _iou(gt[b], best))


def test_the_lit_share_list_names_each_face_over_the_cap_with_its_windows():
    """``benchmarks.proposals --list-lit`` (docs/proposals.md "Fourteenth pass: the 40 % lit share, face
    by face"): the ground truth of the lights street at 512x256 (seed 0), every pane counted as a
    window, is itself over the 40 % cap on one face -- a dormer's cheek one pixel wide (9 px) holding
    its dormer's pane. The list names that face with its size, normal and the window on it; Table 5
    counts it among the faces under 3 px across."""
    from benchmarks.proposals import frame_and_walls, pane_kinds, window_rules

    scene, _, walls = frame_and_walls(512, 256, 0, "lights")
    every = {str(i): "window" for i in scene.lights.instance_ids()}
    over: list = []
    faces: list = []
    _, _, share, _, _ = window_rules(scene, scene.lights, walls, kinds=every, gt_kinds=pane_kinds(0, "lights"),
                                     lit_over=over, faces=faces)
    assert len(over) == 1 and share > 0.4
    sh, n_px, _, (y0, y1, x0, x1), _, _, all_panes, wins, axis = over[0]
    assert sh == share and n_px == 9 and x1 == x0 and axis == 0 and all_panes == sh
    assert [(w[2], w[5] == 1.0, w[6]) for w in wins] == [("window", True, "dormer")]
    hot = [f for f in faces if f[0] > 0.4]
    assert hot == [(sh, 0, 1, y1 - y0 + 1)]


def test_the_lights_streets_truth_passes_its_own_corrected_1_5x_count():
    """The lights street records the kinds of the lights it adds, not of the panes its facades share with
    the default street; its ground-floor shop windows (from 0.8 m, 2.1 m tall) counted as windows there,
    so a far ground-floor pane of seed 1 was 1.68x the facade's upper-floor windows: the truth itself
    over the corrected 1.5x count (docs/proposals.md "Twentieth pass: the 1.5x rule"). ``pane_kinds``
    gives such panes the layout's rule, as on the default street: shop fronts (old code: 1 over, and
    the seed's 54 unrecorded panes windows)."""
    from benchmarks.proposals import frame_and_walls, pane_areas, pane_kinds, window_rules

    kinds = pane_kinds(1, "lights")
    assert kinds["1218"] == "shop"  # the old count's offender: from 0.8 m, 2.1 m tall
    scene, _, walls = frame_and_walls(512, 256, 1, "lights")
    offs: list = []
    *_, big_corr = window_rules(scene, scene.lights, walls, kinds=kinds, pane_m2=pane_areas(1, "lights"),
                                gt_kinds=kinds, offenders=offs)
    assert big_corr == 0 and offs == []
    # the kinds the street records stay its own (a gable, a dormer, an office band are not windows)
    recorded = scene.provenance["layout"]["light_kinds"]
    assert all(kinds[k] == v for k, v in recorded.items())
