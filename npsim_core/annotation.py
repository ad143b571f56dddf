"""Inactive light-source annotation: light instances, groups, and their files (docs/method.md §7, docs/annotation.md).

Data model
----------
``instance_map`` is an HxW int32 map: 0 = no light, otherwise the id of the
light instance that owns the pixel (so a pixel belongs to at most one light).
Instance ids follow the Cityscapes convention ``classId * 1000 + index`` with
classId 1..12 for lights, so the instance PNG *is* the map. Groups (classes
13..21) have ids ``classId * 1000 + index`` too and list their member lights.
A light exists until it is deleted, even when it owns no pixel (``extra_ids``),
so erasing every pixel of a grouped light never breaks its group.
``meta`` holds per-image metadata (``done`` flag, image checksum, notes,
superpixel settings); it is saved in the JSON.

Files (``<stem>`` = scene or image name)
----------------------------------------
``<stem>_lights_instanceIds.png``  uint16 instance map (classId*1000 + index)
``<stem>_lights_classIds.png``     uint8 class map (0 = none)
``<stem>_lights.json``             format name + version, image size, classes,
                                   instances (bbox ``[x0, y0, x1, y1]`` inclusive,
                                   area, group), groups (members, bbox), checksums
                                   (sha256 of the image pixels and of the instance
                                   map), meta
``<stem>_lights_coco.json``        COCO-style annotations with RLE masks

All files of one save are written to temporary files first and renamed into
place only when every one of them was written, so a failed save leaves the
previous files untouched. Loading checks the format version (a newer version is
refused) and the instance-map checksum (a PNG that does not belong to its JSON
is refused), raising :class:`NpsimInputError` without modifying anything.

Recovery
--------
The editor autosaves to ``.<stem>_lights.autosave.npz`` (:func:`autosave_path`)
next to the annotation; the file is removed after a real save or a deliberate
discard, so its presence when opening an image means the last session ended
without saving (crash) and its content can be restored.
"""

from __future__ import annotations

import hashlib
import json
import re
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from pycocotools import mask as coco_mask

from .errors import NpsimInputError
from .io import atomic_path, read_image, read_json
from .labels import light_class, light_classes

FORMAT_NAME = "npsim-lights"
FORMAT_VERSION = 1
COCO_FORMAT_NAME = "npsim-lights-coco"
RECOVERY_FORMAT_NAME = "npsim-lights-autosave"


def class_of(instance_id: int) -> int:
    """Class id encoded in an instance or group id (``id // 1000``)."""
    return int(instance_id) // 1000


def is_light_class(class_id: int) -> bool:
    return 1 <= int(class_id) <= 12


def is_group_class(class_id: int) -> bool:
    return 13 <= int(class_id) <= 21


#: The group class a light class naturally belongs to (editor's default for Ctrl+G).
#: The group class a light of each class goes into by default (docs/annotation.md "Selecting and grouping"):
#: windows -> windows_group, vehicle lamps and panes -> car_group, transport windows -> bus_group; street
#: lights, advertisements, clocks and inferred lights are not grouped by default (None).
DEFAULT_GROUP_FOR_LIGHT: dict[int, int | None] = {1: 13, 2: 14, 3: 14, 4: 14, 5: 14, 6: 14, 7: 16,
                                                  8: None, 9: None, 10: None, 11: None, 12: None}

#: Cityscapes label id of a vehicle (its ``instanceIds`` are ``labelId * 1000 + k``) -> the group class of its
#: lights: car (and caravan) -> car_group, truck (and trailer) -> truck_group, bus, train, motorcycle, bicycle.
VEHICLE_GROUP_OF_LABEL: dict[int, int] = {26: 14, 29: 14, 27: 15, 30: 15, 28: 16, 31: 19, 32: 18, 33: 17}
#: Light classes that belong to a vehicle (its windows and lamps).
VEHICLE_LIGHT_CLASSES = frozenset({2, 3, 4, 5, 6, 7})


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
    #: Per-image metadata saved in the JSON (``done``, ``image_sha256``, ``notes``...).
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        m = np.asarray(self.instance_map)
        if m.ndim != 2:
            raise NpsimInputError(f"instance_map must be HxW, got shape {m.shape}")
        # C-contiguous int32 so edits can use a flat view (pixel diffs by flat index).
        self.instance_map = np.ascontiguousarray(m, dtype=np.int32)

    @classmethod
    def empty(cls, height: int, width: int) -> "LightAnnotation":
        return cls(np.zeros((height, width), dtype=np.int32))

    def copy(self) -> "LightAnnotation":
        return LightAnnotation(self.instance_map.copy(), dict(self.groups), set(self.extra_ids),
                               json.loads(json.dumps(self.meta)))

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.instance_map.shape)  # type: ignore[return-value]

    def instance_ids(self) -> list[int]:
        present = np.flatnonzero(np.bincount(self.instance_map.ravel()))
        ids = set(int(i) for i in present if i != 0) | set(int(i) for i in self.extra_ids)
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

    def group_index(self) -> dict[int, int]:
        """Light id -> id of the group holding it."""
        return {m: g.id for g in self.groups.values() for m in g.members}

    def next_id(self, class_id: int, reserved: set[int] | None = None) -> int:
        """Smallest unused ``class_id*1000 + index`` (index from 1)."""
        used = set(self.instance_ids()) | set(self.groups) | set(reserved or ())
        k = 1
        while class_id * 1000 + k in used:
            k += 1
        if k >= 1000:
            raise NpsimInputError(f"class {class_id} has 999 instances already")
        return class_id * 1000 + k

    def areas(self) -> dict[int, int]:
        """Pixel count per light id (0 for lights without pixels)."""
        counts = np.bincount(self.instance_map.ravel())
        out = {int(i): int(counts[i]) for i in np.flatnonzero(counts) if i != 0}
        for i in self.extra_ids:
            out.setdefault(int(i), 0)
        return out

    def stats(self) -> dict[int, dict]:
        """Per instance: area (px) and bbox ``[x0, y0, x1, y1]`` (inclusive), vectorised.

        Works on the lit pixels only (sorted by id), so it is cheap on large,
        mostly empty maps.
        """
        m = self.instance_map
        W = m.shape[1]
        idx = np.flatnonzero(m)
        out: dict[int, dict] = {}
        if idx.size:
            vals = m.ravel()[idx]
            order = np.argsort(vals, kind="stable")
            vals, idx = vals[order], idx[order]
            starts = np.flatnonzero(np.r_[True, vals[1:] != vals[:-1]])
            rows, cols = idx // W, idx % W
            x0 = np.minimum.reduceat(cols, starts); x1 = np.maximum.reduceat(cols, starts)
            y0 = np.minimum.reduceat(rows, starts); y1 = np.maximum.reduceat(rows, starts)
            counts = np.diff(np.r_[starts, vals.size])
            for j, s in enumerate(starts):
                out[int(vals[s])] = {"area": int(counts[j]),
                                     "bbox": [int(x0[j]), int(y0[j]), int(x1[j]), int(y1[j])]}
        for i in self.extra_ids:
            out.setdefault(int(i), {"area": 0, "bbox": None})
        return out

    def group_bbox(self, group_id: int, stats: dict[int, dict] | None = None) -> list[int] | None:
        """Union of the members' boxes ``[x0, y0, x1, y1]`` (None when no member has pixels)."""
        st = stats if stats is not None else self.stats()
        boxes = [st[m]["bbox"] for m in self.groups[group_id].members if st.get(m, {}).get("bbox")]
        if not boxes:
            return None
        return [min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes),
                max(b[3] for b in boxes)]

    def validate(self, source: str = "annotation") -> None:
        """Check class ranges and group membership; raise NpsimInputError."""
        valid_lights = {c.id for c in light_classes() if not c.is_group}
        valid_groups = {c.id for c in light_classes() if c.is_group}
        ids = self.instance_ids()
        if self.instance_map.min(initial=0) < 0 or self.instance_map.max(initial=0) > 65535:
            raise NpsimInputError(f"{source}: instance ids must lie in 0..65535 (uint16 PNG)")
        bad = [i for i in ids if class_of(i) not in valid_lights or i % 1000 == 0]
        if bad:
            raise NpsimInputError(f"{source}: instance ids {bad[:5]} encode classes outside 1..12 "
                                  "(ids must be classId*1000 + index, index 1..999)")
        idset = set(ids)
        seen: dict[int, int] = {}
        for g in self.groups.values():
            if g.class_id not in valid_groups or g.id % 1000 == 0:
                raise NpsimInputError(f"{source}: group {g.id} has class {g.class_id}, groups must be 13..21")
            missing = [m for m in g.members if m not in idset]
            if missing:
                raise NpsimInputError(f"{source}: group {g.id} lists members {missing[:5]} that are not lights")
            for m in g.members:
                if m in seen:
                    raise NpsimInputError(f"{source}: light {m} is in two groups ({seen[m]} and {g.id})")
                seen[m] = g.id

    def to_json(self, image_sha256: str | None = None) -> dict:
        st = self.stats()
        H, W = self.shape
        inst = []
        group_of = self.group_index()
        for i in self.instance_ids():
            c = light_class(class_of(i))
            inst.append({"id": i, "class_id": c.id, "class_name": c.name, "area": st[i]["area"],
                         "bbox": st[i]["bbox"], "group": group_of.get(i)})
        groups = []
        for gid in sorted(self.groups):
            g = self.groups[gid]
            groups.append({"id": gid, "class_id": g.class_id, "class_name": light_class(g.class_id).name,
                           "members": list(g.members), "bbox": self.group_bbox(gid, st)})
        meta = dict(self.meta)
        img_sum = image_sha256 or meta.get("image_sha256")
        return {"format": FORMAT_NAME, "version": FORMAT_VERSION, "width": W, "height": H,
                "image_sha256": img_sum, "instance_map_sha256": map_checksum(self.instance_map),
                "classes": [{"id": c.id, "name": c.name, "kind": c.kind, "category": c.category}
                            for c in light_classes()],
                "instances": inst, "groups": groups, "meta": meta}


# --------------------------------------------------------------------------- checksums
def image_checksum(image: np.ndarray) -> str:
    """sha256 of an array's pixels, its shape and dtype (hex)."""
    a = np.ascontiguousarray(image)
    h = hashlib.sha256(f"{a.shape}|{a.dtype.str}|".encode())
    h.update(memoryview(a).cast("B"))
    return h.hexdigest()


def map_checksum(instance_map: np.ndarray) -> str:
    """sha256 of the instance map as the uint16 values the PNG stores."""
    return image_checksum(np.asarray(instance_map).astype("<u2"))


# --------------------------------------------------------------------------- COCO RLE
# Runs are column-major and start with a run of zeros (COCO's convention). pycocotools does the
# compressed-string coding and the decoding; only the sparse encoder below is ours, because building
# a full-image mask per light for ``pycocotools.mask.encode`` is ~5x slower on a 2048x1024 export of
# small lights (tests/test_annotation.py checks it against pycocotools).
def rle_from_indices(index: np.ndarray, total: int) -> list[int]:
    """COCO run lengths from the sorted column-major flat indices of a mask's pixels.

    ``index = flatnonzero(mask.ravel(order="F"))`` gives the counts of
    ``pycocotools.mask.encode(mask)``, but this costs O(pixels in the mask), not
    O(image), so exporting hundreds of small lights from a 2048x1024 map stays fast.
    """
    idx = np.asarray(index, dtype=np.int64)
    if idx.size == 0:
        return [int(total)] if total else []
    brk = np.flatnonzero(np.diff(idx) != 1)
    starts = idx[np.r_[0, brk + 1]]
    ends = idx[np.r_[brk, idx.size - 1]] + 1
    zeros = np.r_[starts[0], starts[1:] - ends[:-1]]
    out = np.empty(2 * starts.size, np.int64)
    out[0::2] = zeros
    out[1::2] = ends - starts
    counts = out.tolist()
    if ends[-1] < total:
        counts.append(int(total - ends[-1]))
    return counts


def rle_encode(mask: np.ndarray) -> list[int]:
    """COCO run lengths (uncompressed ``counts``) of a binary HxW mask."""
    m = np.asarray(mask, dtype=bool)
    return rle_from_indices(np.flatnonzero(m.ravel(order="F")), m.size)


def _column_major_pixels(ann: "LightAnnotation") -> dict[int, np.ndarray]:
    """Sorted column-major flat indices of every light's pixels (one sort over the lit pixels)."""
    m = ann.instance_map
    H, W = m.shape
    rows, cols = np.nonzero(m)
    if rows.size == 0:
        return {}
    vals = m[rows, cols].astype(np.int64)
    fidx = cols.astype(np.int64) * H + rows
    order = np.lexsort((fidx, vals))
    vals, fidx = vals[order], fidx[order]
    starts = np.flatnonzero(np.r_[True, vals[1:] != vals[:-1]])
    ends = np.r_[starts[1:], vals.size]
    return {int(vals[a]): fidx[a:b] for a, b in zip(starts, ends)}


def rle_to_string(counts: list[int]) -> str:
    """COCO's compressed RLE string of uncompressed ``counts`` (pycocotools' coding)."""
    counts = [int(c) for c in counts]
    if not counts:
        return ""
    total = sum(counts)
    return coco_mask.frPyObjects({"size": [1, total], "counts": counts}, 1, total)["counts"].decode("ascii")


def rle_decode(counts: list[int] | str | bytes, height: int, width: int) -> np.ndarray:
    """COCO RLE ``counts`` (a list of run lengths or the compressed string) -> HxW bool.

    Malformed input raises :class:`NpsimInputError`: runs that do not cover the
    image exactly, and strings that are truncated or not the canonical encoding
    of an HxW mask (pycocotools itself pads short runs with zeros).
    """
    H, W = int(height), int(width)
    if isinstance(counts, (str, bytes)):
        try:
            raw = counts.encode("ascii") if isinstance(counts, str) else bytes(counts)
        except UnicodeEncodeError:
            raise NpsimInputError("compressed RLE string has non-ASCII characters") from None
        code = np.frombuffer(raw, np.uint8).astype(np.int16) - 48
        if code.size and (code.min() < 0 or code.max() > 63):
            raise NpsimInputError("compressed RLE string has characters outside COCO's alphabet")
        if code.size and code[-1] & 0x20:
            raise NpsimInputError("compressed RLE string ends inside a number")
        rle = {"size": [H, W], "counts": raw}
    else:
        c = np.asarray(counts, dtype=np.int64).ravel()
        if c.size and (c.min() < 0 or c.sum() != H * W):
            raise NpsimInputError(f"RLE counts sum to {int(c.sum())}, expected {H}x{W}={H * W}")
        if c.size == 0 or H * W == 0:
            return np.zeros((H, W), dtype=bool)
        rle = coco_mask.frPyObjects({"size": [H, W], "counts": c.tolist()}, H, W)
        raw = None
    if H * W == 0:
        return np.zeros((H, W), dtype=bool)
    try:
        mask = coco_mask.decode(rle)
    except ValueError as exc:  # runs past the end of the image
        raise NpsimInputError(f"compressed RLE string does not fit {H}x{W} ({exc})") from None
    if raw is not None and raw and coco_mask.encode(mask)["counts"] != raw:
        raise NpsimInputError(f"compressed RLE string is not an exact {H}x{W} mask")
    return cv2.transpose(mask.T).view(bool)  # C-ordered HxW; cv2's blocked transpose is ~15x numpy's copy


def to_coco(ann: LightAnnotation, *, file_name: str = "", image_id: int = 1, compressed: bool = True) -> dict:
    """COCO-style document: one annotation per light (RLE mask) and per group (union mask, members)."""
    H, W = ann.shape
    st = ann.stats()
    pix = _column_major_pixels(ann)
    empty = np.zeros(0, np.int64)

    def seg(index: np.ndarray) -> dict:
        counts = rle_from_indices(index, H * W)
        return {"size": [H, W], "counts": rle_to_string(counts) if compressed else counts}

    def coco_box(b):  # COCO bbox is [x, y, w, h]
        return [b[0], b[1], b[2] - b[0] + 1, b[3] - b[1] + 1] if b else [0, 0, 0, 0]

    anns = []
    group_of = ann.group_index()
    for i in ann.instance_ids():
        anns.append({"id": i, "image_id": image_id, "category_id": class_of(i), "iscrowd": 0,
                     "area": st[i]["area"], "bbox": coco_box(st[i]["bbox"]),
                     "segmentation": seg(pix.get(i, empty)), "group": group_of.get(i)})
    for gid in sorted(ann.groups):
        g = ann.groups[gid]
        idx = np.sort(np.concatenate([pix.get(m, empty) for m in g.members] + [empty]))
        anns.append({"id": gid, "image_id": image_id, "category_id": g.class_id, "iscrowd": 0,
                     "area": int(idx.size), "bbox": coco_box(ann.group_bbox(gid, st)),
                     "segmentation": seg(idx), "members": list(g.members)})
    return {"info": {"format": COCO_FORMAT_NAME, "version": FORMAT_VERSION},
            "images": [{"id": image_id, "file_name": file_name, "width": W, "height": H}],
            "categories": [{"id": c.id, "name": c.name, "supercategory": c.category} for c in light_classes()],
            "annotations": anns}


def from_coco(doc: dict, source: str = "COCO JSON") -> LightAnnotation:
    """Rebuild a :class:`LightAnnotation` from :func:`to_coco`'s output (exact)."""
    try:
        info = doc.get("info", {})
        if info.get("format") != COCO_FORMAT_NAME:
            raise NpsimInputError(f"{source}: not an NPSim COCO light export (format {info.get('format')!r})")
        if int(info.get("version", 0)) > FORMAT_VERSION:
            raise NpsimInputError(f"{source}: written by a newer NPSim (version {info['version']} > "
                                  f"{FORMAT_VERSION}); update NPSim to open it")
        img = doc["images"][0]
        H, W = int(img["height"]), int(img["width"])
        m = np.zeros((H, W), dtype=np.int32)
        ann = LightAnnotation(m)
        for a in doc["annotations"]:
            cid = int(a["category_id"])
            if is_group_class(cid):
                ann.groups[int(a["id"])] = GroupInstance(int(a["id"]), tuple(int(x) for x in a["members"]))
                continue
            mask = rle_decode(a["segmentation"]["counts"], H, W)
            if (m[mask] != 0).any():
                raise NpsimInputError(f"{source}: light {a['id']} overlaps another light")
            m[mask] = int(a["id"])
            if not mask.any():
                ann.extra_ids.add(int(a["id"]))
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        if isinstance(exc, NpsimInputError):
            raise
        raise NpsimInputError(f"{source}: malformed COCO light export ({type(exc).__name__}: {exc})") from None
    ann.validate(source)
    return ann


def save_coco(ann: LightAnnotation, path: str | Path, *, compressed: bool = True, file_name: str = "") -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(to_coco(ann, file_name=file_name, compressed=compressed)), encoding="utf-8")
    return path


def load_coco(path: str | Path) -> LightAnnotation:
    return from_coco(read_json(path), str(path))


# --------------------------------------------------------------------------- annotation files
def annotation_paths(folder: str | Path, stem: str) -> dict[str, Path]:
    folder = Path(folder)
    return {"instance_png": folder / f"{stem}_lights_instanceIds.png",
            "class_png": folder / f"{stem}_lights_classIds.png",
            "json": folder / f"{stem}_lights.json",
            "coco_json": folder / f"{stem}_lights_coco.json"}


def _png_bytes(arr: np.ndarray, where: Path) -> bytes:
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(arr))
    if not ok:
        raise NpsimInputError(f"{where}: OpenCV could not encode a {arr.dtype} PNG")
    return buf.tobytes()


def _write_bytes(path: Path, data: bytes) -> None:
    # Own function so tests can make a save fail after a temp file was written.
    path.write_bytes(data)


def save_annotation(ann: LightAnnotation, folder: str | Path, stem: str, *, image: np.ndarray | None = None,
                    coco: bool = True) -> dict[str, Path]:
    """Write the instance PNG, class PNG, JSON (and COCO JSON), all or nothing.

    Every file is written to a temporary sibling first; only when all were
    written are they renamed into place, so a failure (disk full, crash in an
    encoder) leaves the previous files untouched. ``image`` (the RGB image the
    annotation belongs to) adds its pixel checksum to the JSON.
    """
    ann.validate()
    paths = annotation_paths(folder, stem)
    if image is not None:
        ann.meta["image_sha256"] = image_checksum(image)
    blobs = {"instance_png": _png_bytes(ann.instance_map.astype(np.uint16), paths["instance_png"]),
             "class_png": _png_bytes(ann.class_map(), paths["class_png"]),
             "json": (json.dumps(ann.to_json(), indent=1) + "\n").encode("utf-8")}
    if coco:
        blobs["coco_json"] = json.dumps(to_coco(ann, file_name=stem)).encode("utf-8")
    with ExitStack() as stack:
        # ExitStack unwinds in reverse: the JSON, entered first, is renamed last,
        # after the PNGs it describes (its checksum then matches what is on disk).
        order = ["json"] + [k for k in blobs if k != "json"]
        for key in order:
            tmp = stack.enter_context(atomic_path(paths[key]))
            _write_bytes(tmp, blobs[key])
    return {k: paths[k] for k in blobs}


def _bad(path: Path, what: str) -> NpsimInputError:
    return NpsimInputError(f"{path}: {what}; the file was left untouched (restore it from a backup, "
                           "or delete the annotation files to start over)")


def parse_annotation_doc(doc: Any, instance_map: np.ndarray, source: Path) -> LightAnnotation:
    """Build an annotation from a parsed JSON document and its instance map (checked)."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT_NAME:
        fmt = doc.get("format") if isinstance(doc, dict) else type(doc).__name__
        raise NpsimInputError(f"{source}: not an NPSim light annotation (format {fmt!r})")
    try:
        version = int(doc.get("version", 0))
    except (TypeError, ValueError):
        raise _bad(source, f"format version {doc.get('version')!r} is not a number") from None
    if version > FORMAT_VERSION:
        raise NpsimInputError(f"{source}: written by a newer NPSim (format version {version} > "
                              f"{FORMAT_VERSION}); update NPSim to open it. The file was left untouched.")
    try:
        H, W = int(doc["height"]), int(doc["width"])
        if instance_map.shape != (H, W):
            raise _bad(source, f"instance map is {instance_map.shape[1]}x{instance_map.shape[0]} but the JSON "
                               f"says {W}x{H}")
        want = doc.get("instance_map_sha256")
        if want and want != map_checksum(instance_map):
            raise _bad(source, "instance PNG does not match the checksum stored in the JSON (corrupt or from "
                               "another save)")
        ann = LightAnnotation(instance_map.astype(np.int32))
        present = set(ann.instance_ids())
        ann.extra_ids = {int(i["id"]) for i in doc.get("instances", [])} - present
        ann.groups = {int(g["id"]): GroupInstance(int(g["id"]), tuple(int(m) for m in g["members"]))
                      for g in doc.get("groups", [])}
        ann.meta = dict(doc.get("meta") or {})
        if doc.get("image_sha256") and "image_sha256" not in ann.meta:
            ann.meta["image_sha256"] = doc["image_sha256"]
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, NpsimInputError):
            raise
        raise _bad(source, f"malformed annotation JSON ({type(exc).__name__}: {exc})") from None
    ann.validate(str(source))
    return ann


def load_annotation(folder: str | Path, stem: str) -> LightAnnotation:
    """Read an annotation written by :func:`save_annotation` (checked, never modified)."""
    paths = annotation_paths(folder, stem)
    doc = read_json(paths["json"])
    raw = read_image(paths["instance_png"], color=False)
    if raw.ndim != 2:
        raise _bad(paths["instance_png"], "instance PNG must be single-channel uint16")
    return parse_annotation_doc(doc, raw, paths["json"])


def load_annotation_file(path: str | Path) -> LightAnnotation:
    """A light annotation from one file: the editor's ``<stem>_lights.json`` (its instance PNG
    beside it) or a COCO JSON (:func:`to_coco`). Errors name the file."""
    path = Path(path)
    if not path.is_file():
        raise NpsimInputError(f"{path}: light annotation not found; give a <name>_lights.json written by "
                              "'npsim annotate' or 'npsim propose', or a COCO JSON")
    doc = read_json(path)
    if isinstance(doc, dict) and doc.get("format") == FORMAT_NAME:
        if not path.name.endswith("_lights.json"):
            raise NpsimInputError(f"{path}: an NPSim light annotation must be named <name>_lights.json, beside "
                                  "its <name>_lights_instanceIds.png")
        return load_annotation(path.parent, path.name[:-len("_lights.json")])
    if isinstance(doc, dict) and ("annotations" in doc or doc.get("format") == COCO_FORMAT_NAME):
        return from_coco(doc, str(path))
    raise NpsimInputError(f"{path}: neither an NPSim light annotation (format {FORMAT_NAME!r}) nor a COCO JSON")


def check_image(ann: LightAnnotation, image: np.ndarray) -> bool:
    """True when ``ann`` was saved for exactly these pixels (or carries no checksum)."""
    want = ann.meta.get("image_sha256")
    return not want or want == image_checksum(image)


# --------------------------------------------------------------------------- autosave / recovery
def autosave_path(folder: str | Path, stem: str) -> Path:
    """Recovery file the editor writes while an annotation has unsaved edits."""
    return Path(folder) / f".{stem}_lights.autosave.npz"


def write_recovery(ann: LightAnnotation, folder: str | Path, stem: str) -> Path:
    """Atomically write ``ann`` (map + JSON) to :func:`autosave_path`."""
    path = autosave_path(folder, stem)
    doc = json.dumps(ann.to_json())
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, instance_map=ann.instance_map.astype(np.uint16),
                                doc=np.frombuffer(doc.encode("utf-8"), dtype=np.uint8))
    return path


def find_recovery(folder: str | Path, stem: str) -> Path | None:
    """The recovery file left by an unsaved session, if any."""
    p = autosave_path(folder, stem)
    return p if p.exists() else None


def load_recovery(path: str | Path) -> LightAnnotation:
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            m = z["instance_map"]
            doc = json.loads(z["doc"].tobytes().decode("utf-8"))
    except Exception as exc:  # noqa: BLE001 -- any decoding problem means a corrupt file
        raise _bad(path, f"unreadable recovery file ({type(exc).__name__})") from None
    return parse_annotation_doc(doc, m, path)


def discard_recovery(folder: str | Path, stem: str) -> None:
    autosave_path(folder, stem).unlink(missing_ok=True)


# --------------------------------------------------------------------------- folders of images
@dataclass(frozen=True)
class AnnotationItem:
    """One image to annotate: where its pixels, labels and annotation files live."""

    name: str
    image_path: Path
    labels_path: Path | None
    folder: Path  # where the annotation files go
    stem: str

    def load_image(self) -> np.ndarray:
        return read_image(self.image_path)

    def load_labels(self) -> np.ndarray | None:
        from .io import read_label_image

        return read_label_image(self.labels_path) if self.labels_path else None

    def load_instances(self, shape: tuple[int, int]) -> np.ndarray | None:
        """The frame's Cityscapes instanceIds (``X_instanceIds.png`` beside its labels), None without them."""
        from .io import instance_ids_path, read_instance_ids

        path = instance_ids_path(self.labels_path) if self.labels_path else None
        return read_instance_ids(path, shape) if path is not None else None

    def has_annotation(self) -> bool:
        return annotation_paths(self.folder, self.stem)["json"].exists()

    def is_done(self) -> bool:
        p = annotation_paths(self.folder, self.stem)["json"]
        if not p.exists():
            return False
        try:
            return bool((read_json(p).get("meta") or {}).get("done", False))
        except NpsimInputError:
            return False


_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
_NOT_IMAGES = re.compile(r"(_labelIds|_lights.*|_color|_instanceIds|_trainIds|_polygons|_disparity|_depth.*)$")


def _scene_folder_item(folder: Path) -> AnnotationItem | None:
    meta_path = folder / "scene.json"
    files: dict[str, str] = {}
    name = None
    if meta_path.exists():
        meta = read_json(meta_path)
        files = dict(meta.get("files", {}))
        name = meta.get("name")
    if "image" not in files:
        cands = sorted(folder.glob("*_rgb.png"))
        if len(cands) != 1:
            return None
        files["image"] = cands[0].name
    name = name or files["image"].rsplit("_", 1)[0]
    lab = folder / files.get("labels", f"{name}_labelIds.png")
    return AnnotationItem(name, folder / files["image"], lab if lab.exists() else None, folder, name)


def discover_items(path: str | Path) -> list[AnnotationItem]:
    """Images to annotate under ``path``.

    ``path`` may be a scene folder (``scene.json`` or one ``*_rgb.png``), a
    folder of scene folders, a folder of images with optional label pairs
    (``X.png`` + ``X_labelIds.png``, ``X_rgb.png`` + ``X_labelIds.png``,
    Cityscapes ``X_leftImg8bit.png`` + ``X_gtFine_labelIds.png``), a Cityscapes or ACDC dataset
    tree (its root, a folder inside it or one of its images: labels from ``gtFine/`` / ``gt/``),
    or one image file. Annotation files are written next to each image.
    """
    path = Path(path)
    if path.is_file():
        items = _image_items(path.parent, [path])
        if not items:
            raise NpsimInputError(f"{path}: not an image NPSim can annotate (png/jpg/bmp/tif)")
        if items[0].labels_path is None:  # a dataset image: its labels live in the layout's gt tree
            items = _dataset_items(path) or items
        return items
    if not path.is_dir():
        raise NpsimInputError(f"{path}: no such file or folder")
    one = _scene_folder_item(path)
    if one is not None:
        return [one]
    dataset = _dataset_items(path)
    if dataset:
        return dataset
    items = [it for sub in sorted(p for p in path.iterdir() if p.is_dir())
             if (it := _scene_folder_item(sub)) is not None]
    items += _image_items(path, sorted(path.iterdir()))
    if not items:
        raise NpsimInputError(f"{path}: found no scene folders or images to annotate")
    return items


def _dataset_items(path: Path) -> list[AnnotationItem]:
    """Labelled frames of a Cityscapes (``leftImg8bit/`` + ``gtFine/``) or ACDC (``rgb_anon/`` +
    ``gt/``) tree: ``path`` is its root, a folder inside its image tree, or one of its images.
    Annotation files go beside each image, where ``npsim run``/``batch`` look for them. Empty for
    other layouts."""
    from .datasets import detect_layout, iter_dataset

    folder = path.parent if path.is_file() else path
    if detect_layout(folder) == "folder":
        return []
    want = path.resolve() if path.is_file() else None
    out = []
    for src in iter_dataset(folder):
        if want is not None and src.image_path.resolve() != want:
            continue
        base = annotation_stem(src.image_path)
        out.append(AnnotationItem(base, src.image_path, src.label_path, src.image_path.parent, base))
    return out


def annotation_stem(image_path: str | Path) -> str:
    """The stem of an image's annotation files, written beside it (``X_leftImg8bit.png`` and
    ``X_rgb.png`` -> ``X``: ``X_lights.json``, ``X_lights_instanceIds.png``...)."""
    return re.sub(r"(_rgb|_leftImg8bit)$", "", Path(image_path).stem)


def _image_items(folder: Path, files: list[Path]) -> list[AnnotationItem]:
    out = []
    for f in files:
        if f.suffix.lower() not in _IMAGE_SUFFIXES or not f.is_file() or f.name.startswith("."):
            continue
        stem = f.stem
        if _NOT_IMAGES.search(stem):
            continue
        base = annotation_stem(f)
        cands = [folder / f"{base}_labelIds.png", folder / f"{base}_gtFine_labelIds.png"]
        lab = next((c for c in cands if c.exists()), None)
        out.append(AnnotationItem(base, f, lab, folder, base))
    return out
