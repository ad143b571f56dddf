"""Vehicle lamp and car-group proposals (npsim_core/proposals/vehicles.py, docs/proposals.md, issue #26)."""

from __future__ import annotations

import functools
from dataclasses import replace

import numpy as np

from npsim_core.annotation import class_of
from npsim_core.camera import Intrinsics
from npsim_core.proposals import ProposalParams, propose_lights

FLAT = ProposalParams(camera_pitch_rad=0.0)
SKY, ROAD, CAR = 23, 7, 26


def _row(h: float, z: float = 10.0) -> int:
    """Image row of a point ``h`` m above the ground at depth ``z`` (camera 1.22 m up, no pitch, f 500 px)."""
    return int(round(59.5 + (1.22 - h) * 500.0 / z))


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    return float((a & b).sum()) / max(1, int((a | b).sum()))


def _car(img, lab, depth, inst, x0: int, x1: int, k: int, paint=(40, 60, 140), lamp=(200, 20, 20), z=10.0,
         plate=None):
    """A car's end face at depth ``z`` (columns x0..x1-1; 1.8 m at 10 m is 90 px), cabin above, two lamps
    0.08-0.38 m in from its sides and 0.07-0.22 m below the body top (0.9 m); instance ``CAR*1000+k``.
    Returns the two lamps' masks (left, right)."""
    ppm = 500.0 / z
    lab[_row(0.9, z):_row(0.3, z), x0:x1] = CAR
    img[_row(0.9, z):_row(0.3, z), x0:x1] = paint
    inset = int(round(0.1 * ppm))
    lab[_row(1.4, z):_row(0.9, z), x0 + inset:x1 - inset] = CAR
    img[_row(1.4, z):_row(0.9, z), x0 + inset:x1 - inset] = paint
    img[_row(1.33, z):_row(0.97, z), x0 + inset + 4:x1 - inset - 4] = (20, 22, 25)
    depth[lab == CAR] = np.where(inst[lab == CAR] == 0, z, depth[lab == CAR])
    rows = slice(_row(0.83, z), _row(0.68, z))
    a, b = int(round(0.08 * ppm)), int(round(0.38 * ppm))
    truth = [np.zeros(lab.shape, bool), np.zeros(lab.shape, bool)]
    truth[0][rows, x0 + a:x0 + b] = True
    truth[1][rows, x1 - b:x1 - a] = True
    for t in truth:
        img[t] = lamp
    if plate is not None:
        c = (x0 + x1) // 2
        img[_row(0.53, z):_row(0.42, z), c - int(0.26 * ppm):c + int(0.26 * ppm)] = plate
    face = np.zeros(lab.shape, bool)
    face[_row(1.4, z):_row(0.3, z), x0:x1] = lab[_row(1.4, z):_row(0.3, z), x0:x1] == CAR
    inst[face & (inst == 0)] = CAR * 1000 + k
    return truth


def _frame(cx: float = 99.5):
    H, W = 120, 200
    img = np.zeros((H, W, 3), np.uint8)
    img[:] = (150, 170, 200)
    lab = np.full((H, W), SKY, np.uint8)
    lab[95:, :] = ROAD
    img[95:] = (70, 70, 75)
    depth = np.full((H, W), 60.0, np.float32)
    inst = np.zeros((H, W), np.int32)
    intr = Intrinsics(fx=500.0, fy=500.0, cx=cx, cy=59.5, width=W, height=H)
    return img, lab, depth, inst, intr


def _lamps(props, threshold=0.5):
    ann = props.above(threshold)
    return ann, [i for i in ann.instance_ids() if class_of(i) in (3, 4, 5, 6)]


def test_a_car_hidden_behind_the_car_in_front_gets_the_visible_sliver_of_its_rear_lamp():
    """In a row parked left of the road the car in front (9 m, 1 m nearer, further left) hides all of
    a car's end face at 10 m but its inner 8 px: the right lamp shows as a 4 px sliver beside the
    occluder's edge (27 % of it), its side recedes to the right, and predicted depth has bled the
    nearer car into the strip. That sliver is proposed (IoU >= 0.5), as a rear lamp. The old code
    found no inner edge of the face (the strip is under a tenth of the face) and proposed no lamp on
    the car."""
    img, lab, depth, inst, intr = _frame(cx=160.0)            # a row parked left of the road
    side = (slice(_row(0.9), _row(0.3)), slice(145, 175))
    lab[side], img[side], inst[side] = CAR, (28, 42, 100), CAR * 1000 + 1
    depth[side] = 10.0 + 0.13 * (np.arange(145, 175) - 144)
    truth = _car(img, lab, depth, inst, 55, 145, 1)
    front = (slice(30, 120), slice(0, 137))                 # the car in front, its far end at 9 m
    lab[front], img[front], depth[front], inst[front] = CAR, (200, 200, 200), 9.0, CAR * 1000 + 2
    strip = (slice(None), slice(137, 141))                   # predicted depth bleeds the nearer car into it
    depth[strip] = np.where(inst[strip] == CAR * 1000 + 1, np.linspace(9.2, 9.9, 4)[None, :], depth[strip])
    visible = truth[1] & (inst == CAR * 1000 + 1)
    assert 3 <= visible.any(0).sum() <= 5
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    on_car = [i for i in lamps if (ann.mask(i) & (inst == CAR * 1000 + 1)).any()]
    assert max((_iou(ann.mask(i), visible) for i in on_car), default=0.0) >= 0.5
    assert all(class_of(i) in (4, 6) for i in on_car)


def _centres(rows_h: tuple[float, float], cols_x: tuple[float, float], z: float, shape, cx: float = 99.5):
    """Pixels whose centres lie in a box of heights ``rows_h`` (m above the ground) and lateral offsets
    ``cols_x`` (m) on a plane at depth ``z``, as the synthetic street labels them (camera 1.22 m up, no
    pitch, f 500 px, cy 59.5)."""
    r, c = np.mgrid[:shape[0], :shape[1]]
    h = 1.22 - (r - 59.5) * z / 500.0
    x = (c - cx) * z / 500.0
    return (h >= rows_h[0]) & (h <= rows_h[1]) & (x >= cols_x[0]) & (x <= cols_x[1])


def _far_car(img, lab, depth, inst, z: float, top: float, paint, lamp, bleed=None):
    """A car's end face 1.8 m wide at depth ``z`` seen head-on (body 0.3 m to ``top``, cabin 0.1 m in
    from its sides to ``top`` + 0.5 m), rasterised by pixel centres; lamps 0.08-0.38 m in from its sides
    and 0.07-0.22 m below the body top in colour ``lamp`` (``bleed``: the colour of the pixels around a
    lamp, as the day render's edge blur leaves them). Returns the two lamp masks."""
    body = _centres((0.3, top), (-0.9, 0.9), z, lab.shape)
    cab = _centres((top, top + 0.5), (-0.8, 0.8), z, lab.shape)
    car = body | cab
    lab[car], img[car], depth[car], inst[car] = CAR, paint, z, CAR * 1000 + 1
    lamps = [_centres((top - 0.22, top - 0.07), xs, z, lab.shape) for xs in ((-0.82, -0.52), (0.52, 0.82))]
    for t in lamps:
        if bleed is not None:
            ring = np.zeros_like(t)
            ys, xs = np.nonzero(t)
            ring[ys.min() - 1:ys.max() + 2, xs.min() - 1:xs.max() + 2] = True
            img[ring & car] = bleed
        img[t] = lamp
    return lamps


def test_a_far_cars_lamps_of_two_pixels_are_laid_out_under_its_body_top_by_pixel_centres():
    """A car 40 m away (1.8 m = 22 px; a lamp 4 x 2 px) whose body top is at 0.8 m, white lamps on white
    paint (nothing to snap to): each lamp is proposed on the pixels the lamp covers (IoU >= 0.5). The
    old code put a narrow face's body top at the typical 0.9 m and padded the box to 5 x 3 px, a row
    and a half above the lamp (IoU 0.2, a miss at the benchmark's 0.3)."""
    img, lab, depth, inst, intr = _frame()
    truth = _far_car(img, lab, depth, inst, 40.0, 0.8, (200, 200, 200), (200, 200, 200))
    assert all(2 <= t.sum() <= 10 for t in truth)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.5


def test_a_far_lamp_pair_seen_one_row_apart_is_laid_out_on_the_pixel_centres_of_its_mean_rows():
    """A far car (40 m, body top 0.9 m; each red lamp 4 x 2 px) whose right lamp shows only its lower row
    (its upper row in the paint's colour): the two snapped lamps agree, and their mean rows (a half pixel
    at the top) cover the centres of both rows -- each lamp is proposed on its own pixels (IoU >= 0.7). The
    old code rounded the mean's ends (round half to even: a row lost) and proposed both lamps one row tall
    (IoU 0.5)."""
    img, lab, depth, inst, intr = _frame()
    truth = _far_car(img, lab, depth, inst, 40.0, 0.9, (40, 60, 140), (200, 20, 20))
    ys, xs = np.nonzero(truth[1])
    assert ys.max() - ys.min() == 1
    img[ys.min(), xs] = (40, 60, 140)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.7


def test_a_far_cars_body_top_edge_standing_out_of_the_paint_is_not_taken_for_its_lamps():
    """A car 40 m away (body top 0.9 m; lamps 4 x 2 px in the paint's colour, nothing to snap to) whose
    body's top row stands out of the paint over the lamps' columns (the deck's or the cabin seam's edge
    by day; 512x256 default seed 0, a 3-px false lamp two rows above a lamp): the lamps are laid out under
    the body top (IoU >= 0.5), not snapped to that row. The old code snapped both to it (IoU 0)."""
    img, lab, depth, inst, intr = _frame()
    truth = _far_car(img, lab, depth, inst, 40.0, 0.9, (40, 60, 140), (40, 60, 140))
    body = _centres((0.3, 0.9), (-0.9, 0.9), 40.0, lab.shape)
    top = int(np.nonzero(body.any(1))[0].min())
    for t in truth:
        xs = np.flatnonzero(t.any(0))
        img[top, xs.min():xs.max() + 1] = (200, 200, 200)
    for params, hit in ((FLAT, True), (replace(FLAT, vehicle_small_lamp_top_m=0.0), False)):
        ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=params))
        assert all((max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.5) == hit for t in truth)


def test_a_car_of_fifty_pixels_gets_its_rear_window():
    """A car 90 m away is 54 px (1.8 m = 10 px wide); its dark rear window (0.07 m above a 0.85 m body
    top) is 16 px: it is proposed (IoU >= 0.3, the benchmark's match). The old code skipped vehicles
    under 60 px and proposed nothing on it."""
    img, lab, depth, inst, intr = _frame()
    _far_car(img, lab, depth, inst, 90.0, 0.85, (150, 150, 155), (150, 150, 155))
    pane = _centres((0.92, 1.28), (-0.72, 0.72), 90.0, lab.shape)
    img[pane] = (25, 25, 30)
    assert 40 <= (lab == CAR).sum() < 60
    ann = propose_lights(img, lab, depth, intr, inst, params=FLAT).annotation
    panes = [i for i in ann.instance_ids() if class_of(i) == 2]
    assert max((_iou(ann.mask(i), pane) for i in panes), default=0.0) >= 0.3


def test_a_far_cars_lamp_two_rows_below_where_its_face_top_is_taken_is_snapped_to():
    """A car 34 m away (red lamps 4 x 2 px on blue paint) whose cabin's lowest two rows show at the body's
    full width (its 0.1 m inset is under two pixels there, and the car in front can hide it): the body top
    is taken two rows high and the lamp boxes with it, and each lamp is snapped to its own pixels (IoU >=
    0.7). The old code looked for them only a row beyond the box and kept the one row it caught (IoU 0.5)."""
    img, lab, depth, inst, intr = _frame()
    truth = _far_car(img, lab, depth, inst, 34.0, 0.9, (40, 60, 140), (200, 20, 20))
    body = _centres((0.3, 0.9), (-0.9, 0.9), 34.0, lab.shape)
    top = int(np.nonzero(body.any(1))[0].min())
    cab = np.zeros_like(body)
    cab[top - 2:top] = body[top]
    lab[cab], img[cab], depth[cab], inst[cab] = CAR, (40, 60, 140), 34.1, CAR * 1000 + 1
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.7


def test_a_far_red_lamp_is_its_own_pixels_not_the_colour_bled_around_it():
    """A far car's red rear lamps (4 x 2 px at 40 m, body top 0.9 m) with their colour bled a pixel
    around them (half red, as the day render's antialiasing and edge blur leave it): the proposed lamp
    is the lamp's pixels, no touch-up needed (IoU >= 0.7), and a rear lamp. The old code took the whole
    blob of colour, 6 x 4 px (IoU 0.33)."""
    img, lab, depth, inst, intr = _frame()
    truth = _far_car(img, lab, depth, inst, 40.0, 0.9, (40, 60, 140), (200, 20, 20), bleed=(120, 40, 80))
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.7
    assert lamps and all(class_of(i) in (4, 6) for i in lamps)


def test_a_far_lamp_whose_rim_stands_out_of_the_paint_more_than_its_middle_is_the_rims_inside():
    """A far car's lamps (4 x 2 px at 40 m, body top 0.9 m) whose middle stays within 30 levels of the
    paint while the pixel around them stands out (a bright rim about a lens dim by day; on the 512x256
    hard street, seed 2, a red car's lamp ringed by lighter pixels): the blob snapped is the ring, and
    the lamp is its inside -- the ring's box less its bled pixel each way -- (IoU >= 0.7). The old code
    eroded the ring's own pixels, which left a few of them (IoU 0.33)."""
    img, lab, depth, inst, intr = _frame()
    truth = _far_car(img, lab, depth, inst, 40.0, 0.9, (40, 60, 140), (60, 50, 110), bleed=(150, 60, 90))
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.7


def test_a_clear_cars_lamps_and_windscreen_are_confident_and_lamps_not_standing_out_are_not():
    """Confidence ranks what an annotator would accept at the editor's slider (0.9): a car whose red lamps
    stand out of blue paint gets them and its dark rear window (its end pane: large, far off the paint)
    at >= 0.9; the same car with lamps a few levels off its red paint (placed by the face's geometry
    alone) gets them below 0.9 -- but still >= 0.5, so the set kept at 0.5 is unchanged. The old code
    gave every pane 0.6, below the slider whatever it looked like."""
    confs = {}
    for name, paint, lamp in (("clear", (40, 60, 140), (200, 20, 20)), ("faint", (150, 40, 40), (160, 36, 36))):
        img, lab, depth, inst, intr = _frame()
        _car(img, lab, depth, inst, 55, 145, 1, paint=paint, lamp=lamp)
        props = propose_lights(img, lab, depth, intr, inst, params=FLAT)
        ids = props.annotation.instance_ids()
        confs[name] = ([props.confidence[i] for i in ids if class_of(i) in (3, 4, 5, 6)],
                       [props.confidence[i] for i in ids if class_of(i) == 2])
    lamps, panes = confs["clear"]
    assert len(lamps) == 2 and min(lamps) >= 0.9
    assert panes and max(panes) >= 0.9
    faint, _ = confs["faint"]
    assert faint and all(0.5 <= c < 0.9 for c in faint)


def test_a_far_cars_rear_window_sits_on_its_own_body_top_not_the_typical_one():
    """A car 52 m away (1.8 m = 17 px, under ``vehicle_small_face_px``) whose body top is at 0.8 m and its
    rear window 0.07 m above it: the end pane is proposed down to the silhouette's own body top, no
    touch-up needed (IoU >= 0.7). The old code cut the cabin band at the typical 0.9 m body top, a row too
    high (IoU 0.61)."""
    assert _far_rear_window_iou(52.0, 0.8, (200, 200, 200)) >= 0.7


def _far_rear_window_iou(z: float, body_top: float, paint) -> float:
    """The best IoU of a proposed vehicle pane with the rear window (0.07 m above the body top, 0.36 m
    tall, 1.44 m wide) of a far car at ``z`` m whose body top is at ``body_top`` m."""
    img, lab, depth, inst, intr = _frame()
    _far_car(img, lab, depth, inst, z, body_top, paint, paint)
    pane = _centres((body_top + 0.07, body_top + 0.43), (-0.72, 0.72), z, lab.shape)
    img[pane] = (25, 25, 30)
    ann = propose_lights(img, lab, depth, intr, inst, params=FLAT).annotation
    panes = [i for i in ann.instance_ids() if class_of(i) == 2]
    return max((_iou(ann.mask(i), pane) for i in panes), default=0.0)


def test_a_far_cars_rear_window_on_a_body_top_at_the_typical_height_reaches_down_to_its_glass():
    """A car 50 m away (1.8 m = 18 px, under ``vehicle_small_face_px``), body top at the typical 0.9 m,
    rear window 0.07 m above it, rasterised by pixel centres: the face's top row is the typical height's
    projected row, rounded -- a line through that row's pixels, not the edge above it -- and the glass
    holds the rows whose centres lie above that line less the 0.07 m frame. The pane is proposed without a
    touch-up (IoU >= 0.7). The old code took the rounded row for an edge and ended the band a row too
    high (IoU 0.68; 2048x1024 hard seeds 0-2, cars beyond 80 m: 49 of 72 matched panes ended 1-3 rows above
    their true bottom; docs/proposals.md, "Twelfth pass: far cars' panes")."""
    assert _far_rear_window_iou(50.0, 0.9, (150, 150, 155)) >= 0.7


def test_a_face_whose_lower_body_the_car_in_front_hides_keeps_its_body_top():
    """A grey car at 10 m whose lower body (from 0.81 m down, its outer half) the car in front hides:
    only 4 full-width body rows show (under 0.15 of its 56-row silhouette), its lamps a few levels off
    the paint (nothing to snap to). Its body top is the top of those rows and the visible lamp is laid
    out under it (IoU >= 0.6). The old code took the silhouette's lower 60 % for the body, its top
    4 rows (0.08 m) too high, the lamp box with it (IoU 0.4)."""
    img, lab, depth, inst, intr = _frame()
    truth = _car(img, lab, depth, inst, 55, 145, 1, paint=(150, 150, 150), lamp=(172, 172, 172))
    front = (slice(80, 120), slice(20, 101))                 # the car in front, 1 m nearer
    lab[front], img[front], depth[front], inst[front] = CAR, (60, 60, 70), 9.0, CAR * 1000 + 2
    visible = truth[1] & (inst == CAR * 1000 + 1)
    assert visible.sum() == truth[1].sum()
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    assert max((_iou(ann.mask(i), visible) for i in lamps), default=0.0) >= 0.6


def test_a_lamp_beside_the_car_in_front_is_not_joined_to_the_seam_of_its_colour():
    """A car at 8 m (a lamp 9 x 19 px) whose outer part the car in front hides from top to bottom, its
    white colour bled one pixel into the silhouette all along the cut (the day render's edge blur); the
    car's red lamp starts right at the cut. The proposed lamp is the lamp (IoU >= 0.7), not the lamp
    and the seam above and below it. The old code snapped to both (IoU 0.6)."""
    z = 8.0
    img, lab, depth, inst, intr = _frame()
    truth = _car(img, lab, depth, inst, 30, 142, 1, z=z)
    lamp = truth[0]
    cut = int(np.flatnonzero(lamp.any(0))[0])                # the car in front ends at the lamp's outer edge
    front = (slice(0, 120), slice(0, cut))
    lab[front], img[front], depth[front], inst[front] = CAR, (220, 220, 220), 7.0, CAR * 1000 + 2
    seam = (inst == CAR * 1000 + 1) & ~lamp
    seam[:, cut + 1:] = False
    img[seam] = (220, 220, 220)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    assert max((_iou(ann.mask(i), lamp) for i in lamps), default=0.0) >= 0.7


def test_a_lamp_mostly_hidden_by_the_car_in_front_is_snapped_to_what_shows_of_it():
    """A car at 8 m whose left lamp the car in front hides but its inner third (a red lamp on green
    paint, 7 x 9 px showing of 19 x 9; the right lamp does not stand out of the paint): the proposed
    lamp is what shows of it (IoU >= 0.9). The old code
    wanted a third of the whole lamp box in off-paint pixels, hidden pixels included, and laid out the
    box by geometry instead (its rows 0.06-0.23 m below the body top: IoU 0.7)."""
    z = 8.0
    img, lab, depth, inst, intr = _frame()
    truth = _car(img, lab, depth, inst, 30, 142, 1, paint=(40, 90, 50), z=z)
    img[truth[1]] = (40, 90, 50)                             # the other lamp does not stand out
    rows, cols = np.flatnonzero(truth[0].any(1)), np.flatnonzero(truth[0].any(0))
    cut = int(cols[-1]) - 2                                  # the car in front hides all of the lamp
    front = (slice(int(rows[0]) + 3, 120), slice(0, cut))    # but its top three rows and inner three columns
    lab[front], img[front], depth[front], inst[front] = CAR, (220, 220, 220), 7.0, CAR * 1000 + 2
    visible = truth[0] & (inst == CAR * 1000 + 1)
    assert 0.35 < visible.sum() / truth[0].sum() < 0.5
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    assert max((_iou(ann.mask(i), visible) for i in lamps), default=0.0) >= 0.9


def test_a_car_cut_by_the_image_border_gets_its_lamp_on_the_strip_of_end_face_left():
    """A grey car at 8 m cut by the frame's right border: 17 px of its end face show (0.15 of its 112 px,
    a grey lamp on grey paint: nothing to snap to), its side face recedes to the left. The face is laid
    out from its inner edge, which depth finds, and the visible lamp with it (IoU >= 0.5). The old code
    took an inner edge only from a strip of 0.3 of the face at the border (as for a face not cut at all),
    laid the face out from the border instead and proposed its lamp beyond the frame (none)."""
    z, corner = 8.0, 183
    img, lab, depth, inst, intr = _frame()
    ppm = 500.0 / z
    body, cab = slice(_row(0.9, z), _row(0.3, z)), slice(_row(1.4, z), _row(0.9, z))
    side = slice(corner - 60, corner)                        # the side face, 12 -> 8.5 m, a shade lighter
    lab[body, side], img[body, side], inst[body, side] = CAR, (175, 175, 175), CAR * 1000 + 1
    depth[body, side] = np.linspace(12.0, 8.5, 60)[None, :]
    for rows, c in ((body, corner), (cab, corner + 6)):
        lab[rows, c:], img[rows, c:], inst[rows, c:], depth[rows, c:] = CAR, (150, 150, 150), CAR * 1000 + 1, z
    lamp = np.zeros(lab.shape, bool)
    lamp[_row(0.83, z):_row(0.68, z), corner + int(round(0.08 * ppm)):corner + int(round(0.38 * ppm))] = True
    img[lamp] = (150, 150, 150)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    assert max((_iou(ann.mask(i), lamp) for i in lamps), default=0.0) >= 0.5


def test_a_lighter_stripe_through_the_lamp_window_is_not_taken_for_the_lamp():
    """A grey car at 10 m whose lamps do not stand out of the paint, and a lighter stripe 4 px wide running
    down its whole body beside the left lamp (as the lighter side face shows inside a face box placed a few
    pixels off, or an edge highlight): the stripe is taller than a lamp could be, so both lamps are laid out
    by the face's geometry (IoU >= 0.5). The old code snapped the left lamp to the stripe and mirrored it
    to the right (IoU 0 for both)."""
    img, lab, depth, inst, intr = _frame()
    truth = _car(img, lab, depth, inst, 55, 145, 1, paint=(150, 150, 150), lamp=(150, 150, 150))
    img[_row(0.9):_row(0.3), 77:81] = (215, 215, 215)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.5


def test_a_side_window_standing_out_of_its_paint_is_taken_at_the_slider_one_barely_darker_is_not():
    """The pane score (``vehicles._rescore``): a side window of 100 px whose colour departs 40 levels from
    the car's paint around it, on a car one of whose lamps was found, is accepted at the editor's slider
    (>= 0.9); the same pane only 10 levels off its paint is not. Such panes were right (IoU >= 0.7) as
    often as those scored 0.9-0.95 on held-out streets (docs/proposals.md, "Tenth pass: vehicle lamps").
    (One lamp in the twelfth pass's first refit; two, its band split at the end face's edge, since the
    second: "Twelfth pass: far cars' panes".)"""
    from npsim_core.proposals.vehicles import _rescore

    p = ProposalParams()

    def pane(contrast_levels: float) -> float:
        return _rescore(0.6, p.vehicle_pane_conf_bias, p.vehicle_pane_conf_weights,
                        (contrast_levels / 40.0, 0.0, float(np.log(100)), 2.0, 0.0, 0.0))

    assert pane(40.0) >= 0.9
    assert 0.5 <= pane(10.0) < 0.9


def test_a_near_cars_faint_window_is_taken_at_the_slider_a_far_cars_equally_faint_one_is_not():
    """A pane's size decides how much a pixel's offset costs its IoU: the near cars' panes of thousands of
    pixels scored 0.7-0.9 matched their true pane at IoU >= 0.5 in 25 of 31 at 2048x1024 (seeds 0-5; those
    of 200-2000 px 46 of 55), the far cars' panes under 200 px in the same band in 97 of 229 (docs/proposals.md, "Twelfth pass: whole cars
    at the slider"). A side window of 3000 px 10 levels off its paint, on a car with one lamp found, is
    taken at the slider (the old weights scored it 0.81); the same window of 50 px is not (both split from
    the end pane at the end face's edge, no pillar seen)."""
    from npsim_core.proposals.vehicles import _rescore

    p = ProposalParams()

    def pane(px: int) -> float:
        return _rescore(0.6, p.vehicle_pane_conf_bias, p.vehicle_pane_conf_weights,
                        (10.0 / 40.0, 0.0, float(np.log(px)), 1.0, 0.0, 0.0))

    assert pane(3000) >= 0.9
    assert 0.5 <= pane(50) < 0.9


def test_a_far_cars_pane_parted_from_the_next_at_a_painted_pillar_is_taken_at_the_slider_one_split_at_the_face_edge_is_not():
    """A pane whose band parted at a pillar -- paint-coloured columns between runs of glass -- sits where the
    photo shows it; one split at the end face's edge was laid out from that edge. At 2048x1024 seeds 0-2 the
    far cars' panes (under 200 px) the old weights scored 0.5-0.9 matched a true pane at IoU >= 0.5 in 50 of
    61 when parted at a pillar, 22 of 90 when split at the edge (docs/proposals.md, "Twelfth pass: far cars'
    panes"). A
    50-px side window 20 levels off its paint on a car with one lamp found: parted at a pillar it is taken at
    the slider (0.9), split at the face's edge it is not. The old score had no such term (0.83 either way)."""
    from npsim_core.proposals.vehicles import _rescore

    p = ProposalParams()

    def pane(parted: bool) -> float:
        return _rescore(0.6, p.vehicle_pane_conf_bias, p.vehicle_pane_conf_weights,
                        (20.0 / 40.0, 0.0, float(np.log(50)), 1.0, 0.0, float(parted)))

    assert pane(True) >= 0.9
    assert 0.5 <= pane(False) < 0.9


def test_the_black_wheel_beside_the_image_border_is_not_taken_for_a_red_lamp_sliver():
    """A blue car at 6 m cut by the frame's right border, its lamps beyond it (or not standing out of the
    paint), and the top of its black wheel at the border reaching 0.62 m, into the rows where a lamp's
    sliver is looked for: a black pixel on blue paint departs from it "towards red" (its red drops least),
    but has no colour of a lamp, so no lamp is proposed there. The old code proposed the wheel's top as
    the rear lamp's sliver."""
    z = 6.0
    img, lab, depth, inst, intr = _frame()
    paint = (46, 77, 132)
    _car(img, lab, depth, inst, 110, 110 + int(1.8 * 500 / z), 1, paint=paint, lamp=paint, z=z)
    wheel = (slice(_row(0.62, z), _row(0.0, z)), slice(200 - int(0.25 * 500 / z), 200))
    lab[wheel], img[wheel], inst[wheel], depth[wheel] = CAR, (20, 20, 20), CAR * 1000 + 1, z
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    on_wheel = np.zeros(lab.shape, bool)
    on_wheel[wheel] = True
    assert not any((ann.mask(i) & on_wheel).any() for i in lamps)


def test_a_red_lamp_on_a_dark_car_whose_face_depth_cannot_place_is_found_by_its_colour():
    """A dark car at 21 m in a row parked left of the road, its outer part hidden by the car in front (2 m
    nearer), whose predicted depth is one ramp over its end face and its side face (0.06 m a pixel, as a
    far row of parked cars reads): the face is misplaced and none of its lamp boxes is kept (hidden, or
    off the silhouette), but its right rear lamp, red on the dark paint, is proposed from its colour
    (IoU >= 0.5). The old code proposed no lamp on the car (2048x1024 hard seeds 1 and 2: lamps of 35
    and 42 px at 61 and 80 m)."""
    z = 21.0
    img, lab, depth, inst, intr = _frame(cx=160.0)
    x0, x1 = 55, 55 + int(round(1.8 * 500 / z))
    truth = _car(img, lab, depth, inst, x0, x1, 1, paint=(18, 21, 28), lamp=(150, 30, 30), z=z)
    side = (slice(_row(0.9, z), _row(0.3, z)), slice(x1, x1 + 40))      # its side face, to the right
    lab[side], img[side], inst[side] = CAR, (28, 31, 40), CAR * 1000 + 1
    own = inst == CAR * 1000 + 1
    depth[own] = np.broadcast_to(z + 0.06 * (np.arange(200) - x0), depth.shape)[own]
    front = (slice(_row(1.3, z - 2), 120), slice(0, x0 + 20))
    lab[front], img[front], depth[front], inst[front] = CAR, (120, 120, 125), z - 2, CAR * 1000 + 2
    visible = truth[1] & (inst == CAR * 1000 + 1)
    assert visible.sum() == truth[1].sum()
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    on_car = [i for i in lamps if (ann.mask(i) & (inst == CAR * 1000 + 1)).any()]
    assert max((_iou(ann.mask(i), visible) for i in on_car), default=0.0) >= 0.5
    assert all(_iou(ann.mask(i), visible) > 0 for i in on_car)


def _sliver_scene(cut: int):
    """The parked row of the sliver test above, the car in front ending at column ``cut`` (141 - cut columns
    of the right lamp show beside it), the lamps purple-red (110, 40, 110) on blue paint (ring contrast
    about 1.7 x 40 levels)."""
    img, lab, depth, inst, intr = _frame(cx=160.0)
    side = (slice(_row(0.9), _row(0.3)), slice(145, 175))
    lab[side], img[side], inst[side] = CAR, (28, 42, 100), CAR * 1000 + 1
    depth[side] = 10.0 + 0.13 * (np.arange(145, 175) - 144)
    truth = _car(img, lab, depth, inst, 55, 145, 1, lamp=(110, 40, 110))
    front = (slice(30, 120), slice(0, cut))
    lab[front], img[front], depth[front], inst[front] = CAR, (200, 200, 200), 9.0, CAR * 1000 + 2
    strip = (slice(None), slice(cut, 141))
    depth[strip] = np.where(inst[strip] == CAR * 1000 + 1, np.linspace(9.2, 9.9, 141 - cut)[None, :], depth[strip])
    return img, lab, depth, inst, intr, truth[1] & (inst == CAR * 1000 + 1)


def test_a_lamp_sliver_one_pixel_wide_is_proposed_below_the_slider_one_three_pixels_wide_at_it():
    """A lamp one pixel thin loses half its IoU to a pixel's offset -- on a photo the column beside the car
    in front is the occluder's blurred edge as often as the lamp (2048x1024 seeds 0-5: of the lamps 1-2 px
    thin scored >= 0.9, 1 tight, 1 needing a touch-up, 5 false). The sliver of a lamp showing one column
    beside the car in front is proposed (kept at 0.5) but under the slider (0.9); the same lamp showing three
    columns is at the slider. The old code counted the thin sliver's 7 pixels as a lamp of 7 px: 0.95."""
    confs = {}
    for cut in (140, 138):
        img, lab, depth, inst, intr, visible = _sliver_scene(cut)
        assert visible.any(0).sum() == 141 - cut
        props = propose_lights(img, lab, depth, intr, inst, params=FLAT)
        ann, lamps = _lamps(props)
        on_car = [i for i in lamps if _iou(ann.mask(i), visible) >= 0.5]
        assert len(on_car) == 1
        confs[cut] = props.confidence[on_car[0]]
    assert 0.5 <= confs[140] < 0.9
    assert confs[138] >= 0.9


def _side_on_car(start: int):
    """A blue car at 8 m whose end face (columns 70-181, red lamps) faces the camera and whose side recedes
    to the left from column 70 to ``start`` (0: out of the frame), its side glass 40 levels darker than the
    paint. Returns the scene and the side glass's mask."""
    z, corner = 8.0, 70
    img, lab, depth, inst, intr = _frame()
    body, cab = slice(_row(0.9, z), _row(0.3, z)), slice(_row(1.4, z), _row(0.9, z))
    side = slice(start, corner)
    for rows in (body, cab):
        lab[rows, side], img[rows, side], inst[rows, side] = CAR, (40, 60, 140), CAR * 1000 + 1
        depth[rows, side] = np.linspace(8.0 + 0.06 * (corner - start), 8.0, corner - start)[None, :]
    glass = np.zeros(lab.shape, bool)
    glass[_row(1.33, z):_row(0.97, z), start:corner - 4] = True
    img[glass] = (0, 20, 100)
    end, end_cab = slice(corner, corner + 112), slice(corner + 6, corner + 106)
    lab[body, end], img[body, end], inst[body, end], depth[body, end] = CAR, (40, 60, 140), CAR * 1000 + 1, z
    lab[cab, end_cab], img[cab, end_cab], inst[cab, end_cab], depth[cab, end_cab] = \
        CAR, (40, 60, 140), CAR * 1000 + 1, z
    img[_row(1.33, z):_row(0.97, z), corner + 10:corner + 102] = (20, 22, 25)
    for a in (corner + 5, corner + 88):
        img[_row(0.83, z):_row(0.68, z), a:a + 19] = (200, 20, 20)
    return img, lab, depth, inst, intr, glass


def test_the_side_window_of_a_near_car_the_image_border_cuts_is_taken_at_the_slider_below_an_uncut_one():
    """A car the image border cuts is near, its side seen at a steep angle, and where its end face ends and
    its side begins is laid out from what the border leaves: the side panes of such cars scored >= 0.9 were
    tight (IoU >= 0.7) once in 15 (2048x1024 and 512x256, seeds 0-5) in the eleventh pass, before the panes
    parted at pillars; in the twelfth, 38 of 49 matched at IoU >= 0.5: all 38 of 2000 px or more at 2048x1024
    and 300 px or more at 512x256, none of the 11 smaller. The side window (1584 px) of a car whose side leaves the frame at the left border is
    taken at the slider (0.9), scored below the same car's ending 12 px inside the frame (the border still
    counts against it). The eleventh pass's weights scored it under the slider."""
    confs = {}
    for start in (0, 12):
        img, lab, depth, inst, intr, glass = _side_on_car(start)
        props = propose_lights(img, lab, depth, intr, inst, params=FLAT)
        ann = props.annotation
        side = [i for i in ann.instance_ids() if class_of(i) == 2 and _iou(ann.mask(i), glass) >= 0.7]
        assert len(side) == 1
        confs[start] = props.confidence[side[0]]
    assert 0.9 <= confs[0] < confs[12]


def test_two_side_windows_parted_by_a_painted_pillar_are_two_panes():
    """The cabin band is split into panes at its pillars -- columns the body's paint shows through (a
    parked row's far car shows its end face's edge only where the car in front leaves its body, and
    there the old split at that edge joined the windscreen and the side window: 2048x1024 hard street,
    seeds 0-2, panes matched at IoU >= 0.5 85 -> 108). A car whose side shows two windows parted by a
    4-px pillar in the paint gets each as its own pane (IoU >= 0.7); the old code proposed one side
    pane over both (IoU about 0.5 with each)."""
    _assert_two_panes_at_a_painted_pillar()


def _assert_two_panes_at_a_painted_pillar(glass_colour=None):
    """A car side on (:func:`_side_on_car`), its side glass (in ``glass_colour`` when given) parted by a
    4-px pillar in the paint at columns 36-39: each window is its own pane (IoU >= 0.7)."""
    img, lab, depth, inst, intr, glass = _side_on_car(12)
    if glass_colour is not None:
        img[glass] = glass_colour
    pillar = np.zeros_like(glass)
    pillar[:, 36:40] = True
    img[glass & pillar] = (40, 60, 140)
    ann = propose_lights(img, lab, depth, intr, inst, params=FLAT).above(0.5)
    panes = [ann.mask(i) for i in ann.instance_ids() if class_of(i) == 2]
    for window in (glass & ~pillar & (np.arange(lab.shape[1]) < 36)[None, :],
                   glass & ~pillar & (np.arange(lab.shape[1]) >= 40)[None, :]):
        assert max(_iou(p, window) for p in panes) >= 0.7


def test_a_glass_sliver_beside_a_pillar_is_proposed_below_the_slider():
    """A run of glass between pillars narrower than a twentieth of its band's widest run is a reflection's
    or a pillar's blurred edge as a rule (2048x1024 seeds 0-5: all 13 such runs matched no pane): it is
    kept at 0.5 (the nights' set is unchanged) but under the slider (0.9), while the panes beside it keep
    their rescored confidence. A car's side glass with a 4-px painted pillar 2 px from its end: the 2-px
    run scored 0.91 on the old code."""
    img, lab, depth, inst, intr, glass = _side_on_car(12)
    cols = np.arange(lab.shape[1])[None, :]
    img[glass & (cols >= 14) & (cols < 18)] = (40, 60, 140)
    props = propose_lights(img, lab, depth, intr, inst, params=FLAT)
    ann = props.annotation
    panes = {i: ann.mask(i) for i in ann.instance_ids() if class_of(i) == 2}
    sliver = [i for i, m in panes.items() if _iou(m, glass & (cols < 14)) >= 0.7]
    side = [i for i, m in panes.items() if _iou(m, glass & (cols >= 18)) >= 0.7]
    assert len(sliver) == len(side) == 1
    assert 0.5 <= props.confidence[sliver[0]] < 0.9
    assert props.confidence[side[0]] >= 0.9


def test_side_windows_a_little_off_the_paints_colour_still_part_at_their_painted_pillar():
    """On a near car a pillar (0.1 m at least) spans 3 px or more and its core shows the paint's own colour:
    columns within half of ``vehicle_pillar_paint_diff`` (10 levels) of the paint are pillar there, and glass
    10-20 levels off the paint is glass (2048x1024 hard seed 1: a grey side window 14-22 levels off its olive
    paint was taken for pillar but for its last 17 columns; docs/proposals.md, "Twelfth pass: whole cars at
    the slider"). A car at 8 m whose side glass departs 15 levels from the paint, parted by a 4-px pillar in
    the paint: each window is its own pane (IoU >= 0.7). The old code took the glass for pillar and split the
    cabin at the end face's edge: one side pane over both (IoU about 0.5 with each)."""
    _assert_two_panes_at_a_painted_pillar((25, 45, 125))


def test_a_face_laid_out_from_its_inner_edge_ends_at_the_pillar_when_depth_runs_onto_the_side_face():
    """A red car at 8 m parked left of the road, its outer part hidden by the car in front, so its end face
    (112 px) is laid out from its inner edge. Its side face (33 px, the same paint, no shading step) recedes
    only 0.25 m in predicted depth (blurred), within the end face's depth run; the cabin above shows the
    dark rear window and the lit side window parted by the pillar. The face ends at the pillar and the
    right lamp (grey on the paint: nothing to snap to) is laid out on it (IoU >= 0.5). The old code ended
    the face at the depth run's end, 33 px too far right, and laid the lamp out on the side face (IoU 0)."""
    z = 8.0
    ppm = 500.0 / z
    img, lab, depth, inst, intr = _frame(cx=199.5)
    body, cab = slice(_row(0.9, z), _row(0.3, z)), slice(_row(1.4, z), _row(0.9, z))
    c0, corner, far = 40, 152, 185                           # end face 40..151 (1.8 m), side face to 184
    inset = int(round(0.1 * ppm))
    for rows, a in ((body, c0), (cab, c0 + inset)):
        lab[rows, a:far], img[rows, a:far], inst[rows, a:far] = CAR, (150, 40, 40), CAR * 1000 + 1
    depth[lab == CAR] = z
    side = (slice(None), slice(corner, far))
    depth[side] = np.where(lab[side] == CAR, np.linspace(z, z + 0.25, far - corner)[None, :], depth[side])
    glass = slice(_row(1.33, z), _row(0.97, z))
    img[glass, c0 + inset + 4:corner - inset] = (30, 32, 38)  # the rear window
    img[glass, corner:far - 2] = (120, 125, 135)              # the side window, lit by the sky
    lamp = np.zeros(lab.shape, bool)
    lamp[_row(0.83, z):_row(0.68, z), corner - int(round(0.38 * ppm)):corner - int(round(0.08 * ppm))] = True
    front = (slice(0, 120), slice(0, 75))                    # the car in front, 1 m nearer
    lab[front], img[front], depth[front], inst[front] = CAR, (30, 30, 35), 7.0, CAR * 1000 + 2
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    assert max((_iou(ann.mask(i), lamp) for i in lamps), default=0.0) >= 0.5


def test_a_car_cut_on_its_centre_side_by_the_car_ahead_gets_the_sliver_of_its_red_lamp_not_of_a_white_one():
    """A car parked right of the road at 10 m, seen from behind, cut on both sides: the car in front in its row
    (9 m, further out) hides its right part, the car driving ahead in our lane (8 m, nearer the image centre)
    all of its left part but 5 px of its left lamp, which shows as a sliver beside that car's edge. That sliver
    is proposed (IoU >= 0.5). The old code looked for a sliver only on the side away from the image centre (a
    parked row's car in front, here beside the right lamp, hidden) and proposed none. A white lamp there is not
    proposed: on the centre side only a red lamp's sliver is looked for (a white one is what glass and bright
    paint bled at the cut look like)."""
    for lamp, want in (((200, 20, 20), True), ((235, 235, 230), False)):
        img, lab, depth, inst, intr = _frame(cx=20.0)       # the car is right of the image centre
        truth = _car(img, lab, depth, inst, 55, 145, 1, lamp=lamp)
        cut = int(np.flatnonzero(truth[0].any(0))[-1]) - 4  # 5 columns of the left lamp show
        row = (slice(_row(0.95), 120), slice(105, 200))      # the car in front in the row, 1 m nearer
        lab[row], img[row], depth[row], inst[row] = CAR, (60, 60, 70), 9.0, CAR * 1000 + 2
        ahead = (slice(20, 120), slice(0, cut))              # the car ahead in our lane
        lab[ahead], img[ahead], depth[ahead], inst[ahead] = CAR, (200, 200, 200), 8.0, CAR * 1000 + 3
        visible = truth[0] & (inst == CAR * 1000 + 1)
        assert visible.any(0).sum() == 5
        ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
        on_car = [i for i in lamps if (ann.mask(i) & (inst == CAR * 1000 + 1)).any()]
        assert (max((_iou(ann.mask(i), visible) for i in on_car), default=0.0) >= 0.5) == want


def test_a_car_whose_face_is_laid_out_from_the_car_in_fronts_edge_is_parked_however_near_our_lane_that_guess_lies():
    """The car of the first sliver test (10 m, all of its end face but 8 px hidden by the car in front, no
    inner edge found) stands 1.2 m left of the camera by the face guessed from the occluder's edge, with no
    kerb in view: that guess says nothing of where the car stands sideways, so its sliver is a parked rear
    lamp (class 4). The old code took the guess's offset for the car's and proposed a moving rear lamp (6),
    lit at night."""
    img, lab, depth, inst, intr = _frame(cx=160.0)
    side = (slice(_row(0.9), _row(0.3)), slice(145, 175))
    lab[side], img[side], inst[side] = CAR, (28, 42, 100), CAR * 1000 + 1
    depth[side] = 10.0 + 0.13 * (np.arange(145, 175) - 144)
    _car(img, lab, depth, inst, 55, 145, 1)
    front = (slice(30, 120), slice(0, 137))
    lab[front], img[front], depth[front], inst[front] = CAR, (200, 200, 200), 9.0, CAR * 1000 + 2
    strip = (slice(None), slice(137, 141))
    depth[strip] = np.where(inst[strip] == CAR * 1000 + 1, np.linspace(9.2, 9.9, 4)[None, :], depth[strip])
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    on_car = [i for i in lamps if (ann.mask(i) & (inst == CAR * 1000 + 1)).any()]
    assert on_car and all(class_of(i) == 4 for i in on_car)


def test_a_cabin_sliver_too_narrow_for_two_two_column_panes_parts_at_its_pillar_into_one_column_panes():
    """A far car in a parked row shows a sliver of its cabin: a band of 4 columns, two of glass, a painted
    pillar, one of glass. Runs of one glass column are not panes in a wider band (a pillar's or the
    silhouette's blurred edge), but a band narrower than two 2-column runs and a pillar can part no
    other way: its runs of one column count (2048x1024 hard street, seeds 0-2, panes matched at IoU >= 0.5
    121 -> 127; docs/proposals.md, "Thirteenth pass: vehicle panes at 512x256"). The old code split the
    band at the end face's edge (IoU 0.5 and 0.33 with the two panes)."""
    from npsim_core.proposals.vehicles import _pane_parts

    paint, glass = (40, 60, 140), (20, 22, 25)
    img = np.zeros((3, 4, 3), np.float32)
    img[:] = glass
    img[:, 2] = paint
    band = np.ones((3, 4), bool)
    end = np.zeros_like(band)
    end[:, 1:] = True  # the end face laid out from the car in front's edge, a column off the pillar
    parts, parted = _pane_parts(img, band, end, np.asarray(paint, np.float32), 20.0)
    assert parted
    truth = [np.zeros_like(band), np.zeros_like(band)]
    truth[0][:, :2] = True
    truth[1][:, 3] = True
    for t in truth:
        assert max(_iou(m, t) for _, m, _ in parts) == 1.0
    # In a band wide enough for two 2-column panes a 1-column run is still no pane.
    img6 = np.zeros((3, 6, 3), np.float32)
    img6[:] = glass
    img6[:, 1] = paint
    parts6, parted6 = _pane_parts(img6, np.ones((3, 6), bool), np.zeros((3, 6), bool),
                                  np.asarray(paint, np.float32), 20.0)
    assert not parted6 and not any(m[:, 0].all() and m.sum() == 3 for _, m, _ in parts6)


def test_a_far_cabin_slivers_pillar_blurred_with_its_glass_still_parts_the_panes():
    """A far car's pillar (0.1 m: a pixel or less at 60 m at 512x256, beyond 120 m at 2048x1024) is blurred with
    the glass either side and no longer within ``vehicle_pillar_paint_diff`` of the paint; in a band too narrow
    for two 2-column panes a column departing from the paint clearly less than the glass on both sides of it
    (``PILLAR_DIP``) is that pillar (2048x1024 hard street, seeds 3-5 held out: panes matched at IoU >= 0.5
    113 -> 122; docs/proposals.md, "Thirteenth pass: vehicle panes at 512x256"). A 4-column band whose third
    column is half paint, half glass parts into 2 + 1 columns (IoU 1 with each; the old code: one band over
    both, split at the face's edge); glass whose columns differ by a few levels does not part."""
    from npsim_core.proposals.vehicles import _pane_parts

    paint, glass = np.array((40, 60, 140), np.float32), np.array((20, 22, 25), np.float32)
    img = np.zeros((3, 4, 3), np.float32)
    img[:] = glass
    img[:, 2] = (paint + glass) / 2
    band = np.ones((3, 4), bool)
    end = np.zeros_like(band)
    end[:, 1:] = True
    parts, parted = _pane_parts(img, band, end, paint, 20.0)
    assert parted
    for cols in (slice(0, 2), slice(3, 4)):
        t = np.zeros_like(band)
        t[:, cols] = True
        assert max(_iou(m, t) for _, m, _ in parts) == 1.0
    img[:, 2] = glass + 6  # a reflection a few levels lighter: still glass
    assert not _pane_parts(img, band, end, paint, 20.0)[1]


def test_the_ceiling_measures_a_lamps_departure_from_its_cars_paint_not_from_the_colour_bled_around_it():
    """``benchmarks.vehicle_lamps --ceiling`` (docs/proposals.md, "Fifteenth pass: vehicle lamps"): a true lamp's
    departure is the largest channel difference from the median paint of its own car 2-4 px around it -- not
    from the pixel of blur right beside it, nor from another car or another light's pixels; a lamp whose car
    shows no paint around it departs 0 (nothing to see it against)."""
    from benchmarks.vehicle_lamps import departure

    img = np.zeros((30, 40, 3), np.uint8)
    img[:] = (90, 90, 90)                     # the road
    inst = np.zeros((30, 40), np.int32)
    inst[5:25, 5:35] = 26001                  # the car, blue paint
    img[5:25, 5:35] = (40, 60, 140)
    inst[5:25, 30:35] = 26002                 # a red car in front of its right end
    img[5:25, 30:35] = (200, 30, 30)
    gt = np.zeros((30, 40), np.int32)
    gt[12:14, 12:16] = 4001                   # its lamp: 8 px, 25 levels redder than the paint
    img[12:14, 12:16] = (65, 60, 140)
    img[11, 11:17] = (52, 60, 140)            # the lamp's colour bled a pixel above it
    gt[12:14, 20:24] = 4002                   # a second lamp, far off the paint, within 4 px of neither
    img[12:14, 20:24] = (250, 250, 250)
    n, mx, med = departure(img, gt, inst, 4001)
    assert n == 8 and mx == 25.0 and med == 25.0
    # Its car hidden all around it (a lamp seen through a gap): nothing to measure it against.
    inst2 = inst.copy()
    inst2[8:18, 8:20] = 26002
    inst2[12:14, 12:16] = 26001
    assert departure(img, gt, inst2, 4001)[1:] == (0.0, 0.0)


def test_a_far_lamp_standing_out_only_in_its_middle_column_is_proposed_at_the_lamps_width():
    """A far car (40 m, body top 0.9 m; each lamp 4 x 2 px) whose lamps depart from the blue paint by the
    snap's 40 levels only in one middle column (the others 20 levels off: a lens lit at its middle by day):
    each lamp is proposed at its width about that column (IoU >= 0.5; 512x256 hard seed 2). The old code
    proposed the one column, and the mate mirrored from it (IoU 0.25, a miss at the benchmark's 0.3)."""
    img, lab, depth, inst, intr = _frame()
    truth = _far_car(img, lab, depth, inst, 40.0, 0.9, (40, 60, 140), (60, 60, 125))
    for t in truth:
        ys, xs = np.nonzero(t)
        assert xs.max() - xs.min() + 1 == 4
        img[ys, np.full_like(xs, xs.min() + 1)] = (200, 20, 20)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.5


def test_a_far_cars_face_whose_ends_predicted_depth_cannot_tell_apart_lies_away_from_the_image_centre():
    """A car right of the image centre (48 m, its end face 2.0-3.8 m right of the axis, a column of side
    face on its left at 50.6 m) whose predicted depth runs 48.0 -> 49.3 m across the end face (blurred with
    a farther car behind its right edge): its two ends (48.1 / 49.2 m) are within 2.5 % of depth, so the
    face lies at the silhouette's side away from the image centre, as for a car parallel to the street,
    and both lamps are found (IoU >= 0.5; 512x256 hard seed 2). The old code took the nearer end by any
    margin, laid the face from the silhouette's left edge, and put the right lamp 3 px short (IoU 0)."""
    img, lab, depth, inst, intr = _frame()
    z, top = 48.0, 0.9
    body = _centres((0.3, top), (2.0, 3.8), z, lab.shape)
    cab = _centres((top, top + 0.5), (2.1, 3.7), z, lab.shape)
    cols = np.flatnonzero(body.any(0))
    side = np.zeros_like(body)
    side[:, cols[0] - 1] = body[:, cols[0]]
    car = body | cab | side
    lab[car], img[car], inst[car] = CAR, (60, 70, 85), CAR * 1000 + 1
    ramp = np.interp(np.arange(lab.shape[1]), [cols[0], cols[-1]], [48.0, 49.3]).astype(np.float32)
    depth[car] = np.broadcast_to(ramp, lab.shape)[car]
    depth[side] = 50.6
    truth = [_centres((top - 0.22, top - 0.07), xs, z, lab.shape) for xs in ((2.08, 2.38), (3.42, 3.72))]
    for t in truth:
        img[t] = (200, 20, 20)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.5


def _lamp_with_rim(rim: float, outside: float, strength: float = 60.0):
    """A car at 10 m (blue paint) whose lamps (15 x 7 px) depart from the paint by ``strength`` levels
    inside, by ``rim`` of that on their own outermost pixels and by ``outside`` on the pixels just around
    them, as the day render's antialiasing and edge blur leave a lamp. Returns the lamps' proposals and
    truths."""
    import cv2

    img, lab, depth, inst, intr = _frame()
    paint = np.array((60, 70, 90), np.float32)
    lamp = paint + (strength, -min(strength, 70.0) * 5 / 6, -min(strength, 90.0))
    truth = _car(img, lab, depth, inst, 55, 145, 1, paint=tuple(int(v) for v in paint))
    k = np.ones((3, 3), np.uint8)
    for t in truth:
        t8 = t.astype(np.uint8)
        inner = cv2.erode(t8, k).astype(bool)
        around = cv2.dilate(t8, k).astype(bool) & ~t
        for where, share in ((inner, 1.0), (t & ~inner, rim), (around, outside)):
            img[where] = np.round(paint + share * (lamp - paint)).astype(np.uint8)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    return ann, lamps, truth


def test_a_lamp_is_proposed_with_its_antialiased_rim_not_a_pixel_short_on_every_side():
    """A lamp of 60 levels on its paint whose outermost pixels depart by 0.45 of that (28 levels: half
    covered, under the snap's 40) and the pixels around it by 0.2 (512x256 hard seeds 0-1, red lamps of
    70-96 px at 10-12 m): each lamp is proposed with its rim (IoU >= 0.9). The old code snapped to the
    pixels 40 levels off, a pixel short on every side (IoU 0.62), a touch-up at the slider's 0.7."""
    ann, lamps, truth = _lamp_with_rim(0.45, 0.2)
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.9


def test_a_lamp_whose_blur_already_reaches_the_snap_is_not_grown_past_its_edge():
    """The same lamp blurred wider (its rim 0.75 of its departure, the pixels around it 0.55: a lamp in
    shade, whose light is the blurred ambient -- 512x256 default seed 2 and lights seed 0): the snap
    already holds the rim, and the pixels around, themselves a mix, are not added (IoU >= 0.9)."""
    ann, lamps, truth = _lamp_with_rim(0.75, 0.55)
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.9


def test_a_bright_lamps_blur_beyond_its_edge_is_not_proposed_with_it():
    """A lamp 110 levels off its paint blurred wide (its rim 0.8 of that, the pixels around it 0.5: 55
    levels, over the snap's 40 -- 512x256 default seed 4 and hard seed 3, 8 x 4-px lamps at 21 m): the
    pixels around it, beside no pixel of the lamp's full colour, are left out (IoU >= 0.9). The old code
    proposed the lamp a pixel too large on every side (IoU 0.69)."""
    ann, lamps, truth = _lamp_with_rim(0.8, 0.5, strength=110.0)
    for t in truth:
        assert max((_iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.9


def test_a_lamp_runs_on_below_the_row_where_the_car_in_front_starts_hiding_the_faces_other_side():
    """A car at 10 m cut by the image border (its right lamp beyond it) whose end face's right half a
    nearer car hides from the left lamp's last row down: the face's fill drops there, so its last row r1 is
    the row above, while the left lamp, seen whole, runs on below it. The lamp is proposed whole (IoU >=
    0.95; 512x256 default seed 0: a 15 x 8-px lamp proposed as its upper 5 rows, IoU 0.52). The old code
    stopped the lamp's snap window at r1 and proposed it a row short (IoU 0.86)."""
    img, lab, depth, inst, intr = _frame()
    truth = _car(img, lab, depth, inst, 140, 230, 1)
    rows = np.flatnonzero(truth[0].any(1))
    front = (slice(int(rows[-1]), 120), slice(170, 200))      # the nearer car, over the face's right half
    lab[front], img[front], depth[front], inst[front] = CAR, (200, 200, 200), 7.0, CAR * 1000 + 2
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    assert max((_iou(ann.mask(i), truth[0]) for i in lamps), default=0.0) >= 0.95


def _dark_car_behind_a_yellow_one():
    """A dark car at 25 m (paint (29, 21, 27)) parked left of the road, its face hidden left of column 130
    by a yellow car at 24 m, 4 px of its side face showing right of it. Returns the frame (image as float32),
    the paint, the yellow car's colour, the car's depth and the cut's column."""
    z, cut = 25.0, 130
    img, lab, depth, inst, intr = _frame(cx=160.0)
    img = img.astype(np.float32)
    paint, occ = np.array((29.0, 21.0, 27.0)), np.array((180.0, 150.0, 60.0))
    for s in ((slice(_row(0.9, z), _row(0.3, z)), slice(100, 136)), (slice(_row(1.4, z), _row(0.9, z)), slice(102, 134))):
        lab[s], img[s], depth[s], inst[s] = CAR, paint, z, CAR * 1000 + 1
    side = (slice(_row(0.9, z), _row(0.3, z)), slice(136, 140))
    lab[side], img[side], inst[side] = CAR, (24, 18, 22), CAR * 1000 + 1
    depth[side] = z + 0.3 * (np.arange(136, 140) - 135)
    front = (slice(40, 120), slice(0, cut))
    lab[front], img[front], depth[front], inst[front] = CAR, occ, 24.0, CAR * 1000 + 2
    return img, lab, depth, inst, intr, paint, occ, z, cut


def _far_lamp_at_the_cut(peak: float):
    """A dark car at 25 m (a lamp 6 x 3 px) in a row parked left of the road: the car in front (24 m) hides
    its face but for 6 px and 4 px of side face -- its face is not placed -- and the inner lamp shows 4 x 3 px
    beside the cut, as a far lamp's blur leaves it on the photo (2048x1024 hard seed 2, a red lamp on a black
    car at 115 m): its middle row ``peak`` levels off the paint in its two middle pixels, 30 in the rest of the
    lamp and 16-27 in the rim the blur spreads a pixel around it. Returns the frame and the visible lamp."""
    img, lab, depth, inst, intr, paint, _, z, cut = _dark_car_behind_a_yellow_one()
    dep = np.array([[18, 26, 26, 18, 10], [21, 30, 30, 21, 18], [30, peak, peak, 30, 27], [20, 30, 30, 21, 18],
                    [18, 26, 27, 18, 10]])
    top = _row(0.83, z)
    img[top - 1:top + 4, cut:cut + 5] = np.clip(paint + dep[..., None] * np.array((1.0, 0.1, 0.2)), 0, 255)
    visible = np.zeros(lab.shape, bool)
    visible[top:_row(0.68, z), cut:cut + 4] = True
    return img.astype(np.uint8), lab, depth, inst, intr, visible


def test_a_far_lamp_beside_the_cut_only_its_middle_row_forty_levels_off_the_paint_is_proposed_at_its_blur():
    """A far lamp beside the car in front whose blur leaves only its middle row's two middle pixels over the
    sliver's 40 levels (42; the rest of it 30, its rim 16-27) is proposed: the pixels off the paint by half that
    peak, less the rim above and below (IoU >= 0.7 with the 4 x 3 px that show). The old code wanted a part over
    40 levels as tall as a lamp's 0.07 m (2 px) and proposed nothing on the car (2048x1024 hard seeds 0, 2: two
    such 12-px lamps at 115 m missed). A lamp whose middle row stays under the 40 levels is not proposed."""
    img, lab, depth, inst, intr, visible = _far_lamp_at_the_cut(42.0)
    assert visible.sum() == 12
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=FLAT))
    on_car = [i for i in lamps if (ann.mask(i) & (inst == CAR * 1000 + 1)).any()]
    assert max((_iou(ann.mask(i), visible) for i in on_car), default=0.0) >= 0.7
    img, lab, depth, inst, intr, visible = _far_lamp_at_the_cut(36.0)
    # (the lamp the geometry lays out in the strip, ``vehicles._cut_strip_lamp``, off: this is the image's rule)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst, params=replace(FLAT, vehicle_cut_strip_length_m=0.0)))
    assert not [i for i in lamps if (ann.mask(i) & (inst == CAR * 1000 + 1)).any()]


def test_a_lamp_box_laid_out_rows_off_over_the_sliver_beside_the_cut_gives_way_to_the_sliver():
    """512x256 default seed 0: a red car (33 m) the green car in front hides but its inner end; its face's top
    is taken three rows high under that car, so the inner lamp's box (laid out by geometry, nothing to snap
    to on red paint) lies at rows 113-115 while the lamp shows as a sliver at the cut, rows 116-117, on the
    box's columns. The sliver is proposed and the box is not (a false lamp of 15 px on the old code, which
    kept both: the sliver overlaps no pixel of the box). With ``vehicle_sliver_box_tol_px`` -1 the box is
    back. Unit: the box goes only when the sliver's rows miss the box's and its columns lie within them."""
    from benchmarks.proposals import frame
    from npsim_core.proposals.vehicles import _sliver_under_box

    scene, inst = frame(512, 256, 0, "default")
    car = inst == 26003
    box = np.zeros(car.shape, bool)
    box[113:116, 197:203] = True
    sliver = np.zeros(car.shape, bool)
    sliver[116:118, 200] = True
    for tol, box_there in ((1, False), (-1, True)):
        params = replace(ProposalParams(), categories=("vehicles",), vehicle_sliver_box_tol_px=tol)
        ann, lamps = _lamps(propose_lights(scene.image, scene.labels, scene.depth, scene.intrinsics, inst, params))
        on_car = [ann.mask(i) for i in lamps if (ann.mask(i) & car).any()]
        assert max((_iou(mk, sliver) for mk in on_car), default=0.0) >= 0.5
        assert any(_iou(mk, box) >= 0.5 for mk in on_car) == box_there
    assert _sliver_under_box(box, sliver, 1)
    assert not _sliver_under_box(box, np.roll(sliver, 5, axis=1), 1)      # columns beyond the box: another lamp
    assert not _sliver_under_box(box, np.roll(sliver, -2, axis=0), 1)     # rows shared: the box holds the lamp
    assert not _sliver_under_box(box, sliver, -1)


def _border_car_with_dark_end(levels: float):
    """A grey car at 8 m cut by the frame's right border (as the test above, 12 px of its 112-px end face
    left: its inner lamp's box, 0.08-0.38 m in, mostly beyond the frame) whose end face shows a dark bluish
    block (63 / 72 / 84 on 112 / 118 / 126 paint: its end's trim or glass) in the lamp's rows, from the box's
    second column to the border; the lamps themselves do not stand out of the paint. The share of the block
    under a proposed lamp."""
    z, corner = 8.0, 188
    img, lab, depth, inst, intr = _frame()
    paint = (112, 118, 126)
    body, cab = slice(_row(0.9, z), _row(0.3, z)), slice(_row(1.4, z), _row(0.9, z))
    side = slice(corner - 60, corner)
    lab[body, side], img[body, side], inst[body, side] = CAR, (135, 140, 146), CAR * 1000 + 1
    depth[body, side] = np.linspace(12.0, 8.5, 60)[None, :]
    for rows, c in ((body, corner), (cab, corner + 6)):
        lab[rows, c:], img[rows, c:], inst[rows, c:], depth[rows, c:] = CAR, paint, CAR * 1000 + 1, z
    dark = np.zeros(lab.shape, bool)
    dark[_row(0.85, z):_row(0.62, z), 194:] = True
    img[dark] = (63, 72, 84)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst,
                                       params=replace(FLAT, vehicle_border_dark_levels=levels)))
    return max(((ann.mask(i) & dark).sum() / dark.sum() for i in lamps), default=0.0)


def test_a_dark_blob_at_the_frames_border_on_a_near_cars_end_is_not_taken_for_its_lamp():
    """The lamp box on the strip of end face the border leaves holds a dark block reaching the border, 49 / 46
    / 42 levels below the paint: it is not snapped to, and the box, mostly beyond the frame, is not proposed
    (512x256 default seed 3: a 106-px false lamp). The old code (``vehicle_border_dark_levels`` 0) snapped the
    lamp to the block."""
    assert _border_car_with_dark_end(20.0) == 0.0
    assert _border_car_with_dark_end(0.0) > 0.5


def _far_car_with_street_bled_into_its_edge(on: bool):
    """A red car 50 m away (84 / 25 / 25 paint, lamps in its colour: nothing to snap to) whose left edge
    column, in the two rows under the lamps, holds the street's grey bled in by the day render's blur (89 /
    69 / 78: 44 levels off the paint). The best IoU of a proposed lamp with each true lamp."""
    z, paint = 50.0, (84, 25, 25)
    img, lab, depth, inst, intr = _frame()
    truth = _far_car(img, lab, depth, inst, z, 0.8, paint, paint)
    body = _centres((0.3, 0.8), (-0.9, 0.9), z, lab.shape)
    left = int(np.nonzero(body.any(0))[0].min())
    low = int(max(np.nonzero(t.any(1))[0].max() for t in truth))
    img[low + 1:low + 3, left] = (89, 69, 78)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst,
                                       params=replace(FLAT, vehicle_small_lamp_edge_bleed=on)))
    return [max((_iou(ann.mask(i), t) for i in lamps), default=0.0) for t in truth]


def test_a_far_cars_lamp_is_not_snapped_to_the_street_bled_into_its_edge_column():
    """The left lamp's window holds the grey bled into the silhouette's last column beside the street, rows
    under the lamp: it is not taken for the lamp, and both lamps are laid out where the face puts them (IoU >=
    0.5; 512x256 default seed 5: a red car at 56 m, both lamps a row low, and seeds 4, 9 on the default and hard
    streets). The old code (``vehicle_small_lamp_edge_bleed`` False) snapped the left lamp to those two pixels
    and mirrored the right one to its rows (IoU under 0.3, misses)."""
    assert min(_far_car_with_street_bled_into_its_edge(True)) >= 0.5
    assert max(_far_car_with_street_bled_into_its_edge(False)) < 0.3


def _faint_sliver_at_the_cut(shift, rows=(68, 71)):
    """The dark car of :func:`_far_lamp_at_the_cut` (25 m, face not placed: the yellow car in front, 24 m, hides
    it left of column 130), its cut blurred as the photo does (the occluder's last column 2/3 its colour, the
    car's first 1/3), and a lamp 1 px across in that first column, rows ``rows`` (0.1-0.25 m below the body
    top): the blur spreads it over the occluder's last column, its own and the car's next alike -- each
    shifted by ``shift`` (8-bit RGB), a third of the lamp's departure from the paint. Returns the frame and
    the visible lamp (1 x 3 px)."""
    img, lab, depth, inst, intr, paint, occ, z, cut = _dark_car_behind_a_yellow_one()
    body = slice(_row(1.4, z), _row(0.3, z))
    img[body, cut - 1], img[body, cut] = (2 * occ + paint) / 3, (occ + 2 * paint) / 3
    img[rows[0]:rows[1], cut - 1:cut + 2] += np.asarray(shift, np.float32)
    visible = np.zeros(lab.shape, bool)
    visible[rows[0]:rows[1], cut] = True
    return np.clip(img, 0, 255).astype(np.uint8), lab, depth, inst, intr, visible


def test_a_lamp_one_pixel_across_at_the_cut_blended_with_the_car_in_front_is_found_by_its_blur_across_the_cut():
    """A lamp 1 px across at the cut whose blur shifts the occluder's last column, the cut column and the car's
    next by 15-18 levels alike (under the sliver's 40 against the paint) is proposed as the cut column over its
    rows (2048x1024 hard seeds 0-2: 10 of the 14 visible lamps missed are such slivers, 15-47 levels off the
    paint; ``vehicles._sliver_blend``); with ``vehicle_sliver_blend_levels`` 0 (the old code) nothing is. A
    red lamp's shift too; not a darker one (a seam, a gap), nor one on the body's top edge, nor a stripe the
    columns two away share, nor a shift of the cut column alone."""
    def on_car(frame, levels=6.0):
        img, lab, depth, inst, intr, visible = frame
        ann, lamps = _lamps(propose_lights(img, lab, depth, intr, inst,
                                           params=replace(FLAT, vehicle_sliver_blend_levels=levels,
                                                          vehicle_cut_strip_length_m=0.0)))
        return [_iou(ann.mask(i), visible) for i in lamps if (ann.mask(i) & (inst == CAR * 1000 + 1)).any()]

    assert on_car(_faint_sliver_at_the_cut((15, 15, 18))) == [1.0]
    assert on_car(_faint_sliver_at_the_cut((15, 15, 18)), 0.0) == []
    assert on_car(_faint_sliver_at_the_cut((20, -4, -6))) == [1.0]
    dark = _faint_sliver_at_the_cut((-15, -15, -18))
    assert on_car(dark) == on_car(dark, 0.0)
    assert on_car(_faint_sliver_at_the_cut((15, 15, 18), rows=(66, 69))) == []
    for cols in (slice(127, 134), slice(130, 131)):
        img, lab, depth, inst, intr, visible = _faint_sliver_at_the_cut((0, 0, 0))
        img = img.astype(np.float32)
        img[68:71, cols] += (15, 15, 18)
        assert on_car((img.astype(np.uint8), lab, depth, inst, intr, visible)) == []


@functools.lru_cache(maxsize=None)
def _proposed_street(seed: int):
    """(512x256 default street ``seed``, its proposals by ``propose_for_scene``), made once per module:
    the pane tests below read the same frames (neither changes the scene or the proposals)."""
    from npsim_core.proposals import propose_for_scene
    from npsim_core.synthetic import street_scene

    scene = street_scene(512, 256, seed, "default")
    return scene, propose_for_scene(scene)


def _best_pane_iou(scene, props, truth_id: int) -> float:
    t = scene.lights.instance_map == truth_id
    ann = props.annotation
    return max((_iou(ann.mask(i), t) for i in ann.instance_ids() if class_of(i) == class_of(truth_id)), default=0.0)


def test_a_near_cars_pane_is_proposed_without_the_sunlit_body_its_cabin_band_runs_over():
    """512x256 default seed 1: a yellow car at 9 m whose cabin band runs 3 rows below its rear window over the
    sunlit top of its body (85-95 levels off the shaded end face's paint, under the pillar test's sight)
    and 14 columns left of it where the silhouette is wider than the cabin; and a black car at 29 m whose
    band's last 3 rows are body. Their panes are proposed without the body's rows and columns (IoU >= 0.7:
    no touch-up at the slider; the old code 0.64, 0.68 and 0.65). A far car's pane (seed 0, 81 m: under
    ``vehicle_pane_body_min_ppm``) is left as it was (IoU 0.82)."""
    scene, props = _proposed_street(1)
    for truth_id in (2045, 2010, 2011):
        assert _best_pane_iou(scene, props, truth_id) >= 0.7, truth_id
    assert _best_pane_iou(*_proposed_street(0), 2019) >= 0.8


def test_a_near_cars_pane_of_dark_glass_takes_the_row_of_glass_below_its_band():
    """512x256 default seeds 0 and 2: red cars at 33 m whose cabin band ends a row or two above their dark
    glass (the band ends 0.07 m above the end face's body top; the cabin stands behind the face). A pane whose
    row below is its glass takes that row (IoU >= 0.7: no touch-up at the slider; the old code 0.64 and 0.68)."""
    for seed, truth_id in ((0, 2007), (2, 2015)):
        assert _best_pane_iou(*_proposed_street(seed), truth_id) >= 0.7, (seed, truth_id)


def test_a_far_cars_lamp_beside_the_cut_of_the_car_in_front_is_laid_out_from_the_geometry_under_the_slider():
    """512x256 default seed 0: a parked row whose far cars (115 px at 38 m, 22 px at 95 m) the car in front hides
    but a strip of their end face beside its cut, each showing its inner rear lamp as a pixel or two blended with
    the occluder (34 and 19 levels off the paint: nothing the snap, the sliver or the blur across the cut sees).
    The cut column at the lamp's heights is proposed where the end face's strip (from the side face's far end)
    holds a lamp's pixel and the column is no blend of the occluder and the paint: both lamps matched (IoU >=
    0.3; none on the old code, which looked at no car under 40 px), as rear lamps (what the blend leaves of them
    is darker), at the rule's confidence, under the editor's slider (``vehicles._cut_lamp``). Off
    (``vehicle_cut_lamp_conf`` 0), with no strip to hold a lamp (``vehicle_cut_lamp_vis_px``) or every pixel
    taken for a blend (``vehicle_cut_lamp_blend_levels``): neither."""
    from benchmarks.proposals import frame
    from benchmarks.vehicle_lamps import lamp_matches

    scene, inst = frame(512, 256, 0, "default")
    far = (4019, 4029)

    def found(**kw):
        params = replace(ProposalParams(), categories=("vehicles",), **kw)
        props = propose_lights(scene.image, scene.labels, scene.depth, scene.intrinsics, inst, params)
        match, _ = lamp_matches(scene.lights, props.above(0.5))
        return {g: (props.confidence[match[g]], class_of(match[g])) for g in far if g in match}

    got = found()
    assert sorted(got) == list(far)
    assert all(c == ProposalParams().vehicle_cut_lamp_conf < 0.9 and k == 4 for c, k in got.values())
    assert found(vehicle_cut_lamp_conf=0.0) == {}
    assert found(vehicle_cut_lamp_vis_px=5.0) == {}
    assert found(vehicle_cut_lamp_blend_levels=255.0) == {}


def test_a_cut_cars_inner_lamp_is_laid_out_from_its_side_faces_far_end_where_the_strip_beside_the_cut_holds_it():
    """512x256 lights seed 1: three cars of the right-hand parked row (20-29 m) that the car in front hides but a
    strip of their end face, their inner lamps showing at the cut as 1-6 columns no image cue tells from the
    occluder's blend. The end face's inner edge lies where a side face ``vehicle_cut_strip_length_m`` long
    ends at the silhouette's centre-side end, the body's top from where that end reaches its body rows; the
    lamp 0.07-0.40 m in from that edge, its part on the silhouette beside the cut, is proposed when it reaches
    ``vehicle_cut_strip_margin`` past the cut column's centre (``vehicles._cut_strip_lamp``; the same on the
    2048x1024 hard street's far cars). All three matched (IoU >= 0.3), rear lamps as the truth (a row on the
    right is seen from behind: ``vehicle_cut_strip_rear_right``; by its blended colour one reads as a front
    lamp); none with the rule off, none when the lamp must reach 6 px past the cut."""
    from benchmarks.proposals import frame
    from benchmarks.vehicle_lamps import lamp_matches

    scene, inst = frame(512, 256, 1, "lights")
    cut = (4033, 4035, 4037)

    def found(**kw):
        params = replace(ProposalParams(), categories=("vehicles",), **kw)
        props = propose_lights(scene.image, scene.labels, scene.depth, scene.intrinsics, inst, params)
        match, _ = lamp_matches(scene.lights, props.above(0.5))
        return {g: class_of(match[g]) for g in cut if g in match}

    assert found() == {4033: 4, 4035: 4, 4037: 4}
    assert found(vehicle_cut_strip_rear_right=False)[4037] == 3
    assert found(vehicle_cut_strip_length_m=0.0) == {}
    assert found(vehicle_cut_strip_margin=(6.0, 0.1)) == {}
