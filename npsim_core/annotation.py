"""Inactive light-source annotation: light instances, groups, and their files (SPEC §6).

Data model
----------
``instance_map`` is an HxW int32 map: 0 = no light, otherwise the id of the
light instance that owns the pixel (so a pixel belongs to at most one light).
Instance ids follow the Cityscapes convention ``classId * 1000 + index`` with
classId 1..12 for lights, so the instance PNG *is* the map. Groups (classes
13..21) have ids ``classId * 1000 + index`` too and list their member lights.

Files (``<stem>`` = scene name)
-------------------------------
``<stem>_lights_instanceIds.png`` uint16 instance map; ``<stem>_lights_classIds.png``
uint8 class map; ``<stem>_lights.json`` classes, instances (bbox, area, group),
groups (members), image size.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import NpsimInputError
from .io import read_image, read_json, write_image, write_json
from .labels import light_class, light_classes

FORMAT_NAME = "npsim-lights"
FORMAT_VERSION = 1


def class_of(instance_id: int) -> int:
    """Class id encoded in an instance or group id (``id // 1000``)."""
    return int(instance_id) // 1000


@dataclass(frozen=True)
class GroupInstance:
    """A group-class instance (class 13..21) holding light-instance ids."""

    id: int
    members: tuple[int, ...]

    @property
    def class_id(self) -> int:
        return class_of(self.id)


@dataclass
class LightAnnotation:
    """Light instances (pixels of ``instance_map``) and groups for one image."""

    instance_map: np.ndarray
    groups: dict[int, GroupInstance] = field(default_factory=dict)
    #: Ids of lights that exist even if they own no pixel yet (editor).
    extra_ids: set[int] = field(default_factory=set)

    @classmethod
    def empty(cls, height: int, width: int) -> "LightAnnotation":
        return cls(np.zeros((height, width), dtype=np.int32))

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.instance_map.shape)  # type: ignore[return-value]

    def instance_ids(self) -> list[int]:
        ids = set(int(i) for i in np.unique(self.instance_map) if i != 0) | set(self.extra_ids)
        return sorted(ids)

    def class_map(self) -> np.ndarray:
        """HxW uint8 light class id (0 = none)."""
        return (self.instance_map // 1000).astype(np.uint8)

    def mask(self, instance_id: int) -> np.ndarray:
        return self.instance_map == instance_id

    def group_of(self, instance_id: int) -> int | None:
        for g in self.groups.values():
            if instance_id in g.members:
                return g.id
        return None

    def next_id(self, class_id: int) -> int:
        """Smallest unused ``class_id*1000 + index`` (index from 1)."""
        used = set(self.instance_ids()) | set(self.groups)
        k = 1
        while class_id * 1000 + k in used:
            k += 1
        if k >= 1000:
            raise NpsimInputError(f"class {class_id} has 999 instances already")
        return class_id * 1000 + k

    def stats(self) -> dict[int, dict]:
        """Per instance: area (px) and bbox ``[x0, y0, x1, y1]`` (inclusive), vectorised."""
        m = self.instance_map
        ids, inv, counts = np.unique(m.ravel(), return_inverse=True, return_counts=True)
        H, W = m.shape
        rows = np.repeat(np.arange(H), W)
        cols = np.tile(np.arange(W), H)
        k = len(ids)
        x0 = np.full(k, W); y0 = np.full(k, H); x1 = np.full(k, -1); y1 = np.full(k, -1)
        np.minimum.at(x0, inv, cols); np.minimum.at(y0, inv, rows)
        np.maximum.at(x1, inv, cols); np.maximum.at(y1, inv, rows)
        out = {}
        for j, i in enumerate(ids):
            if i != 0:
                out[int(i)] = {"area": int(counts[j]), "bbox": [int(x0[j]), int(y0[j]), int(x1[j]), int(y1[j])]}
        for i in self.extra_ids:
            out.setdefault(int(i), {"area": 0, "bbox": None})
        return out

    def validate(self, source: str = "annotation") -> None:
        """Check class ranges and group membership; raise NpsimInputError."""
        valid_lights = {c.id for c in light_classes() if not c.is_group}
        valid_groups = {c.id for c in light_classes() if c.is_group}
        ids = self.instance_ids()
        bad = [i for i in ids if class_of(i) not in valid_lights]
        if bad:
            raise NpsimInputError(f"{source}: instance ids {bad[:5]} encode classes outside 1..12 "
                                  "(ids must be classId*1000 + index)")
        idset = set(ids)
        for g in self.groups.values():
            if g.class_id not in valid_groups:
                raise NpsimInputError(f"{source}: group {g.id} has class {g.class_id}, groups must be 13..21")
            missing = [m for m in g.members if m not in idset]
            if missing:
                raise NpsimInputError(f"{source}: group {g.id} lists members {missing[:5]} that are not lights")

    def to_json(self) -> dict:
        st = self.stats()
        H, W = self.shape
        inst = []
        for i in self.instance_ids():
            c = light_class(class_of(i))
            inst.append({"id": i, "class_id": c.id, "class_name": c.name, "area": st[i]["area"],
                         "bbox": st[i]["bbox"], "group": self.group_of(i)})
        groups = []
        for gid in sorted(self.groups):
            g = self.groups[gid]
            boxes = [st[m]["bbox"] for m in g.members if st.get(m, {}).get("bbox")]
            bbox = ([min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes),
                     max(b[3] for b in boxes)] if boxes else None)
            groups.append({"id": gid, "class_id": g.class_id, "class_name": light_class(g.class_id).name,
                           "members": list(g.members), "bbox": bbox})
        return {"format": FORMAT_NAME, "version": FORMAT_VERSION, "width": W, "height": H,
                "classes": [{"id": c.id, "name": c.name, "kind": c.kind, "category": c.category}
                            for c in light_classes()],
                "instances": inst, "groups": groups}


def annotation_paths(folder: str | Path, stem: str) -> dict[str, Path]:
    folder = Path(folder)
    return {"instance_png": folder / f"{stem}_lights_instanceIds.png",
            "class_png": folder / f"{stem}_lights_classIds.png",
            "json": folder / f"{stem}_lights.json"}


def save_annotation(ann: LightAnnotation, folder: str | Path, stem: str) -> dict[str, Path]:
    """Write the instance PNG, class PNG and JSON (each atomically)."""
    ann.validate()
    paths = annotation_paths(folder, stem)
    write_image(paths["instance_png"], ann.instance_map.astype(np.uint16))
    write_image(paths["class_png"], ann.class_map())
    write_json(paths["json"], ann.to_json())
    return paths


def load_annotation(folder: str | Path, stem: str) -> LightAnnotation:
    """Read an annotation written by :func:`save_annotation`."""
    paths = annotation_paths(folder, stem)
    doc = read_json(paths["json"])
    if doc.get("format") != FORMAT_NAME:
        raise NpsimInputError(f"{paths['json']}: not an NPSim light annotation (format {doc.get('format')!r})")
    if int(doc.get("version", 0)) > FORMAT_VERSION:
        raise NpsimInputError(f"{paths['json']}: written by a newer NPSim (format version {doc['version']} > "
                              f"{FORMAT_VERSION}); update NPSim to open it")
    raw = read_image(paths["instance_png"], color=False)
    if raw.ndim != 2:
        raise NpsimInputError(f"{paths['instance_png']}: instance PNG must be single-channel uint16")
    if raw.shape != (doc["height"], doc["width"]):
        raise NpsimInputError(f"{paths['instance_png']}: size {raw.shape[::-1]} differs from the JSON's "
                              f"{doc['width']}x{doc['height']}")
    ann = LightAnnotation(raw.astype(np.int32))
    present = set(ann.instance_ids())
    ann.extra_ids = {int(i["id"]) for i in doc.get("instances", [])} - present
    ann.groups = {int(g["id"]): GroupInstance(int(g["id"]), tuple(int(m) for m in g["members"]))
                  for g in doc.get("groups", [])}
    ann.validate(str(paths["json"]))
    return ann
