"""The proposal layer of the editor: automatic light proposals shown apart from the annotation,
accepted (as ordinary lights and groups, through the undo stack) or rejected one by one, by
group or above a confidence.

:class:`ProposalBook` keeps which proposals were accepted (proposal id -> annotation id) or
rejected; a proposal whose accepted light was undone is pending again. It builds the editor
commands for an acceptance (one undo step) and the RGBA overlay (translucent fill in the class
colour, dashed black/white outline, so proposals never look like accepted lights).
See docs/annotation.md ("Proposals").
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from npsim_core.annotation import class_of
from npsim_core.annotation_ops import group_lights, new_instance, paint

from .overlays import MAX_ID, light_color_lut

#: Fill alpha of a pending proposal (the accepted lights' fill is far more opaque).
PROPOSAL_FILL_ALPHA = 70
#: Dash period of the proposal outline, in image pixels along x + y.
DASH = 3


def proposal_rgba(pmap: np.ndarray, pending: Iterable[int]) -> np.ndarray:
    """(H, W, 4) uint8 overlay of the ``pending`` proposals of the proposal instance map ``pmap``:
    a translucent class-colour fill and a dashed outline (black and white dashes on the border
    pixels, readable on bright and dark pixels alike)."""
    H, W = pmap.shape
    out = np.zeros((H, W, 4), np.uint8)
    pend = np.fromiter(pending, np.int64)
    if pend.size == 0:
        return out
    m = np.where(np.isin(pmap, pend), pmap, 0)
    lit = m != 0
    edge = np.zeros((H, W), bool)
    edge[:, 1:] |= m[:, 1:] != m[:, :-1]
    edge[:, :-1] |= m[:, :-1] != m[:, 1:]
    edge[1:, :] |= m[1:, :] != m[:-1, :]
    edge[:-1, :] |= m[:-1, :] != m[1:, :]
    edge &= lit
    out[..., :3] = light_color_lut()[np.clip(m, 0, MAX_ID)]
    out[..., 3] = np.where(lit, PROPOSAL_FILL_ALPHA, 0)
    yy, xx = np.indices((H, W), sparse=True)
    white = ((xx + yy) // DASH) % 2 == 0
    out[edge & white, :3] = 255
    out[edge & ~white, :3] = 0
    out[edge, 3] = 255
    return out


def _pixels_by_id(pmap: np.ndarray) -> dict[int, np.ndarray]:
    """Flat pixel indices of every non-zero id of ``pmap`` (one sort, not one pass per id)."""
    flat = pmap.ravel()
    nz = np.flatnonzero(flat)
    if nz.size == 0:
        return {}
    order = nz[np.argsort(flat[nz], kind="stable")]
    ids, starts = np.unique(flat[order], return_index=True)
    return {int(i): part for i, part in zip(ids, np.split(order, starts[1:]))}


@dataclass
class ProposalBook:
    """The proposals of one image and what became of them (module doc)."""

    proposals: object  # npsim_core.proposals.LightProposals
    accepted: dict[int, int] = field(default_factory=dict)  # proposal light/group id -> annotation id
    rejected: set[int] = field(default_factory=set)  # proposal light ids

    def __post_init__(self) -> None:
        ann = self.proposals.annotation
        self.pixels = _pixels_by_id(ann.instance_map)
        self.group_of = {m: gid for gid, g in ann.groups.items() for m in g.members}

    @property
    def light_ids(self) -> list[int]:
        return sorted(self.pixels)

    def confidence(self, pid: int) -> float:
        return float(self.proposals.confidence.get(int(pid), 0.0))

    def pending(self, existing: set[int]) -> list[int]:
        """Proposal light ids neither rejected nor accepted as a light that still exists in the
        annotation (``existing``: its instance ids)."""
        return [p for p in self.light_ids if p not in self.rejected and self.accepted.get(p) not in existing]

    def at(self, x: int, y: int, existing: set[int]) -> int:
        """The pending proposal light at pixel (x, y), 0 for none."""
        pid = int(self.proposals.annotation.instance_map[y, x])
        return pid if pid and pid in set(self.pending(existing)) else 0

    def expand(self, pid: int) -> tuple[list[int], list[int]]:
        """(lights, groups) of the whole proposal group of light ``pid`` (just the light when ungrouped)."""
        gid = self.group_of.get(int(pid))
        if gid is None:
            return [int(pid)], []
        return list(self.proposals.ids_in_group(gid)), [gid]

    def reject(self, lights: Iterable[int]) -> None:
        self.rejected |= {int(i) for i in lights}

    def accept(self, session, lights: Iterable[int], groups: Iterable[int] = (), *,
               group_members: dict[int, Iterable[int]] | None = None) -> list[int]:
        """Add the proposal ``lights`` (and every light of ``groups``) to the session's annotation as one
        undo step: a new light per proposal (its pixels not already taken by a light), then each of
        ``groups`` -- and each group an accepted light's proposal group was accepted as before --
        as a group of its accepted lights (of ``group_members[gid]`` only, when given). Returns the
        new light ids."""
        existing = set(session.ann.instance_ids())
        pending = set(self.pending(existing))
        groups = [int(g) for g in groups]
        members_of = {int(g): [int(m) for m in ms] for g, ms in (group_members or {}).items()}
        want = {int(i) for i in lights} | {m for g in groups for m in members_of.get(g, self.proposals.ids_in_group(g))}
        todo = sorted(want & pending)
        new: list[int] = []
        session.begin_stroke("accept proposals")
        try:
            for pid in todo:
                flat = session.ann.instance_map.reshape(-1)
                free = self.pixels[pid][flat[self.pixels[pid]] == 0]
                if free.size == 0:  # wholly under existing lights: nothing to add
                    continue
                cmd, nid = new_instance(session.ann, class_of(pid))
                session.apply(cmd)
                session.apply(paint(session.ann, free, nid))
                self.accepted[pid] = nid
                self.rejected.discard(pid)
                new.append(nid)
            ids_now = set(session.ann.instance_ids())
            touched = set(groups) | {self.group_of[p] for p in todo if p in self.group_of and
                                     self.accepted.get(self.group_of[p]) in session.ann.groups}
            for gid in sorted(touched):
                members = [self.accepted[m] for m in members_of.get(gid, self.proposals.ids_in_group(gid))
                           if self.accepted.get(m) in ids_now]
                if not members:
                    continue
                cmd, ngid = group_lights(session.ann, members, class_of(gid))
                session.apply(cmd)
                self.accepted[gid] = ngid
        finally:
            session.end_stroke()
        return new

    def accept_above(self, session, threshold: float) -> list[int]:
        """Accept every pending proposal with confidence >= ``threshold`` (one undo step), grouped as
        the proposals' groups restricted to those lights (``LightProposals.above``)."""
        kept = self.proposals.above(float(threshold))
        pend = set(self.pending(set(session.ann.instance_ids())))
        lights = [i for i in kept.instance_ids() if i in pend]
        groups = [gid for gid, g in kept.groups.items() if set(g.members) & pend]
        return self.accept(session, lights, groups,
                           group_members={gid: g.members for gid, g in kept.groups.items()})
