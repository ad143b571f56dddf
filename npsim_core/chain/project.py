"""Project folders: a frame with its annotation, the chain's parameters and its cached results.

Layout: ``scene/`` (a scene folder), ``project.json`` (format, version, parameters, the
cached arrays' file names) and ``cache/*.npy``. Plain JSON and arrays, no pickle.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .params import ChainParams
from ..errors import NpsimInputError
from ..io import read_json, write_json, write_npy
from ..scene import Scene, load_scene, save_scene

__all__ = ["PROJECT_VERSION", "save_project", "load_project"]

PROJECT_VERSION = 1


def save_project(folder: str | Path, scene: Scene, params: ChainParams, results=None) -> Path:
    """Write a project folder; ``results`` (:class:`~npsim_core.chain.ChainResults`) adds the
    filtered depth, uncertain map and refined depth as ``cache/*.npy``."""
    folder = Path(folder)
    save_scene(scene, folder / "scene")
    cached = {}
    if results is not None:
        for name, arr in (("filtered_depth", results.filtered), ("uncertain", results.uncertain),
                          ("refined_depth", results.depth if results.refine is not None else None)):
            if arr is not None:
                write_npy(folder / "cache" / f"{name}.npy", np.asarray(arr))
                cached[name] = f"cache/{name}.npy"
    write_json(folder / "project.json", {"format": "npsim-project", "version": PROJECT_VERSION, "scene": "scene",
                                         "params": params.to_json(), "cache": cached})
    return folder


def load_project(folder: str | Path) -> tuple[Scene, ChainParams]:
    """Read a project folder written by :func:`save_project`: (scene, parameters)."""
    folder = Path(folder)
    doc = read_json(folder / "project.json")
    if not isinstance(doc, dict) or doc.get("format") != "npsim-project":
        raise NpsimInputError(f"{folder / 'project.json'}: not an NPSim project file")
    if int(doc.get("version", 0)) > PROJECT_VERSION:
        raise NpsimInputError(f"{folder / 'project.json'}: written by a newer NPSim (version {doc['version']}); "
                              "update NPSim to open it")
    scene = load_scene(folder / doc.get("scene", "scene"))
    return scene, ChainParams.from_json(doc.get("params", {}), str(folder / "project.json"))
