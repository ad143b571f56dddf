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

from ..camera import LOW_CONFIDENCE  # re-exported: defined with the depth conventions
from ..errors import NpsimInputError
from ..scene import Scene

METHODS = ("popup", "files", "network", "stereo")

#: Depth limits applied to every depth that enters the program, from every source:
#: nearer than ``DEPTH_NEAR_M`` (a camera sees nothing 10 cm in front of its lens; 1e-30 m built
#: vertices on the camera centre) or beyond ``DEPTH_FAR_M`` (``mesh.far_limit``'s default: a sky
#: at 1e30 m scored AbsRel 6e27) is invalid (NaN), and the count is reported.
DEPTH_NEAR_M = 0.1
DEPTH_FAR_M = 300.0


@dataclass(frozen=True)
class DepthLimits:
    """What :func:`limit_depth` dropped: pixel counts nearer than ``near_m`` and beyond ``far_m``."""

    near_m: float
    far_m: float
    dropped_near: int = 0
    dropped_far: int = 0

    @property
    def dropped(self) -> int:
        return self.dropped_near + self.dropped_far

    def __add__(self, other: "DepthLimits") -> "DepthLimits":
        return DepthLimits(max(self.near_m, other.near_m), min(self.far_m, other.far_m),
                           self.dropped_near + other.dropped_near, self.dropped_far + other.dropped_far)

    def sentence(self) -> str:
        """'' when nothing was dropped, else e.g. '12 pixels dropped as invalid (3 nearer than 0.1 m, 9
        beyond 300 m)'."""
        if not self.dropped:
            return ""
        return (f"{self.dropped} pixel{'s' if self.dropped != 1 else ''} dropped as invalid ({self.dropped_near} "
                f"nearer than {self.near_m:g} m, {self.dropped_far} beyond {self.far_m:g} m)")

    def to_json(self) -> dict:
        return {"near_m": self.near_m, "far_m": self.far_m, "dropped_near": self.dropped_near,
                "dropped_far": self.dropped_far}


def limit_depth(depth: np.ndarray, near_m: float = DEPTH_NEAR_M,
                far_m: float = DEPTH_FAR_M) -> tuple[np.ndarray, DepthLimits]:
    """``depth`` (m) with finite values outside [``near_m``, ``far_m``] set to NaN, and their counts.

    NaN, inf and values <= 0 were invalid already (docs/method.md §1.1) and are not counted; the
    result is float32 (a copy only when something changed)."""
    if not (np.isfinite(near_m) and 0 <= near_m < far_m):  # far may be inf (no far limit)
        raise NpsimInputError(f"depth limits must satisfy 0 <= near < far (metres), got near {near_m}, far {far_m}")
    d = np.asarray(depth, np.float32)
    with np.errstate(invalid="ignore"):
        fin = np.isfinite(d) & (d > 0)
        near = fin & (d < near_m)
        far = fin & (d > far_m)
    lim = DepthLimits(float(near_m), float(far_m), int(near.sum()), int(far.sum()))
    if lim.dropped:
        d = np.where(near | far, np.float32(np.nan), d)
    return d, lim


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
    confidence : (H, W) float32 or None
        Per-pixel confidence in [0, 1] where the method gives one (the pop-up prior:
        low on hidden contacts and far-limit placements, docs/geometry.md); NaN where
        the depth is invalid.
    """

    depth: np.ndarray
    normals: np.ndarray
    method: str
    info: dict[str, Any] = field(default_factory=dict)
    confidence: np.ndarray | None = None

    def apply(self, scene: Scene) -> Scene:
        """``scene`` with this estimate as its input depth/normals and a provenance entry."""
        prov = dict(scene.provenance)
        prov["geometry"] = {"method": self.method, **{k: v for k, v in self.info.items() if _jsonable(v)}}
        return scene.with_(depth=self.depth, normals=self.normals, provenance=prov)


def _jsonable(v: Any) -> bool:
    return isinstance(v, (str, int, float, bool, type(None), list, tuple, dict))


def estimate_geometry(scene: Scene, method: str = "popup", params: Any = None,
                      limits: tuple[float, float] = (DEPTH_NEAR_M, DEPTH_FAR_M)) -> GeometryEstimate:
    """Estimate depth and normals for ``scene`` with ``method``.

    Parameters
    ----------
    scene : Scene
        Image, labels, intrinsics, camera height/pitch.
    method : {"popup", "files", "network", "stereo"}
    params : PopupParams | FilesParams | NetworkParams | StereoParams, optional
        The method's frozen parameters (defaults when ``None``; ``files`` and
        ``network`` need paths, so their params are required).
    limits : (near, far) metres
        Depth outside is invalid (:func:`limit_depth`); the counts dropped are in
        ``info["depth_limits"]``.
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
    est = fn(scene, params)
    depth, lim = limit_depth(est.depth, *limits)
    normals = est.normals
    if lim.dropped:
        normals = np.where(np.isfinite(depth)[..., None], normals, np.float32(np.nan)).astype(np.float32)
    conf = est.confidence
    if conf is not None and lim.dropped:
        conf = np.where(np.isfinite(depth), conf, np.float32(np.nan)).astype(np.float32)
    return GeometryEstimate(depth, normals, est.method, {**est.info, "depth_limits": lim.to_json()}, conf)


def confidence_summary(confidence: np.ndarray, threshold: float = LOW_CONFIDENCE) -> dict:
    """Share of the pixels with a confidence (finite) below ``threshold``, their mean confidence, the
    count, and a sentence for the log (e.g. "31.0 % of the depth's pixels guessed (confidence < 0.5)")."""
    c = np.asarray(confidence)
    ok = np.isfinite(c)
    n = int(ok.sum())
    low = float((c[ok] < threshold).mean()) if n else 0.0
    return {"low_share": round(low, 4), "threshold": float(threshold),
            "mean": round(float(c[ok].mean()), 4) if n else None, "pixels": n,
            "sentence": f"{100 * low:.1f} % of the depth's pixels guessed (confidence < {threshold:g})"}


def invalid_label_mask(labels: np.ndarray, invalid_ids: tuple[int, ...]) -> np.ndarray:
    """True where the label is one of ``invalid_ids`` (sky, ego vehicle, borders)."""
    lut = np.zeros(256, dtype=bool)
    lut[list(invalid_ids)] = True
    return lut[labels]


__all__ = ["GeometryEstimate", "estimate_geometry", "METHODS", "invalid_label_mask", "limit_depth", "DepthLimits",
           "DEPTH_NEAR_M", "DEPTH_FAR_M", "LOW_CONFIDENCE", "confidence_summary"]
