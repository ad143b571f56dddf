"""Undoable edits of a :class:`~npsim_core.annotation.LightAnnotation`.

Every edit is a small command object holding a *diff*: the flat indices of the
pixels it changes with their old and new instance ids (int32 each), plus the
group / light-set state before and after (a few small dicts). A 2048×1024
stroke therefore costs memory proportional to the pixels it touched, never a
copy of the map. Commands are built by the factory functions below (which
check the invariants and return ``None`` when nothing would change) and run
through an :class:`UndoStack`::

    stack = UndoStack(ann)
    cmd, new_id = new_instance(ann, 1)
    stack.push(cmd)
    stack.push(paint(ann, np.flatnonzero(mask), new_id))
    stack.undo(); stack.redo()

Invariants kept by every command
--------------------------------
* a pixel belongs to at most one light (the map stores one id per pixel);
  painting leaves other lights' pixels alone unless ``overwrite=True``;
* a light exists until deleted, even without pixels (it is then kept in
  ``extra_ids``), so erasing never leaves a group pointing at nothing;
* a group holds only existing lights, each light is in at most one group;
  deleting a light removes it from its group and an emptied group is removed;
* changing a class re-encodes the id (``classId*1000 + index``) and rewrites
  the pixels and the group membership that refer to it.

Each ``redo``/``undo`` returns a :class:`Change` (the touched rectangle and ids)
so a view can repaint only what changed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Protocol

import cv2
import numpy as np

from .annotation import (VEHICLE_GROUP_OF_LABEL, VEHICLE_LIGHT_CLASSES, GroupInstance, LightAnnotation, class_of,
                         is_group_class, is_light_class)
from .errors import NpsimInputError


# --------------------------------------------------------------------------- change notices
@dataclass(frozen=True)
class Change:
    """What an edit touched: ``rect`` = (x0, y0, x1, y1) half-open pixel box or None; ids touched;
    ``structure`` = the set of lights or groups changed (pixel-only edits leave it False: lights
    stay registered when they lose pixels, so the set of lights cannot change by painting)."""

    rect: tuple[int, int, int, int] | None = None
    ids: frozenset[int] = frozenset()
    structure: bool = False

    def union(self, other: "Change") -> "Change":
        if self.rect is None:
            rect = other.rect
        elif other.rect is None:
            rect = self.rect
        else:
            a, b = self.rect, other.rect
            rect = (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
        return Change(rect, self.ids | other.ids, self.structure or other.structure)


@dataclass
class PixelDiff:
    """Flat pixel indices with their old and new ids (int32)."""

    index: np.ndarray
    old: np.ndarray
    new: np.ndarray

    def apply(self, ann: LightAnnotation, forward: bool) -> None:
        ann.instance_map.reshape(-1)[self.index] = self.new if forward else self.old

    def rect(self, width: int) -> tuple[int, int, int, int]:
        rows, cols = self.index // width, self.index % width
        return int(cols.min()), int(rows.min()), int(cols.max()) + 1, int(rows.max()) + 1

    def ids(self) -> frozenset[int]:
        return frozenset(int(i) for i in np.union1d(np.unique(self.old), np.unique(self.new)) if i != 0)

    @property
    def nbytes(self) -> int:
        return self.index.nbytes + self.old.nbytes + self.new.nbytes


#: ``LightAnnotation.meta`` entries keyed by light or group id (``str(id)``): a signal lamp's colour, a
#: signal head's state and direction, a window's kind (docs/proposals.md). Commands that create lights
#: from another annotation (accepting proposals) carry them in their :class:`Structure`.
ID_META_KEYS = ("lamp_colours", "traffic_light_states", "traffic_light_direction", "light_kinds")


@dataclass(frozen=True)
class Structure:
    """Groups and registered lights at one moment (small; copied per command), and optionally the
    per-id meta entries (:data:`ID_META_KEYS`) as ``((key, ((id, value), ...)), ...)``; ``None``
    leaves the annotation's meta alone (every command but an acceptance of proposals)."""

    groups: tuple[GroupInstance, ...]
    extra_ids: frozenset[int]
    id_meta: tuple[tuple[str, tuple[tuple[str, str], ...]], ...] | None = None

    @classmethod
    def of(cls, ann: LightAnnotation, *, with_meta: bool = False) -> "Structure":
        meta = None
        if with_meta:
            meta = tuple((k, tuple(sorted((str(i), str(v)) for i, v in dict(ann.meta.get(k) or {}).items())))
                         for k in ID_META_KEYS)
        return cls(tuple(ann.groups[g] for g in sorted(ann.groups)), frozenset(ann.extra_ids), meta)

    def apply(self, ann: LightAnnotation) -> None:
        ann.groups = {g.id: g for g in self.groups}
        ann.extra_ids = set(self.extra_ids)
        if self.id_meta is not None:
            for key, items in self.id_meta:
                if items:
                    ann.meta[key] = dict(items)
                else:
                    ann.meta.pop(key, None)

    def ids(self) -> frozenset[int]:
        out = set(self.extra_ids)
        for g in self.groups:
            out.add(g.id)
            out.update(g.members)
        return frozenset(out)


class Command(Protocol):
    text: str

    def redo(self, ann: LightAnnotation) -> Change: ...

    def undo(self, ann: LightAnnotation) -> Change: ...


@dataclass
class EditCommand:
    """One edit: an optional pixel diff plus the structure before and after."""

    text: str
    diff: PixelDiff | None
    before: Structure
    after: Structure

    def _change(self, ann: LightAnnotation) -> Change:
        rect = self.diff.rect(ann.shape[1]) if self.diff is not None else None
        ids = self.diff.ids() if self.diff is not None else frozenset()
        structure = self.before != self.after
        if structure:
            ids = ids | (self.before.ids() ^ self.after.ids()) | _changed_group_ids(self.before, self.after)
        return Change(rect, ids, structure)

    def redo(self, ann: LightAnnotation) -> Change:
        if self.diff is not None:
            self.diff.apply(ann, True)
        self.after.apply(ann)
        return self._change(ann)

    def undo(self, ann: LightAnnotation) -> Change:
        if self.diff is not None:
            self.diff.apply(ann, False)
        self.before.apply(ann)
        return self._change(ann)


def _changed_group_ids(a: Structure, b: Structure) -> frozenset[int]:
    ga, gb = {g.id: g for g in a.groups}, {g.id: g for g in b.groups}
    out = set()
    for gid in set(ga) | set(gb):
        if ga.get(gid) != gb.get(gid):
            out.add(gid)
            for g in (ga.get(gid), gb.get(gid)):
                if g is not None:
                    out.update(g.members)
    return frozenset(out)


@dataclass
class MacroCommand:
    """Several commands undone and redone as one (e.g. one mouse drag)."""

    text: str
    commands: list = field(default_factory=list)

    def redo(self, ann: LightAnnotation) -> Change:
        ch = Change()
        for c in self.commands:
            ch = ch.union(c.redo(ann))
        return ch

    def undo(self, ann: LightAnnotation) -> Change:
        ch = Change()
        for c in reversed(self.commands):
            ch = ch.union(c.undo(ann))
        return ch


class UndoStack:
    """Linear undo/redo history over one annotation, with a 'clean' (saved) marker."""

    def __init__(self, ann: LightAnnotation, limit: int = 1000) -> None:
        self.ann = ann
        self.limit = limit
        self._done: list = []
        self._undone: list = []
        self._clean_depth: int | None = 0
        self._dropped = 0

    def push(self, cmd, *, applied: bool = False) -> Change:
        """Run ``cmd`` (unless ``applied``) and record it; ``None`` commands are ignored."""
        if cmd is None:
            return Change()
        ch = Change() if applied else cmd.redo(self.ann)
        self._done.append(cmd)
        if self._clean_depth is not None and self._clean_depth > len(self._done) - 1:
            self._clean_depth = None  # the saved state was in the discarded redo branch
        self._undone.clear()
        if len(self._done) > self.limit:
            self._done.pop(0)
            self._dropped += 1
            if self._clean_depth is not None:
                self._clean_depth -= 1
                if self._clean_depth < 0:
                    self._clean_depth = None
        return ch

    def undo(self) -> Change | None:
        if not self._done:
            return None
        cmd = self._done.pop()
        self._undone.append(cmd)
        return cmd.undo(self.ann)

    def redo(self) -> Change | None:
        if not self._undone:
            return None
        cmd = self._undone.pop()
        self._done.append(cmd)
        return cmd.redo(self.ann)

    @property
    def can_undo(self) -> bool:
        return bool(self._done)

    @property
    def can_redo(self) -> bool:
        return bool(self._undone)

    def undo_text(self) -> str:
        return self._done[-1].text if self._done else ""

    def redo_text(self) -> str:
        return self._undone[-1].text if self._undone else ""

    def __len__(self) -> int:
        return len(self._done)

    def mark_clean(self) -> None:
        self._clean_depth = len(self._done)

    @property
    def is_clean(self) -> bool:
        return self._clean_depth == len(self._done)

    def clear(self) -> None:
        self._done.clear()
        self._undone.clear()
        self._clean_depth = 0


# --------------------------------------------------------------------------- helpers
def _flat_index(ann: LightAnnotation, index) -> np.ndarray:
    idx = np.asarray(index)
    if idx.dtype == bool:
        if idx.shape != ann.shape:
            raise NpsimInputError(f"mask shape {idx.shape} differs from the annotation's {ann.shape}")
        return np.flatnonzero(idx).astype(np.int32)
    idx = np.unique(idx.astype(np.int64).ravel())
    n = ann.instance_map.size
    if idx.size and (idx[0] < 0 or idx[-1] >= n):
        raise NpsimInputError(f"pixel indices must lie in 0..{n - 1}")
    return idx.astype(np.int32) if n < 2**31 else idx


def _diff(ann: LightAnnotation, idx: np.ndarray, new) -> PixelDiff | None:
    flat = ann.instance_map.reshape(-1)
    old = flat[idx]
    new_arr = np.broadcast_to(np.asarray(new, dtype=np.int32), old.shape)
    keep = old != new_arr
    if not keep.any():
        return None
    return PixelDiff(idx[keep], old[keep].copy(), np.ascontiguousarray(new_arr[keep]))


def _require_light(ann: LightAnnotation, iid: int) -> None:
    if not is_light_class(class_of(iid)) or iid % 1000 == 0:
        raise NpsimInputError(f"{iid} is not a light id (classId 1..12 * 1000 + index)")


def _exists(ann: LightAnnotation, iid: int) -> bool:
    return iid in ann.extra_ids or bool((ann.instance_map == iid).any())


def _without_members(groups: dict[int, GroupInstance], remove: set[int]) -> dict[int, GroupInstance]:
    """Groups with ``remove`` taken out of their members; emptied groups dropped."""
    out = {}
    for gid, g in groups.items():
        members = tuple(m for m in g.members if m not in remove)
        if members:
            out[gid] = GroupInstance(gid, members)
    return out


def _pixel_command(ann: LightAnnotation, text: str, diff: PixelDiff | None, register: set[int]) -> EditCommand | None:
    if diff is None:
        return None
    before = Structure.of(ann)
    # Every light that loses pixels stays registered so it survives losing all of them.
    lost = set(int(i) for i in np.unique(diff.old) if i != 0)
    after = Structure(before.groups, frozenset(ann.extra_ids | lost | register))
    return EditCommand(text, diff, before, after)


# --------------------------------------------------------------------------- command factories
def paint(ann: LightAnnotation, index, instance_id: int, *, overwrite: bool = False,
          text: str = "paint") -> EditCommand | None:
    """Give pixels (flat indices or an HxW bool mask) to light ``instance_id``.

    Pixels of other lights are kept unless ``overwrite``. Returns None when nothing changes.
    """
    _require_light(ann, instance_id)
    idx = _flat_index(ann, index)
    if not overwrite:
        cur = ann.instance_map.reshape(-1)[idx]
        idx = idx[(cur == 0) | (cur == instance_id)]
    return _pixel_command(ann, text, _diff(ann, idx, instance_id), {instance_id})


def erase(ann: LightAnnotation, index, instance_id: int | None = None, *, text: str = "erase") -> EditCommand | None:
    """Clear pixels (of ``instance_id`` only, when given). The lights themselves remain."""
    idx = _flat_index(ann, index)
    cur = ann.instance_map.reshape(-1)[idx]
    idx = idx[(cur != 0) if instance_id is None else (cur == instance_id)]
    return _pixel_command(ann, text, _diff(ann, idx, 0), set())


def new_instance(ann: LightAnnotation, class_id: int) -> tuple[EditCommand, int]:
    """A new, empty light of ``class_id`` (1..12). Returns the command and its id."""
    if not is_light_class(class_id):
        raise NpsimInputError(f"class {class_id} is not a light class (1..12)")
    iid = ann.next_id(class_id)
    before = Structure.of(ann)
    after = Structure(before.groups, before.extra_ids | {iid})
    return EditCommand(f"new {iid}", None, before, after), iid


def split_paint(ann: LightAnnotation, index, class_id: int, *, overwrite: bool = False, connectivity: int = 4,
                min_area: int = 1) -> tuple[EditCommand | None, list[int]]:
    """Make one new light of ``class_id`` per connected region of the given pixels.

    This is how a drag across a row of windows becomes one instance per window.
    Regions smaller than ``min_area`` pixels are ignored.
    """
    if not is_light_class(class_id):
        raise NpsimInputError(f"class {class_id} is not a light class (1..12)")
    idx = _flat_index(ann, index)
    if not overwrite:
        idx = idx[ann.instance_map.reshape(-1)[idx] == 0]
    if idx.size == 0:
        return None, []
    H, W = ann.shape
    rows, cols = idx // W, idx % W
    y0, x0 = int(rows.min()), int(cols.min())
    crop = np.zeros((int(rows.max()) - y0 + 1, int(cols.max()) - x0 + 1), np.uint8)
    crop[rows - y0, cols - x0] = 1
    n, comp = cv2.connectedComponents(crop, connectivity=connectivity)
    lab = comp[rows - y0, cols - x0]
    areas = np.bincount(lab, minlength=n)
    # Order regions left-to-right, top-to-bottom so ids follow reading order.
    firsts = np.full(n, np.iinfo(np.int64).max)
    np.minimum.at(firsts, lab, cols.astype(np.int64) * H + rows)
    order = [k for k in np.argsort(firsts) if k != 0 and areas[k] >= min_area]
    if not order:
        return None, []
    new_vals = np.zeros(idx.size, np.int32)
    ids: list[int] = []
    reserved: set[int] = set()
    for k in order:
        iid = ann.next_id(class_id, reserved)
        reserved.add(iid)
        ids.append(iid)
        new_vals[lab == k] = iid
    keep = new_vals != 0
    diff = _diff(ann, idx[keep], new_vals[keep])
    cmd = _pixel_command(ann, f"paint {len(ids)} regions", diff, set(ids))
    return cmd, ids


def change_class(ann: LightAnnotation, instance_id: int, new_class: int) -> tuple[EditCommand | None, int]:
    """Re-class a light (1..12) or a group (13..21): the id is re-encoded, pixels and
    group memberships follow. Returns the command and the new id."""
    old_class = class_of(instance_id)
    if old_class == new_class:
        return None, instance_id
    before = Structure.of(ann)
    if instance_id in ann.groups:
        if not is_group_class(new_class):
            raise NpsimInputError(f"a group can only become another group class (13..21), not {new_class}")
        gid = ann.next_id(new_class)
        groups = dict(ann.groups)
        g = groups.pop(instance_id)
        groups[gid] = GroupInstance(gid, g.members)
        after = Structure(tuple(groups[k] for k in sorted(groups)), before.extra_ids)
        return EditCommand(f"class {instance_id} -> {gid}", None, before, after), gid
    _require_light(ann, instance_id)
    if not is_light_class(new_class):
        raise NpsimInputError(f"a light can only become another light class (1..12), not {new_class}")
    if not _exists(ann, instance_id):
        raise NpsimInputError(f"light {instance_id} does not exist")
    nid = ann.next_id(new_class)
    idx = np.flatnonzero(ann.instance_map.reshape(-1) == instance_id).astype(np.int32)
    diff = _diff(ann, idx, nid) if idx.size else None
    groups = {gid: GroupInstance(gid, tuple(nid if m == instance_id else m for m in g.members))
              for gid, g in ann.groups.items()}
    after = Structure(tuple(groups[k] for k in sorted(groups)), (before.extra_ids - {instance_id}) | {nid})
    return EditCommand(f"class {instance_id} -> {nid}", diff, before, after), nid


def delete_instance(ann: LightAnnotation, instance_id: int) -> EditCommand | None:
    """Delete a light (its pixels cleared, removed from its group, emptied groups removed)
    or a group (its lights stay)."""
    before = Structure.of(ann)
    if instance_id in ann.groups:
        groups = {k: g for k, g in ann.groups.items() if k != instance_id}
        return EditCommand(f"delete group {instance_id}", None, before,
                           Structure(tuple(groups[k] for k in sorted(groups)), before.extra_ids))
    if not _exists(ann, instance_id):
        return None
    idx = np.flatnonzero(ann.instance_map.reshape(-1) == instance_id).astype(np.int32)
    diff = _diff(ann, idx, 0) if idx.size else None
    groups = _without_members(ann.groups, {instance_id})
    after = Structure(tuple(groups[k] for k in sorted(groups)), before.extra_ids - {instance_id})
    return EditCommand(f"delete {instance_id}", diff, before, after)


def group_lights(ann: LightAnnotation, members: Iterable[int], group_class: int) -> tuple[EditCommand, int]:
    """Group existing lights as a new instance of ``group_class`` (13..21).

    Lights already in another group move to the new one (emptied groups are removed).
    """
    if not is_group_class(group_class):
        raise NpsimInputError(f"class {group_class} is not a group class (13..21)")
    mem = tuple(sorted(set(int(m) for m in members)))
    if not mem:
        raise NpsimInputError("select at least one light to group")
    existing = set(ann.instance_ids())
    bad = [m for m in mem if m not in existing or not is_light_class(class_of(m))]
    if bad:
        raise NpsimInputError(f"only existing lights can be grouped; {bad[:5]} are not")
    before = Structure.of(ann)
    gid = ann.next_id(group_class)
    groups = _without_members(ann.groups, set(mem))
    groups[gid] = GroupInstance(gid, mem)
    after = Structure(tuple(groups[k] for k in sorted(groups)), before.extra_ids)
    return EditCommand(f"group {gid}", None, before, after), gid


def ungroup(ann: LightAnnotation, group_id: int) -> EditCommand | None:
    """Remove a group; its lights remain."""
    if group_id not in ann.groups:
        return None
    return delete_instance(ann, group_id)


def snap_to_superpixels(ann: LightAnnotation, instance_id: int, labels: np.ndarray, *, threshold: float = 0.5,
                        overwrite: bool = False) -> EditCommand | None:
    """Fill-to-superpixel: a light covering at least ``threshold`` of a superpixel gets all of
    it (free pixels only unless ``overwrite``); its pixels in superpixels it covers less are cleared.

    Turns a rough brush stroke into a clean, edge-following mask.
    """
    _require_light(ann, instance_id)
    lab = np.asarray(labels)
    if lab.shape != ann.shape:
        raise NpsimInputError(f"superpixel labels {lab.shape} differ from the annotation's {ann.shape}")
    flat_lab = lab.reshape(-1).astype(np.int64)
    flat = ann.instance_map.reshape(-1)
    own = flat == instance_id
    n = int(flat_lab.max()) + 1
    total = np.bincount(flat_lab, minlength=n)
    mine = np.bincount(flat_lab[own], minlength=n)
    full = (mine > 0) & (mine >= threshold * total)
    target = full[flat_lab]
    grow = target & ~own & ((flat == 0) | overwrite)
    shrink = own & ~target
    idx = np.flatnonzero(grow | shrink).astype(np.int32)
    new = np.where(grow[idx], instance_id, 0).astype(np.int32)
    return _pixel_command(ann, f"snap {instance_id}", _diff(ann, idx, new), {instance_id})


def vehicle_of(instance_map: np.ndarray, instances: np.ndarray, light_id: int) -> int:
    """The vehicle holding light ``light_id``: the Cityscapes instance id (``labelId * 1000 + k``, a label of
    :data:`~npsim_core.annotation.VEHICLE_GROUP_OF_LABEL`) under at least half of its pixels, else 0."""
    px = instance_map == int(light_id)
    if not px.any():
        return 0
    ids, counts = np.unique(instances[px], return_counts=True)
    k = int(np.argmax(counts))
    inst = int(ids[k])
    if 2 * counts[k] < px.sum() or inst < 1000 or inst // 1000 not in VEHICLE_GROUP_OF_LABEL:
        return 0
    return inst


def vehicle_grouping(ann: LightAnnotation, instances: np.ndarray,
                     light_id: int) -> tuple[int | None, tuple[int, ...], int] | None:
    """Where a vehicle light just drawn goes: ``(group, members, group_class)`` -- ``members`` (the light and
    its vehicle's ungrouped lights) join ``group`` (the one group its vehicle's other lights are in), or, when
    ``group`` is None, are grouped anew as ``group_class`` (the vehicle's: :data:`VEHICLE_GROUP_OF_LABEL`).
    None when the light is no vehicle light, lies on no vehicle instance (``instances``: Cityscapes
    instanceIds, HxW), or its vehicle's other lights are split over several groups (the annotator decides).

    Every light of a vehicle belongs to that vehicle's group (one car = one car_group, docs/annotation.md),
    so the editor can group a light drawn on a car without a gesture: the Ctrl+G per car drawn."""
    if class_of(light_id) not in VEHICLE_LIGHT_CLASSES or instances is None or instances.shape != ann.shape:
        return None
    inst = vehicle_of(ann.instance_map, instances, light_id)
    if not inst:
        return None
    on = ann.instance_map[instances == inst]
    counts = np.bincount(on[on > 0]) if on.size else np.zeros(1, np.int64)
    areas = ann.areas()
    mates = [int(i) for i in np.flatnonzero(counts) if int(i) != int(light_id)
             and class_of(int(i)) in VEHICLE_LIGHT_CLASSES and 2 * counts[i] >= areas.get(int(i), 0)]
    groups = {ann.group_of(m) for m in mates}
    if len(groups - {None}) > 1:
        return None
    gid = next(iter(groups - {None}), None)
    members = tuple(sorted([m for m in mates if ann.group_of(m) is None] + [int(light_id)]))
    return gid, members, class_of(gid) if gid is not None else VEHICLE_GROUP_OF_LABEL[inst // 1000]
