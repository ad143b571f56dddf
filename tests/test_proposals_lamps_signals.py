"""Street lamps, signal heads and advertisements drawn as an annotator draws them (issue #26, ninth pass
"lamp, signal and sign masks", docs/proposals.md): the signal lamps on the lenses, a sign's
half-covered rim, a sign in perspective or cut by the frame (the street lamps' lens masks were taken
back the same session)."""

from __future__ import annotations

import numpy as np

from npsim_core.annotation import class_of
from npsim_core.camera import Intrinsics
from npsim_core.proposals import ProposalParams, propose_lights

from proposal_helpers import FLAT, canvas, iou

SKY, ROAD, BUILDING, POLE, TRAFFIC_LIGHT, VEGETATION = 23, 7, 11, 17, 19, 21


def _only(props, classes, threshold=0.5):
    ann = props.above(threshold)
    ids = [i for i in ann.instance_ids() if class_of(i) in classes]
    return ann, ids


def _mix(a, b, cover: float) -> np.ndarray:
    """sRGB colour of a pixel ``cover`` covered by ``a`` over ``b`` (coverage blends in linear light)."""
    lin = cover * (np.asarray(a, float) / 255.0) ** 2.2 + (1 - cover) * (np.asarray(b, float) / 255.0) ** 2.2
    return np.round(255.0 * lin ** (1 / 2.2)).astype(np.uint8)


def test_signal_lamps_sit_on_the_lenses_when_the_housing_label_holds_its_side_face():
    """A head seen from its left: the label holds its front face (cols 90-99) and a 3 px side face in
    shade, so the box's centre is 1.5 px right of the front face's, where the lenses are. The lamps are
    the lenses (the old proposer centred them in the box, 1-2 px off the lenses: a touch-up each in
    the editor), and they are not pulled onto the outline pixels, which blend with the bright sky."""
    img, lab = canvas()
    lab[30:60, 90:103] = TRAFFIC_LIGHT
    img[30:60, 90:103] = (15, 15, 15)
    img[30:60, 100:102] = (40, 40, 42)                          # the side face, in shade
    img[30:60, 102] = (80, 90, 105)                             # its outline, half sky
    lenses = []
    for k, col in enumerate(((120, 20, 15), (110, 80, 10), (15, 90, 40))):
        m = np.zeros(lab.shape, bool)
        m[31 + 10 * k:39 + 10 * k, 91:99] = True                 # 8 px lenses centred on the front face
        img[m] = col
        lenses.append(m)
    lab[60:110, 95:97] = POLE
    ann, lamps = _only(propose_lights(img, lab), (12,))
    assert len(lamps) == 3
    by_row = sorted(lamps, key=lambda i: np.nonzero(ann.mask(i))[0].mean())
    assert all(iou(ann.mask(i), m) >= 0.85 for i, m in zip(by_row, lenses))


def _facade(wall=(150, 140, 130)):
    img, lab = canvas()
    lab[:, :] = BUILDING
    img[:, :] = wall
    depth = np.full(lab.shape, 20.0, np.float32)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=99.5, cy=59.5, width=200, height=120)   # 10 px per metre
    return img, lab, depth, intr


ADS = ProposalParams(categories=("ads",))


def test_a_signs_rim_pixels_it_covers_at_least_half_of_are_in_its_mask():
    """A blue 3 x 0.6 m sign whose edges fall mid-pixel: its rim pixels are 60 % covered (paler than the
    panel, under the saturation threshold) on the top and left, 30 % on the bottom and right. The mask
    holds the first and not the second (the old proposer dropped both)."""
    wall, red = (150, 140, 130), (60, 90, 170)
    img, lab, depth, intr = _facade(wall)
    img[41:46, 51:80] = red
    img[40, 51:80] = img[41:46, 50] = _mix(red, wall, 0.6)
    img[46, 51:80] = img[41:46, 80] = _mix(red, wall, 0.3)
    img[40, 50] = _mix(red, wall, 0.36)
    sign = np.zeros(lab.shape, bool)
    sign[40:46, 50:80] = True
    ann, ads = _only(propose_lights(img, lab, depth, intr, params=ADS), (10,))
    assert len(ads) == 1
    m = ann.mask(ads[0])
    assert m[40, 51:80].all() and m[41:46, 50].all() and not m[46].any() and not m[:, 80].any()
    assert iou(m, sign) >= 0.95


def test_a_sign_seen_in_perspective_is_kept_though_it_fills_under_70_percent_of_its_box():
    """A sign on a facade receding from the camera is a trapezoid: here 20 px wide, 12 px tall at its
    near end and 4 px at its far end (62 % of its box). It is a panel (the old proposer asked 70 % of the
    box and dropped it); a ragged blob of the same colour filling 55 % of its hull is not."""
    img, lab, depth, intr = _facade()
    yy, xx = np.mgrid[0:120, 0:200]
    half = 6.0 - 4.0 * (xx - 40) / 19.0                        # 6 px half-height at x=40, 2 px at x=59
    trap = (xx >= 40) & (xx < 60) & (np.abs(yy + 0.5 - 50.0) <= half)
    img[trap] = (30, 60, 200)
    rng = np.random.default_rng(0)
    ragged = (xx >= 120) & (xx < 150) & (yy >= 40) & (yy < 60) & (rng.random((120, 200)) < 0.55)
    img[ragged] = (30, 60, 200)
    ann, ads = _only(propose_lights(img, lab, depth, intr, params=ADS), (10,))
    assert len(ads) == 1 and iou(ann.mask(ads[0]), trap) >= 0.9


def test_a_sign_cut_by_the_frame_is_held_to_its_height_alone():
    """A 0.6 m tall sign of which the frame shows 0.8 m of width (0.48 m^2, under the 1 m^2 minimum) is
    proposed; the same piece of sign inside the frame is too small to be one."""
    img, lab, depth, intr = _facade()
    img[40:46, 0:8] = (200, 30, 25)                            # cut by the left border
    img[80:86, 100:108] = (200, 30, 25)                        # whole, 0.8 x 0.6 m
    ann, ads = _only(propose_lights(img, lab, depth, intr, params=ADS), (10,))
    assert len(ads) == 1
    ys, xs = np.nonzero(ann.mask(ads[0]))
    assert xs.min() == 0 and ys.min() == 40


def test_a_uniform_saturated_panel_passes_the_editors_default_slider():
    """A uniform red sign of 3 x 0.6 m is accepted at the editor's default threshold (0.9)."""
    img, lab, depth, intr = _facade()
    img[40:46, 50:80] = (200, 30, 25)
    ann, ads = _only(propose_lights(img, lab, depth, intr, params=ADS), (10,), threshold=0.9)
    assert len(ads) == 1


def test_a_sign_whose_top_a_tree_hides_is_held_to_half_the_height():
    """A red sign 2 m wide whose top a tree hides: 2 px (0.2 m) of it show under the foliage. It is
    proposed, below the editor's default slider (a part of a panel); the same 2 px strip on open wall is
    too thin to be a sign (the old proposer dropped both, and the windows proposer took the hidden one)."""
    img, lab, depth, intr = _facade()
    lab[30:40, 40:70] = VEGETATION
    img[30:40, 40:70] = (40, 70, 30)
    img[40:42, 45:65] = (200, 30, 25)                          # under the tree
    img[80:82, 100:120] = (200, 30, 25)                        # on open wall
    props = propose_lights(img, lab, depth, intr, params=ADS)
    ann, ads = _only(props, (10,))
    assert len(ads) == 1
    ys, xs = np.nonzero(ann.mask(ads[0]))
    assert ys.min() == 40 and xs.min() == 45 and 0.5 <= props.confidence[ads[0]] < 0.9


def test_a_small_sign_in_a_shops_fascia_band_is_a_sure_sign():
    """A red panel 1.6 x 0.5 m (0.8 m^2, under the 1 m^2 minimum: a one-bay shop's sign) whose bottom edge
    is 3.05 m above the ground, in a shop's fascia band, is proposed as sure as a sign that meets the size
    rules (the old proposer held it at 0.4, under the slider: a review or a draw); the same panel on an
    upper floor (bottom 5.2 m up) is still held at 0.4, and so is a 0.1 m fleck on open wall in the band
    (under half the minimum height: a letter or a piece of a sign)."""
    img, lab, depth, intr = _facade()
    img[29:34, 40:56] = (200, 30, 25)                          # bottom edge at row 33.5: 3.05 m up
    img[8:13, 120:136] = (200, 30, 25)                         # bottom edge at row 12.5: 5.2 m up
    img[26, 150:166] = (200, 30, 25)                           # 0.1 m tall, bottom 3.4 m up
    props = propose_lights(img, lab, depth, intr, params=ADS)
    ann, ads = _only(props, (10,), threshold=0.0)
    assert len(ads) == 3
    by_col = sorted(ads, key=lambda i: np.nonzero(ann.mask(i))[1].min())
    assert [props.confidence[i] >= 0.9 for i in by_col] == [True, False, False]
    assert max(props.confidence[i] for i in by_col[1:]) < 0.5
