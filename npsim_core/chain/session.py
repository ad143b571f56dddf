"""A frame's inputs: one loader for every source the chain reads.

* a scene folder (``scene.json`` + arrays, as written by ``npsim sample`` / ``npsim estimate``);
* a project folder (``project.json``; its parameters come with it, :mod:`npsim_core.chain.project`);
* one image inside a dataset (Cityscapes, ACDC, or a plain folder with ``x_labelIds.png``
  beside ``x.png``): its labels, camera and disparity are found by the dataset readers;
* a dataset root or a folder of scene folders: :func:`iter_frames` lists its frames.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from ..errors import NpsimInputError
from ..scene import Scene

__all__ = ["FrameSource", "load_frame", "iter_frames", "scaled_frame", "annotations_root", "frame_annotation_files",
           "scene_annotation_files"]

#: Environment variable naming the annotations folder used for read-only datasets (docs/annotation.md,
#: "Where a frame's annotation is saved").
ANNOTATIONS_ENV = "NPSIM_ANNOTATIONS"


def annotations_root() -> Path:
    """The annotations folder for frames whose dataset folder cannot be written.

    ``$NPSIM_ANNOTATIONS`` when set, else ``$XDG_DATA_HOME/npsim/annotations`` (default
    ``~/.local/share/npsim/annotations``). Inside it a frame's files sit under its image folder's
    absolute path (``/data/cs/leftImg8bit/val/x/a.png`` -> ``ROOT/data/cs/leftImg8bit/val/x/a_lights.json``),
    so frames of different datasets never collide.
    """
    env = os.environ.get(ANNOTATIONS_ENV)
    if env:
        return Path(env).expanduser()
    data = os.environ.get("XDG_DATA_HOME") or str(Path.home() / ".local" / "share")
    return Path(data) / "npsim" / "annotations"


def _writable(folder: Path) -> bool:
    return os.access(folder, os.W_OK | os.X_OK)


def frame_annotation_files(image_path: str | Path) -> tuple[Path, str]:
    """``(folder, stem)`` of a dataset image's light annotation (``folder/<stem>_lights.json`` and its PNGs).

    The editor writes it beside the image (``X_leftImg8bit.png`` -> ``X_lights.json``), where
    ``--lights auto`` and ``npsim batch`` read it. When the image's folder is not writable (a
    read-only dataset) the same names go to :func:`annotations_root` under the folder's absolute
    path. An annotation already saved in one of the two places is found there (beside first).
    """
    from ..annotation import annotation_paths, annotation_stem

    image = Path(image_path)
    stem = annotation_stem(image)
    beside = image.parent
    mirror = annotations_root() / beside.resolve().relative_to(beside.resolve().anchor)
    for folder in (beside, mirror):
        if annotation_paths(folder, stem)["json"].exists():
            return folder, stem
    return (beside if _writable(beside) else mirror), stem


def scene_annotation_files(scene: Scene) -> tuple[Path, str] | None:
    """``(folder, stem)`` where the light annotation of a loaded frame is saved: its scene folder
    (``<name>_lights.json``, also inside a project), else :func:`frame_annotation_files` of its
    dataset image; None for a frame that exists only in memory (e.g. a generated street)."""
    prov = scene.provenance
    if prov.get("folder"):
        return Path(prov["folder"]), scene.name
    if prov.get("image"):
        return frame_annotation_files(prov["image"])
    return None


@dataclass(frozen=True)
class FrameSource:
    """One frame of a dataset root: its name, where it is, how to load it (picklable: it is
    sent to worker processes and Ray tasks) and, for dataset layouts, its split and
    city/sequence."""

    name: str
    path: Path
    load: Callable[[], Scene]
    split: str | None = None
    group: str | None = None


def load_frame(path: str | Path, *, hfov_deg: float | None = None, trainids: bool = False,
               scale: float = 1.0, with_ground_truth: bool = True) -> Scene:
    """The frame at ``path``: a scene folder, a project folder, or one dataset image.

    ``scale`` resamples it (:func:`scaled_frame`); ``hfov_deg`` sets the intrinsics of a
    dataset image; ``with_ground_truth=False`` drops a scene folder's ground truth.
    """
    path = Path(path)
    if not path.exists():
        raise NpsimInputError(f"{path}: not found; give a scene folder (see 'npsim sample'), a project folder "
                              "or a labelled image")
    if path.is_dir():
        if (path / "project.json").exists():
            from .project import load_project

            scene = load_project(path)[0]
        elif (path / "scene.json").exists() or (path / "intrinsics.json").exists():
            from ..scene import load_scene

            scene = load_scene(path, with_ground_truth=with_ground_truth)
        else:
            scene = _dataset_folder(path, hfov_deg, trainids)
    else:
        scene = _dataset_image(path, hfov_deg, trainids)
    return scaled_frame(scene, scale)


def load_source(src) -> Scene:
    """A dataset entry's scene (:class:`~npsim_core.datasets.SceneSource`) with the light annotation
    the editor saved for it, when there is one: beside its image, or in the annotations folder of a
    read-only dataset (:func:`frame_annotation_files`; module-level: picklable for workers)."""
    from ..annotation import annotation_paths, load_annotation

    scene = src.load()
    image = Path(src.image_path)
    folder, stem = frame_annotation_files(image)
    path = annotation_paths(folder, stem)["json"]
    if scene.lights is not None or not path.exists():
        return scene
    ann = load_annotation(folder, stem)
    if ann.shape != (scene.height, scene.width):
        raise NpsimInputError(f"{path}: the light annotation is {ann.shape[1]}x{ann.shape[0]} but {image.name} is "
                              f"{scene.width}x{scene.height}; it belongs to another image (move or delete it)")
    return scene.with_(lights=ann, provenance={**scene.provenance, "lights": str(path)})


def _dataset_image(path: Path, hfov_deg: float | None, trainids: bool) -> Scene:
    from ..datasets import iter_dataset

    for src in iter_dataset(path.parent, trainids=trainids, hfov_deg=hfov_deg):
        if Path(src.image_path).resolve() == path.resolve():
            return load_source(src)
    raise NpsimInputError(f"{path}: no labels found for this image; put {path.stem}_labelIds.png beside it or use "
                          "a Cityscapes/ACDC folder layout")


def _dataset_folder(path: Path, hfov_deg: float | None, trainids: bool) -> Scene:
    """A folder holding one frame's dataset files side by side (image, labels, camera JSON, disparity)."""
    from ..datasets import iter_folder

    frames = list(iter_folder(path, trainids=trainids, hfov_deg=hfov_deg))
    if len(frames) == 1:
        return load_source(frames[0])
    if not frames:
        raise NpsimInputError(f"{path}: neither a scene folder (scene.json / intrinsics.json), a project "
                              "(project.json) nor a frame's files (X.png or X_leftImg8bit.png with "
                              "X_labelIds.png or X_gtFine_labelIds.png)")
    raise NpsimInputError(f"{path}: holds {len(frames)} frames ({', '.join(f.name for f in frames[:4])}"
                          f"{', …' if len(frames) > 4 else ''}); open one of its images, or use 'npsim batch' "
                          "for all of them")


def iter_frames(root: str | Path, *, trainids: bool = False, hfov_deg: float | None = None) -> list[FrameSource]:
    """Every frame under ``root``: its scene folders, else its dataset images (Cityscapes, ACDC,
    plain folder). Raises a clear error when there are none."""
    root = Path(root)
    if not root.is_dir():
        raise NpsimInputError(f"{root}: dataset folder not found" if not root.exists() else
                              f"{root}: is a file; give the dataset folder")
    scene_dirs = sorted(p.parent for p in root.glob("*/scene.json"))
    if scene_dirs:
        from ..scene import load_scene

        return [FrameSource(d.name, d, functools.partial(load_scene, d)) for d in scene_dirs]
    from ..datasets import open_dataset

    return [FrameSource(s.name, Path(s.image_path), functools.partial(load_source, s), s.split, s.group)
            for s in open_dataset(root, trainids=trainids, hfov_deg=hfov_deg)]


def scaled_frame(scene: Scene, scale: float) -> Scene:
    """The frame resampled to ``scale`` (image INTER_AREA; labels, instances, depth, normals, lights nearest)."""
    if scale == 1.0:
        return scene
    if not (0.05 <= scale <= 1.0):
        raise NpsimInputError(f"scale must be in [0.05, 1], got {scale}")
    W, H = max(2, round(scene.width * scale)), max(2, round(scene.height * scale))

    def near(a):
        return None if a is None else cv2.resize(a, (W, H), interpolation=cv2.INTER_NEAREST)

    lights = None
    if scene.lights is not None:
        from ..annotation import LightAnnotation

        lights = LightAnnotation(near(scene.lights.instance_map.astype(np.int32)), dict(scene.lights.groups))
        present = set(lights.instance_ids())
        lights.groups = {gid: type(g)(g.id, tuple(m for m in g.members if m in present))
                         for gid, g in lights.groups.items() if any(m in present for m in g.members)}
    return scene.with_(image=cv2.resize(scene.image, (W, H), interpolation=cv2.INTER_AREA),
                       labels=near(scene.labels), intrinsics=scene.intrinsics.resized(W, H),
                       depth=near(scene.depth), normals=near(scene.normals), depth_gt=near(scene.depth_gt),
                       depth_stereo=near(scene.depth_stereo),
                       normals_gt=near(scene.normals_gt), lights=lights, albedo=near(scene.albedo),
                       roughness=near(scene.roughness), instances=near(scene.instances))
