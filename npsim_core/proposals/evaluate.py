"""Scoring proposals against a ground-truth annotation: per-category mask-IoU matching (docs/proposals.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..annotation import LightAnnotation, class_of
from .core import CATEGORY_CLASSES


@dataclass(frozen=True)
class CategoryScore:
    """Matches of one category: ground-truth and proposed counts, one-to-one matches at the IoU threshold."""

    category: str
    n_gt: int
    n_pred: int
    n_match: int

    @property
    def recall(self) -> float:
        return self.n_match / self.n_gt if self.n_gt else float("nan")

    @property
    def precision(self) -> float:
        return self.n_match / self.n_pred if self.n_pred else float("nan")


def _category_ids(ann: LightAnnotation, category: str, areas: dict[int, int], min_area: int) -> list[int]:
    want = CATEGORY_CLASSES[category]
    tl = {m for g in ann.groups.values() if g.class_id == 20 for m in g.members}
    return [i for i, a in areas.items() if class_of(i) in want and a >= min_area
            and (category != "traffic_light_lamps" or i in tl)]


def score_category(gt: LightAnnotation, pred: LightAnnotation, category: str, *, iou: float = 0.3,
                   min_gt_area: int = 1) -> CategoryScore:
    """Greedy one-to-one matching (highest IoU first) of ``category``'s lights at mask IoU >= ``iou``.

    Ground-truth lights smaller than ``min_gt_area`` pixels are left out of the recall, and
    a proposal that matches one of them (IoU >= ``iou``) is left out of the precision.
    """
    g_area, p_area = gt.areas(), pred.areas()
    g_all = _category_ids(gt, category, g_area, 1)
    g_ids = set(_category_ids(gt, category, g_area, min_gt_area))
    p_ids = _category_ids(pred, category, p_area, 1)
    if not g_all or not p_ids:
        return CategoryScore(category, len(g_ids), len(p_ids), 0)
    g_map, p_map = gt.instance_map.ravel(), pred.instance_map.ravel()
    sel = np.isin(g_map, g_all) & np.isin(p_map, p_ids)
    pairs, inter = np.unique(np.stack([g_map[sel], p_map[sel]]).astype(np.int64), axis=1, return_counts=True)
    cand = []
    for (g, p), n in zip(pairs.T.tolist(), inter.tolist()):
        u = g_area[g] + p_area[p] - n
        if n / u >= iou:
            cand.append((n / u, g, p))
    cand.sort(reverse=True)
    used_g: set[int] = set()
    used_p: set[int] = set()
    pairs_kept = []
    for _, g, p in cand:
        if g not in used_g and p not in used_p:
            used_g.add(g)
            used_p.add(p)
            pairs_kept.append((g, p))
    n_match = sum(1 for g, _ in pairs_kept if g in g_ids)
    # a proposal matching a ground-truth light below min_gt_area is neither right nor wrong
    n_excused = sum(1 for g, _ in pairs_kept if g not in g_ids)
    return CategoryScore(category, len(g_ids), len(p_ids) - n_excused, n_match)


def score(gt: LightAnnotation, pred: LightAnnotation, *, iou: float = 0.3, min_gt_area: int = 1,
          categories: tuple[str, ...] = ("windows", "vehicle_lamps", "street_lamps", "traffic_light_lamps")
          ) -> dict[str, CategoryScore]:
    """:func:`score_category` for each category."""
    return {c: score_category(gt, pred, c, iou=iou, min_gt_area=min_gt_area) for c in categories}
