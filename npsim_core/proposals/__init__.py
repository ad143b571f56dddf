"""Automatic light proposals from a daytime frame (docs/proposals.md).

``propose_lights(image, labels, depth, intrinsics, instances)`` proposes traffic-light lamps,
street-lamp heads, vehicle lamps and panes, building windows and advertisements as a
:class:`~npsim_core.annotation.LightAnnotation` (ids ``classId*1000 + k``, groups) with a
confidence per light and per group; ``LightProposals.above(t)`` keeps the sure ones.
"""

from __future__ import annotations

from .core import CATEGORY_CLASSES, LightProposals, propose_for_scene, propose_lights, summarize
from .params import ProposalParams

__all__ = ["ProposalParams", "LightProposals", "propose_lights", "propose_for_scene", "CATEGORY_CLASSES", "summarize"]
