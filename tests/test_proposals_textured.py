"""Windows on a brick facade without depth (docs/proposals.md "Twelfth pass: a brick facade without depth")."""

from __future__ import annotations

import numpy as np

from npsim_core.camera import Intrinsics
from npsim_core.proposals import propose_lights
from npsim_core.proposals.params import ProposalParams

W, H = 256, 128
# 3 floors of 6 panes, 10 px wide and 14 px tall, on a wall from row 8 to row 100
PANES = [(14 + 28 * r, 12 + 40 * c) for r in range(3) for c in range(6)]


def _brick_wall(seed: int = 0, texture: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """A grey wall of brick courses (2 rows light, 2 dark), its low-frequency shading and noise, with
    dark panes that carry the texture too; sky above, road below. Returns (image, labels)."""
    rng = np.random.default_rng(seed)
    lab = np.full((H, W), 7, np.uint8)
    lab[:8] = 23
    lab[8:100] = 11
    yy, xx = np.mgrid[:H, :W]
    base = np.full((H, W), 150.0)
    for y, x in PANES:
        base[y:y + 14, x:x + 10] = 45.0
    tex = float(texture) * (((yy // 2) % 2) * 35.0 + 20 * np.sin(xx / 9.0) * np.cos(yy / 13.0) + rng.normal(0, 6, (H, W)))
    f = np.where(lab == 11, base + tex, np.where(lab == 23, 200.0, 90.0))
    img = np.repeat(np.clip(f, 0, 255).astype(np.uint8)[..., None], 3, axis=2)
    return img, lab


def _windows(img: np.ndarray, lab: np.ndarray,
             params: ProposalParams = ProposalParams()) -> list[tuple[int, int, int, int]]:
    """Boxes (y0, x0, y1, x1) of the windows proposed at confidence >= 0.5, without depth."""
    K = Intrinsics(fx=W, fy=W, cx=(W - 1) / 2, cy=(H - 1) / 2, width=W, height=H)
    props = propose_lights(img, lab, None, K, None, params)
    ann = props.above(0.5)
    out = []
    for i in props.category_ids("windows"):
        ys, xs = np.nonzero(ann.instance_map == i)
        if ys.size:
            out.append((ys.min(), xs.min(), ys.max() + 1, xs.max() + 1))
    return out


def _matched(boxes: list[tuple[int, int, int, int]]) -> int:
    """Panes covered by a proposed box at IoU >= 0.3."""
    n = 0
    for y, x in PANES:
        for y0, x0, y1, x1 in boxes:
            inter = max(0, min(y1, y + 14) - max(y0, y)) * max(0, min(x1, x + 10) - max(x0, x))
            if inter / ((y1 - y0) * (x1 - x0) + 140 - inter) >= 0.3:
                n += 1
                break
    return n


def test_brick_facade_without_depth_gives_its_windows_not_its_bricks():
    img, lab = _brick_wall()
    boxes = _windows(img, lab)
    assert _matched(boxes) >= 15  # of 18 panes
    assert len(boxes) <= 24  # not a window per brick course


def test_texture_rule_leaves_a_plain_wall_alone():
    plain, lab = _brick_wall(texture=False)
    a = _windows(plain, lab)
    b = _windows(plain, lab, ProposalParams(window_texture_mad=0.0))
    assert a == b and _matched(a) >= 15
