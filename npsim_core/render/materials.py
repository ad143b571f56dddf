"""Surface materials for the night render (docs/method.md §6.1).

When the scene carries albedo / roughness maps (the thesis's inverse-rendering
network F_ir, or ground truth of the synthetic scene) they are used as given.
Otherwise a documented fallback:

* **albedo** -- the daytime image is linearised (sRGB decoding); per semantic
  class its pixels are rescaled so the class's mean luminance equals a prior
  albedo for that class (asphalt 0.10, buildings 0.25, vegetation 0.08, ...),
  which removes the daylight's overall level; relative luminance inside a class
  is compressed (``contrast`` exponent 0.7) to weaken baked-in cast shadows.
  Chroma is kept. Result clipped to [0.01, 0.9].
* **roughness** -- per-class priors (asphalt 0.6, paint 0.25, glass 0.05, ...).
* **kind** -- which BSDF each class gets: ``diffuse`` (buildings, vegetation,
  people, ...), ``asphalt`` (rough plastic: the faint glossy sheen of roads and
  sidewalks at night), ``paint`` (vehicles: glossy plastic coat over the albedo),
  ``metal`` (poles, signs: rough plastic), and ``glass`` for the pixels of window
  light classes (1, 2, 7): a dark glossy surface when the window is unlit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..labels import cityscapes
from .lights import srgb_to_linear

KINDS = ("diffuse", "asphalt", "paint", "metal", "glass")
#: Light classes whose pixels are glass (window_building, window_parked, window_transport).
GLASS_LIGHT_CLASSES = (1, 2, 7)

_ALBEDO_PRIOR = {"road": 0.10, "sidewalk": 0.18, "parking": 0.12, "rail track": 0.1, "ground": 0.12,
                 "building": 0.25, "wall": 0.30, "fence": 0.20, "guard rail": 0.3, "bridge": 0.25, "tunnel": 0.2,
                 "pole": 0.20, "polegroup": 0.2, "traffic light": 0.08, "traffic sign": 0.35, "vegetation": 0.08,
                 "terrain": 0.12, "person": 0.20, "rider": 0.2, "car": 0.25, "truck": 0.3, "bus": 0.3,
                 "caravan": 0.3, "trailer": 0.3, "train": 0.3, "motorcycle": 0.2, "bicycle": 0.2}
_KIND = {"road": "asphalt", "sidewalk": "asphalt", "parking": "asphalt", "rail track": "asphalt",
         "car": "paint", "truck": "paint", "bus": "paint", "caravan": "paint", "trailer": "paint", "train": "paint",
         "motorcycle": "paint", "bicycle": "metal", "pole": "metal", "polegroup": "metal", "traffic light": "metal",
         "traffic sign": "metal", "guard rail": "metal"}
_ROUGHNESS = {"diffuse": 1.0, "asphalt": 0.6, "paint": 0.25, "metal": 0.4, "glass": 0.05}


@dataclass(frozen=True)
class MaterialParams:
    """Fallback material estimation parameters.

    contrast : exponent applied to within-class relative luminance (1 = keep day contrast).
    albedo_prior : optional overrides ``{class name: albedo}``.
    """

    contrast: float = 0.7
    albedo_prior: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Materials:
    """Per-pixel material maps aligned with the image.

    albedo : (H, W, 3) float32 linear RGB; roughness : (H, W) float32 in [0, 1];
    kind_lut : (256,) int index into :data:`KINDS` per labelId; source : 'scene' or 'fallback'.
    labels : (H, W) uint8 labelIds the maps were made for (the builder uses them to repair
        texture coordinates of visible vertices, see ``scene_builder``).
    """

    albedo: np.ndarray
    roughness: np.ndarray
    kind_lut: np.ndarray
    source: str
    labels: np.ndarray | None = None


def kind_lut() -> np.ndarray:
    """(256,) material kind index per Cityscapes labelId."""
    lut = np.zeros(256, dtype=np.int32)
    for c in cityscapes().classes:
        lut[c.id] = KINDS.index(_KIND.get(c.name, "diffuse"))
    return lut


def estimate_materials(image: np.ndarray, labels: np.ndarray, *, albedo: np.ndarray | None = None,
                       roughness: np.ndarray | None = None, light_classes: np.ndarray | None = None,
                       params: MaterialParams = MaterialParams()) -> Materials:
    """Albedo, roughness and BSDF kinds for a scene.

    Parameters
    ----------
    image : (H, W, 3) uint8 daytime sRGB.
    labels : (H, W) uint8 labelIds.
    albedo, roughness : maps from the scene (used as given when not None).
    light_classes : (H, W) light class per pixel (0 = none); window classes get glass roughness.
    """
    kl = kind_lut()
    H, W = labels.shape
    source = "scene" if albedo is not None else "fallback"
    if albedo is None:
        albedo = fallback_albedo(image, labels, params)
    if roughness is None:
        rough_of_kind = np.array([_ROUGHNESS[k] for k in KINDS], dtype=np.float32)
        roughness = rough_of_kind[kl[labels]]
        if light_classes is not None:
            roughness = np.where(np.isin(light_classes, GLASS_LIGHT_CLASSES), _ROUGHNESS["glass"], roughness)
        source += "+prior roughness"
    return Materials(np.ascontiguousarray(albedo, dtype=np.float32),
                     np.ascontiguousarray(roughness, dtype=np.float32).reshape(H, W), kl, source,
                     np.asarray(labels, dtype=np.uint8))


def fallback_albedo(image: np.ndarray, labels: np.ndarray, params: MaterialParams = MaterialParams()) -> np.ndarray:
    """Per-class normalised linear daytime colour (module docstring)."""
    lin = srgb_to_linear(image.astype(np.float32) / 255.0)
    lum = lin @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    lab = labels.astype(np.intp).ravel()
    sums = np.bincount(lab, weights=lum.ravel(), minlength=256)
    counts = np.bincount(lab, minlength=256)
    mean = np.where(counts > 0, sums / np.maximum(counts, 1), 1.0)
    prior = np.full(256, 0.2)
    for c in cityscapes().classes:
        prior[c.id] = params.albedo_prior.get(c.name, _ALBEDO_PRIOR.get(c.name, 0.2))
    eps = 1e-4
    rel = lum / np.maximum(mean[labels], eps)
    target = prior[labels] * np.power(np.maximum(rel, 0.0), params.contrast)
    albedo = lin * (target / np.maximum(lum, eps))[..., None]
    # Black day pixels (lum ~ 0) get the class prior as grey.
    dark = lum < eps
    albedo[dark] = prior[labels][dark][:, None]
    return np.clip(albedo, 0.01, 0.9).astype(np.float32)
