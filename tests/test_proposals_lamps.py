"""Street lamps and signs as an annotator trusts them (issue #26, eleventh pass "street lamps and
signs: confidence and lost pole tops", docs/proposals.md): the confidence of arm heads and masts, a far
pole whose top the labels lost, and a sign that something in front touches but that meets the size
rules anyway."""

from __future__ import annotations

import numpy as np

from npsim_core.annotation import class_of
from npsim_core.camera import Intrinsics
from npsim_core.proposals import ProposalParams, propose_lights

from proposal_helpers import FLAT, canvas, iou

ROAD, BUILDING, POLE, TRAFFIC_LIGHT, VEGETATION = 7, 11, 17, 19, 21
GREY = (80, 80, 85)


def _lamps(props, threshold=0.5):
    ann = props.above(threshold)
    return ann, [i for i in ann.instance_ids() if class_of(i) in (8, 9)]


def _pole_frame(px_per_m: float, depth_m: float):
    """A 200 x 200 frame of sky over road at ``depth_m`` with ``px_per_m`` pixels per metre there; the
    row of the ground under the camera's 1.22 m (``foot``)."""
    img, lab = canvas(H=200, W=200)
    lab[150:, :] = ROAD
    depth = np.full((200, 200), depth_m, np.float32)
    f = px_per_m * depth_m
    intr = Intrinsics(fx=f, fy=f, cx=99.5, cy=99.5, width=200, height=200)
    foot = int(round(99.5 + 1.22 * px_per_m))
    return img, lab, depth, intr, foot


def _arm_pole(px_per_m: float = 10.0, depth_m: float = 20.0):
    """An 8 m pole (``px_per_m`` px per metre), its arm 2 m long and 0.2 m thick, a 0.8 x 0.4 m head at
    the arm's end with a lens under the arm."""
    img, lab, depth, intr, foot = _pole_frame(px_per_m, depth_m)
    top = foot - 80
    lab[top:foot, 60:62], img[top:foot, 60:62] = POLE, GREY         # trunk
    lab[top:top + 2, 60:81], img[top:top + 2, 60:81] = POLE, GREY   # arm
    lab[top:top + 4, 73:81], img[top:top + 4, 73:81] = POLE, GREY   # head, cols 73-80
    lens = np.zeros(lab.shape, bool)
    lens[top + 2:top + 4, 73:80] = True
    img[lens] = (200, 200, 190)
    return img, lab, depth, intr, lens


def _wall():
    """A 200 x 120 frame of plain wall 20 m away, 10 px per metre."""
    img, lab = canvas()
    lab[:, :] = BUILDING
    img[:, :] = (150, 140, 130)
    depth = np.full(lab.shape, 20.0, np.float32)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=99.5, cy=59.5, width=200, height=120)
    return img, lab, depth, intr


def test_an_arm_head_on_a_tall_pole_passes_the_editors_default_slider():
    """An arm reaching 2 m from an 8 m pole holds a luminaire: accepted at the editor's default 0.9 (it
    was 0.75 plus up to 0.2 for a head brighter than the trunk, so a head in shade was drawn again)."""
    img, lab, depth, intr, lens = _arm_pole()
    img[lens] = GREY                                                 # a lens as dark as the housing
    props = propose_lights(img, lab, depth, intr, params=FLAT)
    ann, lamps = _lamps(props, threshold=0.9)
    assert len(lamps) == 1


def test_an_arm_holding_a_signal_at_its_end_is_a_mast_not_a_sure_luminaire():
    """The same pole with a signal head hanging at the arm's end is a signal mast: its head stays a
    proposal, under the slider."""
    img, lab, depth, intr, lens = _arm_pole()
    top = int(np.flatnonzero(lab[:, 61] == POLE).min())
    lab[top + 4:top + 14, 76:80], img[top + 4:top + 14, 76:80] = TRAFFIC_LIGHT, (20, 20, 20)
    props = propose_lights(img, lab, depth, intr, params=ProposalParams(camera_pitch_rad=0.0,
                                                                       categories=("street_lamps",)))
    ann, lamps = _lamps(props)
    assert len(lamps) == 1 and props.confidence[lamps[0]] < 0.9


def test_a_far_pole_whose_top_the_labels_lost_takes_the_arm_above_it():
    """A far pole (5 px per metre) whose label shows the trunk up to 7 m, then 4 rows of wall, then its
    arm and head (2 rows, 1.6 m to the left): the labels lost the trunk's sub-pixel top. The lamp is
    the head at the arm's end (the proposer before saw a plain pole top: a 0.3 light at the trunk's top
    and none at the head)."""
    img, lab, depth, intr, foot = _pole_frame(5.0, 40.0)
    top = foot - 35
    lab[top:foot, 60], img[top:foot, 60] = POLE, GREY                # trunk, 1 px, up to 7 m
    lab[top - 7:top - 5, 52:61], img[top - 7:top - 5, 52:61] = POLE, GREY   # arm and head
    img[top - 6, 52:56] = (200, 200, 190)
    ann, lamps = _lamps(propose_lights(img, lab, depth, intr, params=FLAT))
    assert len(lamps) == 1 and class_of(lamps[0]) == 8
    ys, xs = np.nonzero(ann.mask(lamps[0]))
    assert set(ys) == {top - 6} and xs.min() == 52 and xs.max() <= 56


def test_a_full_size_sign_whose_top_a_tree_touches_passes_the_slider():
    """A red sign 3 x 0.8 m whose top row runs along a tree's foliage: it meets the size rules without
    the tree's allowance, so it is as sure as a sign on open wall (before, any sign along something in
    front lost 0.2 and was drawn again in the editor); a 0.2 m strip under the tree, kept only by that
    allowance, stays under the slider."""
    img, lab, depth, intr = _wall()
    lab[30:40, 40:80], img[30:40, 40:80] = VEGETATION, (40, 70, 30)
    img[40:48, 45:75] = (200, 30, 25)                            # under the tree, full size
    lab[70:80, 120:150], img[70:80, 120:150] = VEGETATION, (40, 70, 30)
    img[80:82, 125:145] = (200, 30, 25)                          # under another tree, a strip
    props = propose_lights(img, lab, depth, intr, params=ProposalParams(categories=("ads",)))
    ann = props.above(0.5)
    ads = sorted((i for i in ann.instance_ids() if class_of(i) == 10), key=lambda i: np.nonzero(ann.mask(i))[0].min())
    assert len(ads) == 2
    assert props.confidence[ads[0]] >= 0.9 and 0.5 <= props.confidence[ads[1]] < 0.9


def test_a_sign_a_pole_in_front_cuts_in_two_is_one_sign():
    """A red sign 4 x 0.8 m with a 0.3 m pole in front of its middle: its two parts are one light (its
    visible pixels, as an annotator draws it); the proposer before made two signs of it (one a
    removal and the other a touch-up in the editor). A second red sign beside it across open wall
    stays its own."""
    img, lab, depth, intr = _wall()
    img[40:48, 30:70] = (200, 30, 25)
    img[40:48, 76:100] = (200, 30, 25)                          # another sign, 6 px of wall between
    lab[:, 48:51], img[:, 48:51] = POLE, GREY                    # the pole in front
    sign = np.zeros(lab.shape, bool)
    sign[40:48, 30:70] = True
    sign[:, 48:51] = False
    props = propose_lights(img, lab, depth, intr, params=ProposalParams(categories=("ads",)))
    ann = props.above(0.5)
    ads = sorted((i for i in ann.instance_ids() if class_of(i) == 10), key=lambda i: np.nonzero(ann.mask(i))[1].min())
    assert len(ads) == 2
    assert iou(ann.mask(ads[0]), sign) >= 0.95


def test_a_sign_under_the_size_rules_is_a_low_sign_not_a_window():
    """A blue blade sign 0.3 x 0.9 m (0.27 m^2, under ``ad_min_area_m2``) on a plain wall: it is proposed
    as a sign under the render's and the editor's thresholds (0.4), which keeps its pixels from the
    windows proposer (before, nothing proposed it as a sign, and a window taken there cost a class fix
    in the editor)."""
    img, lab, depth, intr = _wall()
    img[40:49, 60:63] = (40, 60, 200)
    sign = np.zeros(lab.shape, bool)
    sign[40:49, 60:63] = True
    props = propose_lights(img, lab, depth, intr)
    ann = props.annotation
    on_sign = {int(i) for i in np.unique(ann.instance_map[sign]) if i}
    assert on_sign and all(class_of(i) == 10 for i in on_sign)
    assert all(props.confidence[i] < 0.5 for i in on_sign)
