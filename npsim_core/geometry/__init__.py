"""Geometry estimators: the method's input depth D and normals N for a scene (docs/method.md §2.2).

One interface, three methods::

    estimate_geometry(scene, "popup")                      # semantic pop-up prior, no weights
    estimate_geometry(scene, "files", FilesParams(depth_path="d.npy"))
    estimate_geometry(scene, "network", NetworkParams(checkpoint="models/depth-anything-small"))

Every method returns a :class:`GeometryEstimate`: z-depth in metres (HxW
float32, NaN = invalid, sky always invalid) and unit normals in the camera
frame pointing toward the camera (HxWx3 float32, NaN = invalid), docs/method.md §1.1, §1.3.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import NpsimInputError
from ..scene import Scene

METHODS = ("popup", "files", "network", "stereo")


@dataclass(frozen=True)
class GeometryEstimate:
    """Estimated geometry of one scene.

    Attributes
    ----------
    depth : (H, W) float32
        z-depth in metres; NaN where invalid (sky, unknown).
    normals : (H, W, 3) float32
        Unit normals, camera frame, toward the camera; NaN where invalid.
    method : str
        ``"popup"``, ``"files"`` or ``"network"``.
    info : dict
        Method details (parameters, fitted values, timings, notes) for provenance.
    """

    depth: np.ndarray
    normals: np.ndarray
    method: str
    info: dict[str, Any] = field(default_factory=dict)

    def apply(self, scene: Scene) -> Scene:
        """``scene`` with this estimate as its input depth/normals and a provenance entry."""
        prov = dict(scene.provenance)
        prov["geometry"] = {"method": self.method, **{k: v for k, v in self.info.items() if _jsonable(v)}}
        return scene.with_(depth=self.depth, normals=self.normals, provenance=prov)


def _jsonable(v: Any) -> bool:
    return isinstance(v, (str, int, float, bool, type(None), list, tuple, dict))


def estimate_geometry(scene: Scene, method: str = "popup", params: Any = None) -> GeometryEstimate:
    """Estimate depth and normals for ``scene`` with ``method``.

    Parameters
    ----------
    scene : Scene
        Image, labels, intrinsics, camera height/pitch.
    method : {"popup", "files", "network", "stereo"}
    params : PopupParams | FilesParams | NetworkParams | StereoParams, optional
        The method's frozen parameters (defaults when ``None``; ``files`` and
        ``network`` need paths, so their params are required).
    """
    from .files import FilesParams, estimate_from_files
    from .network import NetworkParams, estimate_network
    from .popup import PopupParams, estimate_popup
    from .stereo import StereoParams, estimate_stereo

    table = {"popup": (PopupParams, estimate_popup), "files": (FilesParams, estimate_from_files),
             "network": (NetworkParams, estimate_network), "stereo": (StereoParams, estimate_stereo)}
    if method not in table:
        raise NpsimInputError(f"unknown geometry method {method!r}; use one of {', '.join(METHODS)}")
    ptype, fn = table[method]
    if params is None:
        if method not in ("popup", "stereo"):
            raise NpsimInputError(f"geometry method {method!r} needs parameters ({ptype.__name__}): "
                                  + ("the depth file" if method == "files" else "the checkpoint folder"))
        params = ptype()
    if not isinstance(params, ptype):
        raise NpsimInputError(f"geometry method {method!r} takes {ptype.__name__}, got {type(params).__name__}")
    return fn(scene, params)


def invalid_label_mask(labels: np.ndarray, invalid_ids: tuple[int, ...]) -> np.ndarray:
    """True where the label is one of ``invalid_ids`` (sky, ego vehicle, borders)."""
    lut = np.zeros(256, dtype=bool)
    lut[list(invalid_ids)] = True
    return lut[labels]


__all__ = ["GeometryEstimate", "estimate_geometry", "METHODS", "invalid_label_mask"]
