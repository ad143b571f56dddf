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
