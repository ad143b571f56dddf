"""The scene model and the scene folder every NPSim command reads and writes.

A :class:`Scene` bundles the daytime image, its labels, the camera, and the
optional geometry (estimated and ground-truth depth / normals), the light
annotation and material maps. Construction validates everything and names the
problem (size mismatch, wrong dtype, unknown labels, non-finite intrinsics).

Scene folder layout (``<name>`` = scene name)::

    scene.json                       name, camera pose hints, provenance, file list
    intrinsics.json                  fx, fy, cx, cy, width, height (pixels)
    <name>_rgb.png                   daytime sRGB image (uint8)
    <name>_labelIds.png              Cityscapes labelIds (uint8)
    depth_pred.npy / normals_pred.npy    estimated geometry (metres; unit normals)
    depth_gt.npy / normals_gt.npy        ground truth, when known
    <name>_lights_instanceIds.png, <name>_lights_classIds.png, <name>_lights.json
    albedo.png / roughness.npy       optional material maps
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from .annotation import LightAnnotation, annotation_paths, load_annotation, save_annotation
from .camera import Intrinsics
from .errors import NpsimInputError
from .io import (read_array, read_depth, read_image, read_json, read_label_image, read_normals, write_image,
                 write_json, write_npy)
from .labels import cityscapes

#: Camera height above the ground (m) and downward pitch (rad) when nothing else is known
#: (Cityscapes' rig, docs/method.md §1.2).
DEFAULT_CAMERA_HEIGHT = 1.22
DEFAULT_CAMERA_PITCH = 0.038


@dataclass(frozen=True)
class Scene:
    """One daytime scene and everything known about it.

    Attributes
    ----------
    name : str
        Short identifier used for file names.
    image : (H, W, 3) uint8
        Daytime sRGB image.
    labels : (H, W) uint8
        Cityscapes labelIds.
    intrinsics : Intrinsics
        Pinhole camera for this image size.
    depth, normals : optional
        Estimated z-depth (m, float32, NaN invalid) and unit normals (camera frame,
        toward the camera, NaN invalid) -- the input D, N of the method.
    depth_gt, normals_gt : optional
        Ground truth, when known (synthetic scene); used for scoring only.
    depth_stereo : optional
        The dataset's stereo depth (m, NaN where the disparity has holes): a depth source
        (``--depth stereo``/``auto``) and the scoring reference of frames without ground truth.
    lights : optional LightAnnotation
        Inactive light sources.
    albedo : optional (H, W, 3) float32 linear RGB in [0, 1]; roughness : optional (H, W) float32.
    camera_height, camera_pitch : float
        Metres above the ground and downward pitch in radians (for the pop-up prior).
    provenance : dict
        Where each piece came from (files, generator and its parameters).
    instances : optional (H, W) integer
        Cityscapes instanceIds (``labelId*1000 + k`` on instance classes), when the dataset has them;
        only the light proposals (docs/proposals.md) read them.
    """

    name: str
    image: np.ndarray
    labels: np.ndarray
    intrinsics: Intrinsics
    depth: np.ndarray | None = None
    normals: np.ndarray | None = None
    depth_gt: np.ndarray | None = None
    normals_gt: np.ndarray | None = None
    depth_stereo: np.ndarray | None = None
    lights: LightAnnotation | None = None
    albedo: np.ndarray | None = None
    roughness: np.ndarray | None = None
    camera_height: float = DEFAULT_CAMERA_HEIGHT
    camera_pitch: float = DEFAULT_CAMERA_PITCH
    provenance: dict[str, Any] = field(default_factory=dict)
    instances: np.ndarray | None = None

    def __post_init__(self) -> None:
        validate_scene(self)

    @property
    def height(self) -> int:
        return int(self.image.shape[0])

    @property
    def width(self) -> int:
        return int(self.image.shape[1])

    def with_(self, **changes: Any) -> "Scene":
        """A copy with some fields replaced (validated again)."""
        return replace(self, **changes)


def validate_scene(s: Scene) -> None:
    """Raise :class:`NpsimInputError` on any inconsistency in ``s``."""
    where = f"scene {s.name!r}"
    img = s.image
    if not isinstance(img, np.ndarray) or img.ndim != 3 or img.shape[2] != 3:
        raise NpsimInputError(f"{where}: image must be an HxWx3 RGB array, got "
                              f"{getattr(img, 'shape', type(img).__name__)}")
    if img.dtype != np.uint8:
        raise NpsimInputError(f"{where}: image must be uint8 sRGB, got {img.dtype}; convert with "
                              "np.clip(x*255, 0, 255).astype(np.uint8) for [0,1] floats")
    H, W = img.shape[:2]
    if s.labels.shape != (H, W):
        raise NpsimInputError(f"{where}: labels are {s.labels.shape[1::-1]} (WxH) but the image is {W}x{H}; "
                              "they must match pixel for pixel")
    if s.labels.dtype != np.uint8:
        raise NpsimInputError(f"{where}: labels must be uint8 labelIds, got {s.labels.dtype}")
    cityscapes().validate(s.labels, f"{where} labels")
    if (s.intrinsics.width, s.intrinsics.height) != (W, H):
        raise NpsimInputError(f"{where}: intrinsics are for {s.intrinsics.width}x{s.intrinsics.height} but the image "
                              f"is {W}x{H}; use Intrinsics.resized({W}, {H})")
    for name in ("depth", "depth_gt", "depth_stereo", "roughness"):
        a = getattr(s, name)
        if a is None:
            continue
        if a.shape != (H, W):
            raise NpsimInputError(f"{where}: {name} has shape {a.shape}, expected {(H, W)}")
        if not np.issubdtype(a.dtype, np.floating):
            raise NpsimInputError(f"{where}: {name} must be floating point (metres), got {a.dtype}")
    for name in ("normals", "normals_gt", "albedo"):
        a = getattr(s, name)
        if a is None:
            continue
        if a.shape != (H, W, 3):
            raise NpsimInputError(f"{where}: {name} has shape {a.shape}, expected {(H, W, 3)}")
        if not np.issubdtype(a.dtype, np.floating):
            raise NpsimInputError(f"{where}: {name} must be floating point, got {a.dtype}")
    if s.instances is not None:
        if not isinstance(s.instances, np.ndarray) or s.instances.shape != (H, W):
            raise NpsimInputError(f"{where}: instances have shape {getattr(s.instances, 'shape', None)}, "
                                  f"expected {(H, W)} like the labels")
        if not np.issubdtype(s.instances.dtype, np.integer):
            raise NpsimInputError(f"{where}: instances must be integer instanceIds, got {s.instances.dtype}")
    if s.lights is not None:
        if s.lights.shape != (H, W):
            raise NpsimInputError(f"{where}: light annotation is {s.lights.shape}, image is {(H, W)}")
        s.lights.validate(f"{where} lights")
    if not (np.isfinite(s.camera_height) and s.camera_height > 0):
        raise NpsimInputError(f"{where}: camera_height must be a positive number of metres, got {s.camera_height}")
    if not np.isfinite(s.camera_pitch):
        raise NpsimInputError(f"{where}: camera_pitch must be finite (radians), got {s.camera_pitch}")


# --------------------------------------------------------------------------- scene folders
ARRAY_FILES = {"depth": "depth_pred.npy", "normals": "normals_pred.npy",
               "depth_gt": "depth_gt.npy", "normals_gt": "normals_gt.npy", "depth_stereo": "depth_stereo.npy",
               "roughness": "roughness.npy"}


#: What replaces a file ``scene.json`` names when it is missing (said in the log and manifest).
MISSING_FALLBACK = {
    "depth": "the input depth falls back to the next source (stereo, a network with --checkpoint, else the "
             "pop-up prior)",
    "normals": "the input normals are computed from the depth",
    "depth_gt": "the frame is not scored against ground truth",
    "normals_gt": "the normals are not scored against ground truth",
    "depth_stereo": "the frame has no stereo depth (neither input nor reference)",
    "roughness": "the nights use the roughness fallback (per-class priors)",
    "albedo": "the nights use the albedo fallback (the linearised day image and per-class priors)",
}


def scene_warnings(scene: Scene) -> list[str]:
    """What loading ``scene`` noticed but did not refuse (e.g. a named file that is missing)."""
    return list(scene.provenance.get("warnings", []))


def save_scene(scene: Scene, folder: str | Path) -> Path:
    """Write ``scene`` as a scene folder (every file atomically). Returns the folder."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    files: dict[str, str] = {}
    write_image(folder / f"{scene.name}_rgb.png", scene.image)
    files["image"] = f"{scene.name}_rgb.png"
    write_image(folder / f"{scene.name}_labelIds.png", scene.labels)
    files["labels"] = f"{scene.name}_labelIds.png"
    write_json(folder / "intrinsics.json", scene.intrinsics.to_dict())
    files["intrinsics"] = "intrinsics.json"
    for attr, fname in ARRAY_FILES.items():
        arr = getattr(scene, attr)
        if arr is not None:
            write_npy(folder / fname, arr.astype(np.float32))
            files[attr] = fname
    if scene.instances is not None:
        write_image(folder / f"{scene.name}_instanceIds.png", scene.instances.astype(np.uint16))
        files["instances"] = f"{scene.name}_instanceIds.png"
    if scene.albedo is not None:
        write_image(folder / "albedo.png", (np.clip(scene.albedo, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8))
        files["albedo"] = "albedo.png"
    if scene.lights is not None:
        paths = save_annotation(scene.lights, folder, scene.name)
        files["lights"] = paths["json"].name
    write_json(folder / "scene.json", {
        "format": "npsim-scene", "version": 1, "name": scene.name,
        "width": scene.width, "height": scene.height,
        "camera_height_m": scene.camera_height, "camera_pitch_rad": scene.camera_pitch,
        "files": files, "provenance": {k: v for k, v in scene.provenance.items() if k != "warnings"}})
    return folder


def load_scene(folder: str | Path, *, with_ground_truth: bool = True) -> Scene:
    """Read a scene folder written by :func:`save_scene` (or laid out the same way by hand).

    Without ``scene.json`` the folder must hold exactly one ``*_rgb.png`` (or
    ``*_leftImg8bit.png``) and the matching ``*_labelIds.png``.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise NpsimInputError(f"{folder}: scene folder not found (create one with 'npsim sample -o {folder}')")
    meta_path = folder / "scene.json"
    meta: dict[str, Any] = read_json(meta_path) if meta_path.exists() else {}
    files: dict[str, str] = dict(meta.get("files", {}))
    if "image" not in files:
        cands = sorted(folder.glob("*_rgb.png")) + sorted(folder.glob("*_leftImg8bit.png"))
        if len(cands) != 1:
            raise NpsimInputError(f"{folder}: expected exactly one *_rgb.png (or *_leftImg8bit.png), found "
                                  f"{[c.name for c in cands]}; add a scene.json listing 'files'")
        files["image"] = cands[0].name
    name = meta.get("name") or files["image"].rsplit("_", 1)[0]
    if "labels" not in files:
        cands = sorted(folder.glob("*_labelIds.png"))
        cands = [c for c in cands if "lights" not in c.name]
        if len(cands) != 1:
            raise NpsimInputError(f"{folder}: expected exactly one *_labelIds.png, found {[c.name for c in cands]}")
        files["labels"] = cands[0].name
    image = read_image(folder / files["image"])
    labels = read_label_image(folder / files["labels"])
    if (folder / "intrinsics.json").exists():
        try:
            intr = Intrinsics.from_dict(read_json(folder / "intrinsics.json"))
        except NpsimInputError as exc:  # name the file: the bare message says only what is wrong
            raise NpsimInputError(f"{folder / 'intrinsics.json'}: {exc}") from None
    else:
        raise NpsimInputError(f"{folder}: intrinsics.json is missing; write fx, fy, cx, cy, width, height "
                              "(pixels) or use 'npsim run --fov DEG'")
    arrays: dict[str, Any] = {}
    warnings: list[str] = []
    for attr, fname in ARRAY_FILES.items():
        if attr.endswith("_gt") and not with_ground_truth:
            continue
        p = folder / files.get(attr, fname)
        if attr in files and not p.exists():  # named, yet gone: the fallback must be said
            warnings.append(f"{meta_path} names {files[attr]}, which is missing: {MISSING_FALLBACK[attr]}")
        if p.exists():
            if attr.startswith("depth") or attr == "roughness":
                arrays[attr] = read_depth(p) if attr.startswith("depth") else read_array(p).astype(np.float32)
            else:
                arrays[attr] = read_normals(p)
    if "albedo" in files and not (folder / files["albedo"]).exists():
        warnings.append(f"{meta_path} names {files['albedo']}, which is missing: {MISSING_FALLBACK['albedo']}")
    if (folder / files.get("albedo", "albedo.png")).exists():
        alb = read_image(folder / files.get("albedo", "albedo.png")).astype(np.float32) / 255.0
        arrays["albedo"] = alb ** 2.2
    if "instances" in files:
        inst = read_image(folder / files["instances"], color=False)
        if inst.ndim != 2 or not np.issubdtype(inst.dtype, np.integer):
            raise NpsimInputError(f"{folder / files['instances']}: instance ids must be a single-channel integer PNG")
        arrays["instances"] = inst
    lights = None
    if annotation_paths(folder, name)["json"].exists():
        lights = load_annotation(folder, name)
    return Scene(name=name, image=image, labels=labels, intrinsics=intr, lights=lights,
                 camera_height=float(meta.get("camera_height_m", DEFAULT_CAMERA_HEIGHT)),
                 camera_pitch=float(meta.get("camera_pitch_rad", DEFAULT_CAMERA_PITCH)),
                 provenance=dict(meta.get("provenance", {}), folder=str(folder),
                                 **({"warnings": warnings} if warnings else {})), **arrays)
