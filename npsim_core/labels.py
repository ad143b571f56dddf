"""Semantic label tables (Cityscapes labelIds) and light-source classes.

Both tables live in ``resources/`` as JSON; this module only reads them.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .errors import NpsimInputError
from .resources import load_json_resource


@dataclass(frozen=True)
class SemanticClass:
    """One Cityscapes class: labelId, trainId (255 = ignored), RGB colour, flags."""

    id: int
    name: str
    train_id: int
    category: str
    color: tuple[int, int, int]
    foreground: bool
    ground: bool
    has_instances: bool


@dataclass(frozen=True)
class LabelTable:
    """The Cityscapes label table with lookup helpers (labelIds 0..33)."""

    classes: tuple[SemanticClass, ...]
    sky_id: int

    @property
    def ids(self) -> np.ndarray:
        return np.array([c.id for c in self.classes], dtype=np.int32)

    def by_name(self, name: str) -> SemanticClass:
        for c in self.classes:
            if c.name == name:
                return c
        raise KeyError(f"unknown Cityscapes class name {name!r}")

    def by_id(self, label_id: int) -> SemanticClass:
        for c in self.classes:
            if c.id == label_id:
                return c
        raise KeyError(f"unknown Cityscapes labelId {label_id}")

    @property
    def foreground_ids(self) -> frozenset[int]:
        """labelIds of the thesis's foreground classes (docs/method.md §1.4)."""
        return frozenset(c.id for c in self.classes if c.foreground)

    @property
    def ground_ids(self) -> frozenset[int]:
        """labelIds the pop-up prior places on the ground plane."""
        return frozenset(c.id for c in self.classes if c.ground)

    def lut(self, attribute: str, fill: int = 0) -> np.ndarray:
        """256-entry lookup table labelId -> attribute (bool/int) for vectorised use."""
        out = np.full(256, fill, dtype=np.int32)
        for c in self.classes:
            out[c.id] = int(getattr(c, attribute))
        return out

    def color_lut(self) -> np.ndarray:
        """(256, 3) uint8 RGB colour per labelId (unknown ids black)."""
        out = np.zeros((256, 3), dtype=np.uint8)
        for c in self.classes:
            out[c.id] = c.color
        return out

    def colorize(self, labels: np.ndarray) -> np.ndarray:
        """HxW labelIds -> HxWx3 uint8 RGB visualisation."""
        return self.color_lut()[np.clip(labels, 0, 255).astype(np.intp)]

    def trainid_to_labelid(self) -> np.ndarray:
        """256-entry LUT trainId -> labelId (255 -> 0 'unlabeled')."""
        out = np.zeros(256, dtype=np.uint8)
        for c in self.classes:
            if 0 <= c.train_id < 255:
                out[c.train_id] = c.id
        return out

    def validate(self, labels: np.ndarray, source: str = "labels") -> None:
        """Raise :class:`NpsimInputError` when ``labels`` holds ids not in the table."""
        present = np.unique(labels)
        known = set(int(i) for i in self.ids)
        unknown = [int(v) for v in present if int(v) not in known]
        if unknown:
            raise NpsimInputError(
                f"{source}: label values {unknown[:10]} are not Cityscapes labelIds (0..33). "
                "If the file holds trainIds, pass trainids=True (CLI: --trainids).")

    def check_not_trainids(self, labels: np.ndarray, source: str = "labels") -> None:
        """Refuse a labelIds map that looks like trainIds (docs/method.md §10.6).

        trainIds 0..18 are also valid labelIds, so a trainIds file without the 255 ignore
        value passes :meth:`validate` -- and reads road as "unlabeled" and building as
        "rectification border". A labelIds map whose ids all lie in 0..18 and a third or more
        of whose pixels are ids 0-3 (unlabeled, ego vehicle, borders: a thin band in real
        frames) is that case.
        """
        if labels.size < 64 or int(labels.max()) > 18:
            return
        if int(labels.max()) <= 3:  # nothing but unlabeled/ego/border/out of ROI: not trainIds, no labels
            ids = sorted(int(i) for i in np.unique(labels))
            raise NpsimInputError(
                f"{source}: an unlabelled frame -- every pixel is {', '.join(self.by_id(i).name for i in ids)} "
                f"(labelId{'s' if len(ids) > 1 else ''} {', '.join(map(str, ids))}), so there is no scene to "
                "reconstruct; give the frame's labelIds file (or label it)")
        frac = float(np.isin(labels, (0, 1, 2, 3)).mean())
        if frac >= 1 / 3:
            raise NpsimInputError(
                f"{source}: looks like trainIds, not labelIds ({100 * frac:.0f}% of pixels would be unlabeled, "
                "ego vehicle or border, and no id is above 18): pass --trainids (trainids=True), or convert "
                "the file to labelIds")


@lru_cache(maxsize=1)
def cityscapes() -> LabelTable:
    """The Cityscapes label table from ``resources/cityscapes_labels.json``."""
    doc = load_json_resource("cityscapes_labels.json")
    classes = tuple(
        SemanticClass(id=d["id"], name=d["name"], train_id=d["trainId"], category=d["category"],
                      color=tuple(d["color"]), foreground=d["foreground"], ground=d["ground"],
                      has_instances=d["hasInstances"])
        for d in doc["labels"])
    return LabelTable(classes=classes, sky_id=int(doc["sky_id"]))


@dataclass(frozen=True)
class LightClass:
    """One inactive-light-source class (docs/method.md §7.1): ids 1-12 lights, 13-21 groups."""

    id: int
    name: str
    kind: str  # "light" or "group"
    category: str  # building / vehicle / object / group
    color: tuple[int, int, int]

    @property
    def is_group(self) -> bool:
        return self.kind == "group"


@lru_cache(maxsize=1)
def light_classes() -> tuple[LightClass, ...]:
    """The 21 light-source classes from ``resources/light_classes.json``."""
    doc = load_json_resource("light_classes.json")
    return tuple(LightClass(id=d["id"], name=d["name"], kind=d["kind"], category=d["category"],
                            color=tuple(d["color"])) for d in doc["classes"])


def light_class(key: int | str) -> LightClass:
    """Light class by id (1..21) or name."""
    for c in light_classes():
        if c.id == key or c.name == key:
            return c
    raise KeyError(f"unknown light-source class {key!r} (ids 1..21, see resources/light_classes.json)")
