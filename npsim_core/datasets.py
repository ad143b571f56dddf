"""Dataset readers: Cityscapes, ACDC and plain image folders -> :class:`SceneSource` records.

Accepted layouts (``ROOT`` = the path given to :func:`open_dataset`)
-------------------------------------------------------------------
Cityscapes::

    ROOT/leftImg8bit/<split>/<city>/<stem>_leftImg8bit.png
    ROOT/gtFine/<split>/<city>/<stem>_gtFine_labelIds.png        (labelTrainIds with trainids=True)
    ROOT/disparity/<split>/<city>/<stem>_disparity.png           optional, stereo depth reference
    ROOT/camera/<split>/<city>/<stem>_camera.json                optional, intrinsics + baseline

ACDC::

    ROOT/rgb_anon/<condition>/<split>/<seq>/<stem>_rgb_anon.png
    ROOT/gt/<condition>/<split>/<seq>/<stem>_gt_labelIds.png     (labelTrainIds with trainids=True)

Plain folder: every ``*.png`` / ``*.jpg`` / ``*.jpeg`` image ``x`` with labels
``x_labelIds.png`` next to it, or ``labels/x.png`` / ``labels/x_labelIds.png``
(with trainids=True also ``x_trainIds.png`` / ``x_labelTrainIds.png``). Image
stems ending in ``_rgb``, ``_leftImg8bit`` or ``_rgb_anon`` match labels without
that suffix, so an NPSim scene folder is also a plain folder -- and so is a folder of
Cityscapes/ACDC files copied side by side (``X_leftImg8bit.png`` with
``X_gtFine_labelIds.png``, ``X_camera.json`` and ``X_disparity.png``; ``X_rgb_anon.png`` with
``X_gt_labelIds.png``).

``ROOT`` may also be a sub-folder of a Cityscapes/ACDC tree (e.g.
``.../leftImg8bit/val/frankfurt``): only the images below it are listed.

Camera: Cityscapes ``camera.json`` gives fx, fy, u0, v0 (for 2048x1024, rescaled
to the image) and the extrinsic height ``z`` and ``pitch``; a given horizontal
field of view (``hfov_deg``, CLI ``--fov``) overrides the intrinsics; otherwise
Cityscapes' typical camera is assumed and the provenance says so.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from .camera import Intrinsics
from .errors import NpsimInputError
from .io import instance_ids_path, read_depth, read_image, read_instance_ids, read_json, read_label_image
from .scene import DEFAULT_CAMERA_HEIGHT, DEFAULT_CAMERA_PITCH, Scene

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
#: Stem endings stripped from image names before matching labels (plain folders).
_IMAGE_STEM_SUFFIXES = ("_leftImg8bit", "_rgb_anon", "_rgb")
#: Names that are never daytime images in a plain folder (labels, visualisations, maps).
_NON_IMAGE_ENDINGS = ("_labelIds", "_trainIds", "_labelTrainIds", "_color", "_instanceIds", "_lights_classIds",
                      "_lights_instanceIds", "_disparity", "_depth", "_normals", "_vis", "_uncertain")
#: Native Cityscapes resolution the camera.json intrinsics refer to.
CITYSCAPES_NATIVE = (2048, 1024)


@dataclass(frozen=True)
class SceneSource:
    """One dataset entry: file paths plus how to turn them into a :class:`Scene`.

    Attributes
    ----------
    name : str
        Scene name (the file stem without the layout's suffix).
    image_path, label_path : Path
        Daytime sRGB image and its labelIds (or trainIds when ``trainids``) PNG.
    layout : str
        ``"cityscapes"``, ``"acdc"`` or ``"folder"``.
    split, group : str or None
        Dataset split and city (Cityscapes) / ``condition/sequence`` (ACDC).
    disparity_path, camera_path : Path or None
        Cityscapes stereo disparity PNG and camera JSON, when present.
    trainids : bool
        The label PNG holds trainIds (mapped to labelIds on load).
    hfov_deg : float or None
        Horizontal field of view overriding every other intrinsics source.
    """

    name: str
    image_path: Path
    label_path: Path
    layout: str
    split: str | None = None
    group: str | None = None
    disparity_path: Path | None = None
    camera_path: Path | None = None
    trainids: bool = False
    hfov_deg: float | None = None

    def camera(self, width: int, height: int) -> tuple[Intrinsics, float, float, dict[str, Any]]:
        """Intrinsics, camera height (m), pitch (rad) and a provenance note for a ``width`` x ``height`` image."""
        note: dict[str, Any] = {}
        cam_height, pitch = DEFAULT_CAMERA_HEIGHT, DEFAULT_CAMERA_PITCH
        intr: Intrinsics | None = None
        if self.camera_path is not None:
            cam = _read_camera_json(self.camera_path)
            intr = cam["intrinsics"].resized(width, height)
            cam_height, pitch = cam["height"], cam["pitch"]
            note["intrinsics"] = f"camera json {self.camera_path.name}"
            note["camera_pose"] = f"camera json {self.camera_path.name} (height z, pitch)"
        if self.hfov_deg is not None:
            intr = Intrinsics.from_fov(width, height, self.hfov_deg)
            note["intrinsics"] = f"horizontal field of view {self.hfov_deg} deg (given)"
        if intr is None:
            intr, how = default_intrinsics(width, height)
            note["intrinsics"] = how
        if "camera_pose" not in note:
            note["camera_pose"] = (f"assumed Cityscapes rig: height {DEFAULT_CAMERA_HEIGHT} m, "
                                   f"pitch {DEFAULT_CAMERA_PITCH} rad")
        return intr, cam_height, pitch, note

    def load(self, *, disparity_as: str = "stereo") -> Scene:
        """Read the files into a validated :class:`Scene`.

        Parameters
        ----------
        disparity_as : {"stereo", "gt", "input", "none"}
            Where Cityscapes stereo depth (``B f / disp``) goes: ``depth_stereo`` (the
            default: a depth source and the scoring reference, docs/method.md §2.2),
            ``depth_gt``, ``depth`` (the estimated input D), or nowhere.
        """
        if disparity_as not in ("stereo", "gt", "input", "none"):
            raise NpsimInputError(f"disparity_as must be 'stereo', 'gt', 'input' or 'none', got {disparity_as!r}")
        image = read_image(self.image_path)
        labels = read_label_image(self.label_path, trainids=self.trainids)
        H, W = image.shape[:2]
        if labels.shape != (H, W):
            raise NpsimInputError(f"{self.label_path}: labels are {labels.shape[1]}x{labels.shape[0]} but the image "
                                  f"{self.image_path} is {W}x{H}; they must match pixel for pixel")
        intr, cam_height, pitch, note = self.camera(W, H)
        prov: dict[str, Any] = {"dataset": self.layout, "image": str(self.image_path),
                                "labels": str(self.label_path), **note}
        if self.trainids:
            prov["labels_format"] = "trainIds mapped to labelIds"
        if self.split:
            prov["split"] = self.split
        arrays: dict[str, np.ndarray] = {}
        if self.disparity_path is not None and disparity_as != "none":
            if self.camera_path is None:
                raise NpsimInputError(f"{self.disparity_path}: converting disparity to depth needs the baseline from "
                                      f"camera/<split>/<city>/{self.name}_camera.json, which is missing")
            cam = _read_camera_json(self.camera_path)
            depth = read_depth(self.disparity_path, disparity_baseline=cam["baseline"],
                               disparity_focal=cam["intrinsics"].resized(*_shape_wh(self.disparity_path)).fx)
            if depth.shape != (H, W):
                raise NpsimInputError(f"{self.disparity_path}: disparity is {depth.shape[1]}x{depth.shape[0]} but "
                                      f"the image is {W}x{H}; resample one of them")
            field = {"stereo": "depth_stereo", "gt": "depth_gt", "input": "depth"}[disparity_as]
            arrays[field] = depth
            prov["stereo_depth"] = f"{self.disparity_path.name} -> {field}"
        # Instance ids (X_gtFine_instanceIds.png beside X_gtFine_labelIds.png) feed the light proposals.
        inst_path = instance_ids_path(self.label_path)
        if inst_path is not None:
            arrays["instances"] = read_instance_ids(inst_path, (H, W))
            prov["instances"] = str(inst_path)
        return Scene(name=self.name, image=image, labels=labels, intrinsics=intr, camera_height=cam_height,
                     camera_pitch=pitch, provenance=prov, **arrays)


def default_intrinsics(width: int, height: int) -> tuple[Intrinsics, str]:
    """Cityscapes' typical camera for an image without a calibration, and a note saying so.

    For a 2:1 image this is ``Intrinsics.cityscapes(W, H)``; for other aspect
    ratios (e.g. ACDC's 1920x1080) rescaling both axes would distort the pixels,
    so Cityscapes' horizontal field of view is kept with square pixels instead.
    """
    if abs(width / height - 2.0) < 0.02:
        return Intrinsics.cityscapes(width, height), (
            "assumed Cityscapes intrinsics (no calibration given; pass --fov to override)")
    hfov = Intrinsics.cityscapes().hfov_deg
    return Intrinsics.from_fov(width, height, hfov), (
        f"assumed Cityscapes field of view {hfov:.1f} deg with square pixels (no calibration given; "
        "pass --fov to override)")


def _shape_wh(path: Path) -> tuple[int, int]:
    from .io import imread

    img = imread(path)
    if img is None:
        raise NpsimInputError(f"{path}: not a readable image")
    return int(img.shape[1]), int(img.shape[0])


def _read_camera_json(path: Path) -> dict[str, Any]:
    """Cityscapes camera JSON -> native intrinsics, baseline (m), height (m), pitch (rad)."""
    doc = read_json(path)
    try:
        ext, intr = doc["extrinsic"], doc["intrinsic"]
        fx, fy, u0, v0 = (float(intr[k]) for k in ("fx", "fy", "u0", "v0"))
        baseline = float(ext["baseline"])
        height = float(ext.get("z", DEFAULT_CAMERA_HEIGHT))
        pitch = float(ext.get("pitch", DEFAULT_CAMERA_PITCH))
    except (KeyError, TypeError, ValueError) as exc:
        raise NpsimInputError(f"{path}: not a Cityscapes camera file (needs intrinsic fx, fy, u0, v0 and extrinsic "
                              f"baseline; problem: {exc!r})") from None
    if not all(math.isfinite(v) for v in (fx, fy, u0, v0, baseline, height, pitch)) or baseline <= 0:
        raise NpsimInputError(f"{path}: camera values must be finite with baseline > 0 "
                              f"(fx={fx}, fy={fy}, u0={u0}, v0={v0}, baseline={baseline})")
    try:
        native = Intrinsics(fx, fy, u0, v0, *CITYSCAPES_NATIVE)
    except NpsimInputError as exc:
        raise NpsimInputError(f"{path}: {exc}") from None
    return {"intrinsics": native, "baseline": baseline, "height": height, "pitch": pitch}


# --------------------------------------------------------------------------- layouts
def _find_root(path: Path, marker: str) -> Path | None:
    """The dataset root holding folder ``marker``: ``path`` itself or the ancestor above ``marker``."""
    if (path / marker).is_dir():
        return path
    parts = path.parts
    if marker in parts:
        i = len(parts) - 1 - parts[::-1].index(marker)
        return Path(*parts[:i]) if i > 0 else Path(os.sep)
    return None


def _images_under(base: Path, pattern: str) -> list[Path]:
    return sorted(p for p in base.rglob(pattern) if p.is_file())


def _layout_entries(path: Path, image_dir: str, image_suffix: str,
                    depth: int) -> Iterator[tuple[Path, tuple[str, ...], str, Path]]:
    """``(root, folders, stem, image)`` for every ``<root>/<image_dir>/<folders...>/<stem><image_suffix>``
    below ``path`` (the dataset root or a folder inside ``image_dir``) with ``depth`` path parts."""
    root = _find_root(path, image_dir)
    if root is None:
        return
    base = path if image_dir in path.parts else root / image_dir
    for img in _images_under(base, f"*{image_suffix}"):
        rel = img.relative_to(root / image_dir)
        if len(rel.parts) == depth:
            yield root, rel.parts[:-1], img.name[: -len(image_suffix)], img


def iter_cityscapes(path: Path, *, trainids: bool = False, hfov_deg: float | None = None) -> Iterator[SceneSource]:
    """Cityscapes entries below ``path`` (the root or a folder inside ``leftImg8bit``)."""
    lbl_suffix = "_gtFine_labelTrainIds.png" if trainids else "_gtFine_labelIds.png"
    for root, (split, city), stem, img in _layout_entries(path, "leftImg8bit", "_leftImg8bit.png", 3):
        lbl = root / "gtFine" / split / city / f"{stem}{lbl_suffix}"
        if not lbl.is_file():
            continue
        disp = root / "disparity" / split / city / f"{stem}_disparity.png"
        cam = root / "camera" / split / city / f"{stem}_camera.json"
        yield SceneSource(name=stem, image_path=img, label_path=lbl, layout="cityscapes", split=split, group=city,
                          disparity_path=disp if disp.is_file() else None,
                          camera_path=cam if cam.is_file() else None, trainids=trainids, hfov_deg=hfov_deg)


def iter_acdc(path: Path, *, trainids: bool = False, hfov_deg: float | None = None) -> Iterator[SceneSource]:
    """ACDC entries below ``path`` (the root or a folder inside ``rgb_anon``)."""
    lbl_suffix = "_gt_labelTrainIds.png" if trainids else "_gt_labelIds.png"
    for root, (condition, split, seq), stem, img in _layout_entries(path, "rgb_anon", "_rgb_anon.png", 4):
        lbl = root / "gt" / condition / split / seq / f"{stem}{lbl_suffix}"
        if not lbl.is_file():
            continue
        yield SceneSource(name=stem, image_path=img, label_path=lbl, layout="acdc", split=split,
                          group=f"{condition}/{seq}", trainids=trainids, hfov_deg=hfov_deg)


def _strip_suffix(stem: str, suffixes: tuple[str, ...]) -> str:
    for s in suffixes:
        if stem.endswith(s) and len(stem) > len(s):
            return stem[: -len(s)]
    return stem


def iter_folder(path: Path, *, trainids: bool = False, hfov_deg: float | None = None) -> Iterator[SceneSource]:
    """Images in the folder ``path`` (not recursive) with labels matched by stem."""
    if not path.is_dir():
        return
    label_endings = ("_trainIds", "_labelTrainIds") if trainids else ("_labelIds",)
    # Cityscapes / ACDC files copied side by side keep their suffixes: X_gtFine_labelIds.png, X_gt_labelIds.png
    label_endings = tuple(f"{pre}{end}" for end in label_endings for pre in ("", "_gtFine", "_gt"))
    for img in sorted(p for p in path.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES):
        if img.stem.endswith(_NON_IMAGE_ENDINGS) or "_lights" in img.stem:
            continue
        stem = _strip_suffix(img.stem, _IMAGE_STEM_SUFFIXES)
        cands = [path / f"{base}{end}.png" for base in dict.fromkeys((img.stem, stem)) for end in label_endings]
        cands += [path / "labels" / f"{base}{end}.png" for base in dict.fromkeys((img.stem, stem))
                  for end in ("",) + label_endings]
        lbl = next((c for c in cands if c.is_file()), None)
        if lbl is None:
            continue
        camera = path / f"{stem}_camera.json"
        disparity = path / f"{stem}_disparity.png"
        yield SceneSource(name=stem, image_path=img, label_path=lbl, layout="folder", trainids=trainids,
                          hfov_deg=hfov_deg, camera_path=camera if camera.is_file() else None,
                          disparity_path=disparity if disparity.is_file() and camera.is_file() else None)


@dataclass(frozen=True)
class _Layout:
    name: str
    marker: str | None
    reader: Any = field(compare=False)


_LAYOUTS = (_Layout("cityscapes", "leftImg8bit", iter_cityscapes), _Layout("acdc", "rgb_anon", iter_acdc),
            _Layout("folder", None, iter_folder))


def detect_layout(path: str | os.PathLike) -> str:
    """``"cityscapes"``, ``"acdc"`` or ``"folder"`` for a dataset path (no files are read)."""
    p = Path(path)
    for lay in _LAYOUTS:
        if lay.marker is not None and _find_root(p, lay.marker) is not None:
            return lay.name
    return "folder"


def iter_dataset(path: str | os.PathLike, *, trainids: bool = False, hfov_deg: float | None = None,
                 layout: str | None = None) -> Iterator[SceneSource]:
    """Yield :class:`SceneSource` records for every labelled image below ``path``.

    ``layout`` forces a reader (``"cityscapes"``, ``"acdc"``, ``"folder"``);
    by default it is detected from the folder names. Images without a matching
    label file are skipped (:func:`open_dataset` reports when nothing matched).
    """
    p = Path(path)
    if not p.exists():
        raise NpsimInputError(f"{p}: dataset folder not found; check the path")
    if not p.is_dir():
        raise NpsimInputError(f"{p}: is a file; give the dataset folder (Cityscapes/ACDC root or an image folder)")
    if hfov_deg is not None and not (0.0 < hfov_deg < 180.0):
        raise NpsimInputError(f"--fov must be a horizontal field of view in (0, 180) degrees, got {hfov_deg}")
    name = layout or detect_layout(p)
    readers = {lay.name: lay.reader for lay in _LAYOUTS}
    if name not in readers:
        raise NpsimInputError(f"unknown dataset layout {name!r}; use one of {sorted(readers)}")
    yield from readers[name](p, trainids=trainids, hfov_deg=hfov_deg)


def open_dataset(path: str | os.PathLike, *, trainids: bool = False, hfov_deg: float | None = None,
                 layout: str | None = None) -> list[SceneSource]:
    """All labelled images below ``path`` as a list; raises a clear error when none match.

    See the module docstring for the accepted layouts.
    """
    p = Path(path)
    sources = list(iter_dataset(p, trainids=trainids, hfov_deg=hfov_deg, layout=layout))
    if not sources:
        kind = layout or detect_layout(p)
        lbl = "labelTrainIds" if trainids else "labelIds"
        expected = {
            "cityscapes": f"leftImg8bit/<split>/<city>/<stem>_leftImg8bit.png with gtFine/<split>/<city>/"
                          f"<stem>_gtFine_{lbl}.png",
            "acdc": f"rgb_anon/<condition>/<split>/<seq>/<stem>_rgb_anon.png with gt/<condition>/<split>/<seq>/"
                    f"<stem>_gt_{lbl}.png",
            "folder": "images x.png/x.jpg with labels x_labelIds.png (or labels/x.png) next to them, or a "
                      "Cityscapes (leftImg8bit/ + gtFine/) or ACDC (rgb_anon/ + gt/) tree",
        }.get(kind, "")
        raise NpsimInputError(f"{p}: no labelled images found (read as a {kind} layout); expected {expected}")
    return sources
