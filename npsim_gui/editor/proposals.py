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

from npsim_core.annotation import GroupInstance, class_of
from npsim_core.annotation_ops import EditCommand, PixelDiff, Structure
from npsim_core.errors import NpsimInputError

from .overlays import MAX_ID, light_color_lut

#: Fill alpha of a pending proposal (the accepted lights' fill is far more opaque).
PROPOSAL_FILL_ALPHA = 70
#: Dash period of the proposal outline, in image pixels along x + y.
DASH = 3
#: The confidence slider's default: "Accept ≥" (Ctrl+Shift+A) takes the proposals at or above it. The one
#: place of this value: the editor's slider and ``benchmarks.annotation_actions`` (which charges one action
#: more for any other threshold) both read it. A multiple of 0.01 (the slider's step).
DEFAULT_ACCEPT_THRESHOLD = 0.9


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
        # The overlay of every proposal, drawn once (a full-frame pass: 0.1-0.4 s at 2048x1024, so a
        # book is built in the proposals' worker); what is pending is then shown by setting the alpha of
        # the changed proposals' own pixels (exact: a proposal's outline does not depend on its neighbours
        # being shown, since a neighbour's id differs from its own either way).
        self.overlay = proposal_rgba(ann.instance_map, self.light_ids)
        self._full_alpha = self.overlay[..., 3].reshape(-1).copy()
        self.shown: set[int] = set(self.light_ids)

    def sync_overlay(self, pending: Iterable[int]) -> tuple[int, int, int, int] | None:
        """Show exactly the ``pending`` proposals in :attr:`overlay`, touching only the pixels of those
        whose state changed; returns the box (x0, y0, x1, y1, half-open) that changed, or None."""
        pend = set(int(p) for p in pending)
        changed = pend ^ self.shown
        if not changed:
            return None
        alpha = self.overlay[..., 3].reshape(-1)
        W = self.overlay.shape[1]
        x0 = y0 = 1 << 30
        x1 = y1 = -1
        for pid in changed:
            px = self.pixels.get(pid)
            if px is None or px.size == 0:
                continue
            alpha[px] = self._full_alpha[px] if pid in pend else 0
            rows, cols = px // W, px % W
            x0, y0 = min(x0, int(cols.min())), min(y0, int(rows.min()))
            x1, y1 = max(x1, int(cols.max()) + 1), max(y1, int(rows.max()) + 1)
        self.shown = pend
        return (x0, y0, x1, y1) if x1 >= 0 else None

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
        ann = session.ann
        existing = set(session.existing_ids())
        pending = set(self.pending(existing))
        groups = [int(g) for g in groups]
        members_of = {int(g): [int(m) for m in ms] for g, ms in (group_members or {}).items()}
        want = {int(i) for i in lights} | {m for g in groups for m in members_of.get(g, self.proposals.ids_in_group(g))}
        todo = sorted(want & pending)
        # One command for the whole acceptance, built with vectorised pixel work and ids handed out
        # here: a command per light (each looking up the map's ids) froze a 2048x1024 frame for seconds.
        used = existing | set(ann.groups) | set(ann.extra_ids)

        def next_id(class_id: int) -> int:
            k = 1
            while class_id * 1000 + k in used:
                k += 1
            if k >= 1000:
                raise NpsimInputError(f"class {class_id} has 999 instances already")
            used.add(class_id * 1000 + k)
            return class_id * 1000 + k

        flat = ann.instance_map.reshape(-1)
        index, values, new = [], [], []
        accepted = dict(self.accepted)
        for pid in todo:
            px = self.pixels[pid]
            free = px[flat[px] == 0]  # pixels already taken by a light stay that light's
            if free.size == 0:
                continue
            nid = next_id(class_of(pid))
            index.append(free)
            values.append(np.full(free.size, nid, np.int32))
            accepted[pid] = nid
            new.append(nid)
        if not new:
            return []
        idx = np.concatenate(index)
        order = np.argsort(idx, kind="stable")
        idx = idx[order].astype(np.int32 if flat.size < 2**31 else np.int64)
        diff = PixelDiff(idx, flat[idx].copy(), np.concatenate(values)[order])
        before = Structure.of(ann, with_meta=True)
        ids_now = existing | set(new)
        gmap = dict(ann.groups)
        touched = set(groups) | {self.group_of[p] for p in todo if p in self.group_of and
                                 accepted.get(self.group_of[p]) in gmap}
        for gid in sorted(touched):
            members = tuple(sorted({accepted[m] for m in members_of.get(gid, self.proposals.ids_in_group(gid))
                                    if accepted.get(m) in ids_now}))
            if not members:
                continue
            # as group_lights: the members leave their old groups (emptied groups go)
            gmap = {g: GroupInstance(g, rest) for g, grp in gmap.items()
                    if (rest := tuple(m for m in grp.members if m not in members))}
            ngid = next_id(class_of(gid))
            gmap[ngid] = GroupInstance(ngid, members)
            accepted[gid] = ngid
        after = Structure(tuple(gmap[k] for k in sorted(gmap)), frozenset(before.extra_ids | set(new)),
                          self._carried_meta(before, accepted, ids_now | set(gmap)))
        session.apply(EditCommand(f"accept {len(new)} proposals", diff, before, after))
        self.accepted = accepted
        self.rejected -= set(todo)
        return new

    def _carried_meta(self, before: Structure, accepted: dict[int, int], alive: set[int]):
        """``before``'s per-id meta plus the proposals' entries (a signal head's state, its lamps'
        colours, a window's kind) of the proposals accepted as ids in ``alive``, re-keyed to the
        annotation's ids: a night lights the state the proposal read from the day photo."""
        pmeta = self.proposals.annotation.meta or {}
        out = []
        for key, items in before.id_meta or ():
            d = dict(items)
            for pid, value in dict(pmeta.get(key) or {}).items():
                nid = accepted.get(int(pid))
                if nid is not None and nid in alive:
                    d[str(nid)] = str(value)
            out.append((key, tuple(sorted(d.items()))))
        return tuple(out)

    def pending_map(self, existing: set[int]) -> np.ndarray | None:
        """The proposal map with only the pending proposals' ids (0 elsewhere), None when none is pending:
        what a stroke accept passes over (``npsim_gui.editor.tools``)."""
        pend = self.pending(existing)
        if not pend:
            return None
        pmap = self.proposals.annotation.instance_map
        return np.where(np.isin(pmap, pend), pmap, 0)

    def accept_lights(self, session, lights: Iterable[int]) -> list[int]:
        """Accept the proposal ``lights`` alone, each with its proposed group restricted to the lights of
        that group accepted now or before (those still in the group it was accepted as; a stroke accept: a floor's true windows without the false mates
        of their group); one undo step. Returns the new light ids."""
        lights = {int(i) for i in lights}
        existing = session.existing_ids()
        members = {}
        for gid in {self.group_of[p] for p in lights if p in self.group_of}:
            # lights of the group accepted before count only while still in the group it was accepted as
            # (an annotator's regrouping stands)
            before = self.accepted.get(gid)
            members[gid] = [m for m in self.proposals.ids_in_group(gid) if m in lights or (
                self.accepted.get(m) in existing and before is not None
                and session.ann.group_of(self.accepted[m]) == before)]
        return self.accept(session, sorted(lights), sorted(members), group_members=members)

    def accept_above(self, session, threshold: float) -> list[int]:
        """Accept every pending proposal with confidence >= ``threshold`` (one undo step), grouped as
        the proposals' groups restricted to those lights (as ``LightProposals.above``, from the ids and
        confidences alone: no pass over the proposal map)."""
        keep = {i for i in self.light_ids if self.confidence(i) >= float(threshold)}
        pend = set(self.pending(session.existing_ids()))
        members = {gid: tuple(m for m in g.members if m in keep)
                   for gid, g in self.proposals.annotation.groups.items()}
        members = {gid: ms for gid, ms in members.items() if ms}
        groups = [gid for gid, ms in members.items() if set(ms) & pend]
        return self.accept(session, sorted(keep & pend), groups, group_members=members)
