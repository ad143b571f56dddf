"""Light proposals: the result type, the shared context of the proposers and the assembly (docs/proposals.md)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from ..annotation import GroupInstance, LightAnnotation, class_of
from ..camera import Intrinsics
from ..errors import NpsimInputError
from ..labels import cityscapes
from .params import ProposalParams


@dataclass
class LightProposals:
    """Every proposed light and group, with a confidence per light id and per group id.

    ``annotation`` holds all proposals (ids ``classId*1000 + k``, groups of classes 13..21);
    ``confidence`` maps each light id and each group id to [0, 1].
    """

    annotation: LightAnnotation
    confidence: dict[int, float] = field(default_factory=dict)

    def above(self, threshold: float) -> LightAnnotation:
        """The lights with confidence >= ``threshold``; a group keeps its kept members, and is dropped
        when none is left. Ids are unchanged (so they still index ``confidence``)."""
        ann = self.annotation
        keep = [i for i in ann.instance_ids() if self.confidence.get(i, 0.0) >= threshold]
        m = ann.instance_map
        ids = np.asarray(sorted(set(np.unique(m).tolist()) | {0}), dtype=np.int64)
        kept = np.isin(ids, np.asarray(keep + [0], dtype=np.int64))
        lut_pos = np.searchsorted(ids, m)
        new_map = np.where(kept[lut_pos], m, 0).astype(np.int32)
        keep_set = set(keep)
        groups = {}
        for gid, g in ann.groups.items():
            members = tuple(x for x in g.members if x in keep_set)
            if members:
                groups[gid] = GroupInstance(gid, members)
        meta = dict(ann.meta)
        for key in ("lamp_colours", "traffic_light_states", "traffic_light_direction", "light_kinds"):  # kept ids
            if key in meta:
                meta[key] = {k: v for k, v in meta[key].items() if int(k) in keep_set or int(k) in groups}
        return LightAnnotation(new_map, groups, {i for i in ann.extra_ids if i in keep_set}, meta)

    def ids_in_group(self, group_id: int) -> tuple[int, ...]:
        """Member light ids of ``group_id`` (empty for an unknown group)."""
        g = self.annotation.groups.get(int(group_id))
        return tuple(g.members) if g is not None else ()

    def category_ids(self, category: str) -> list[int]:
        """Light ids of one benchmark category (see :data:`CATEGORY_CLASSES`)."""
        want = CATEGORY_CLASSES[category]
        tl_members = {m for g in self.annotation.groups.values() if g.class_id == 20 for m in g.members}
        out = []
        for i in self.annotation.instance_ids():
            if class_of(i) in want and (category != "traffic_light_lamps" or i in tl_members):
                out.append(i)
        return out


#: Light classes of each benchmark category (traffic-light lamps are 'inferred' lights in a traffic_light_group).
CATEGORY_CLASSES: dict[str, tuple[int, ...]] = {
    "windows": (1,), "vehicle_lamps": (3, 4, 5, 6), "vehicle_windows": (2, 7), "street_lamps": (8, 9),
    "traffic_light_lamps": (12,), "advertisements": (10,)}


# --------------------------------------------------------------------------- proposer plumbing
@dataclass
class Light:
    """One proposed light: class, a local boolean mask at (y0, x0), confidence."""

    class_id: int
    y0: int
    x0: int
    mask: np.ndarray
    confidence: float
    #: Signal lamps: the lamp's colour ("red", "amber", "green"), saved as ``meta.lamp_colours``.
    colour: str | None = None
    #: Windows: ``window``, ``shop`` (a shop front) or ``office_band`` (a glass floor band), saved as
    #: ``meta.light_kinds``.
    kind: str | None = None
    #: Windows: the visible part of a pane cut at its top or bottom by the frame or something in
    #: front (kept however low, left out of the façade lattice fit; docs/proposals.md, "Fourth pass").
    cut: bool = False


@dataclass
class Group:
    """Proposed group: class (13..21), members, confidence."""

    class_id: int
    members: list[Light]
    confidence: float
    #: Signal heads: the lamp the day photo shows lit, saved as ``meta.traffic_light_states``.
    state: str | None = None
    #: Signal heads: ``"pedestrian"`` for a pedestrian signal (its own state), saved as
    #: ``meta.traffic_light_direction``; None: the vehicles' direction ("ahead").
    direction: str | None = None


@dataclass
class Context:
    """Inputs shared by the proposers, validated once."""

    image: np.ndarray            # HxWx3 uint8 sRGB
    labels: np.ndarray           # HxW uint8 labelIds
    depth: np.ndarray | None     # HxW float32 metres, NaN invalid
    intrinsics: Intrinsics
    instances: np.ndarray | None  # HxW int32 instanceIds
    params: ProposalParams
    _lum: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return self.labels.shape  # type: ignore[return-value]

    @property
    def lum(self) -> np.ndarray:
        """Linear luminance (HxW float32, 0..1), computed once."""
        if self._lum is None:
            import cv2

            lut = ((np.arange(256) / 255.0) ** 2.2).astype(np.float32)
            lin = cv2.LUT(np.ascontiguousarray(self.image), lut)  # lut[image], a third of its time
            self._lum = lin @ np.array([0.2126, 0.7152, 0.0722], np.float32)
        return self._lum

    def depths_in(self, y0: int, y1: int, x0: int, x1: int, mask: np.ndarray | None = None) -> np.ndarray | None:
        """The finite depths (m) of a box (mask: local bool of the box); None without depth or none finite."""
        if self.depth is None:
            return None
        d = self.depth[y0:y1, x0:x1]
        if mask is not None:
            d = d[mask]
        d = d[np.isfinite(d)]
        return d if d.size else None

    def metres_per_px(self, y0: int, y1: int, x0: int, x1: int, mask: np.ndarray | None = None) -> float | None:
        """Metres per pixel at the median depth of a box (mask: local bool of the box), None without depth."""
        d = self.depths_in(y0, y1, x0, x1, mask)
        return None if d is None else float(median(d)) / float(self.intrinsics.fy)

    def height_above_ground(self, v: np.ndarray | float, z: np.ndarray | float) -> np.ndarray | float:
        """Height (m) above the ground plane of the point seen at image row ``v`` with z-depth ``z`` (m)."""
        p = self.params
        y = (np.asarray(v, dtype=np.float64) - self.intrinsics.cy) * np.asarray(z, dtype=np.float64) \
            / self.intrinsics.fy
        down = y * np.cos(p.camera_pitch_rad) + np.asarray(z, dtype=np.float64) * np.sin(p.camera_pitch_rad)
        return p.camera_height_m - down


def median(a: np.ndarray, axis: int | None = None):
    """``np.median(a, axis)``, the same value and type, by one sort: numpy's own spends tens of
    microseconds of Python a call, and the proposers take thousands a frame over a few dozen pixels.
    ``axis`` None flattens. An empty array, NaN, or a type other than float or integer is left to numpy."""
    a = np.asarray(a)
    if axis is None:
        a, axis = a.reshape(-1), 0
    n = a.shape[axis]
    kind = a.dtype.kind
    if n == 0 or kind not in "fiu":
        return np.median(a, axis=axis)
    s = a.copy(order="K")  # np.sort's own steps, without its wrapper
    s.sort(axis=axis)
    if axis:
        s = np.moveaxis(s, axis, 0)
    if kind == "f":
        last = s[-1]  # NaN sorts last (a scalar for 1-D: no ufunc call)
        if (last != last).any() if s.ndim > 1 else last != last:
            return np.median(a, axis=axis)
    else:
        s = s.astype(np.float64)  # numpy's mean of two integers
    # + 0.0: numpy's mean starts its sum at 0, which turns -0.0 into 0.0
    return s[n // 2] + 0.0 if n % 2 else (s[n // 2 - 1] + s[n // 2] + 0.0) / 2


def pixels(img: np.ndarray, sel: np.ndarray) -> np.ndarray:
    """``img[sel]`` for an (h, w, k) image and an (h, w) bool mask: the same (n, k) array, each pixel's k
    values copied as one item (numpy's boolean index over a 3-D array copies value by value, 3-4x slower)."""
    if img.ndim != 3 or img.strides[-1] != img.itemsize or img.dtype.kind not in "fiu":
        return img[sel]
    k = img.shape[-1]
    return img.view(np.dtype((np.void, k * img.itemsize)))[..., 0][sel].view(img.dtype).reshape(-1, k)


def nanmedian(a: np.ndarray, axis: int | None = None):
    """``np.nanmedian(a, axis)``, the same floats and dtype, by one sort (NaN sorts last): numpy's own
    sorts a masked array (slow in Python) below 600 values along the axis. The non-NaN values' two middle
    order statistics, their sum over 2 as numpy's. Along an axis, NaN where a row (column) has no number,
    without numpy's warning; ``axis`` None (or a 1-D array) with no number is left to numpy, which warns.
    An array holding an inf is left to numpy (its masked sort orders an inf and a NaN as it may)."""
    a = np.asarray(a)
    if axis is None or a.ndim == 1:
        v = a.ravel()
        v = v[~np.isnan(v)]
        return median(v) if v.size else np.nanmedian(a)
    if np.isinf(a).any():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN rows: NaN, as below
            return np.nanmedian(a, axis=axis)
    s = np.sort(np.moveaxis(a, axis, 0), axis=0)
    k = np.count_nonzero(~np.isnan(s), axis=0)
    lo = np.take_along_axis(s, np.maximum((k - 1) // 2, 0)[None], axis=0)[0]
    hi = np.take_along_axis(s, (k // 2)[None], axis=0)[0]
    out = (lo + hi + 0.0) / 2  # + 0.0: as numpy's sum from 0, no -0.0; (x + x) / 2 is x for an odd count
    out[k == 0] = np.nan
    return out


def components(mask: np.ndarray, min_area: int = 1, connectivity: int = 8):
    """Connected components of a bool mask: yields (y0, x0, local bool mask, area) per component."""
    import cv2

    # Labelled over the mask's box only (a frame's few poles or signals took a full-frame labelling
    # each), its corner at even rows and columns: OpenCV labels 2x2 blocks, so the components come in
    # the same order as over the whole frame.
    rows = np.flatnonzero(mask.any(1))
    if rows.size == 0:
        return
    cols = np.flatnonzero(mask.any(0))
    ya, xa = int(rows[0]) & ~1, int(cols[0]) & ~1
    sub = mask[ya:int(rows[-1]) + 1, xa:int(cols[-1]) + 1]
    n, lab, stats, _ = cv2.connectedComponentsWithStats(sub.astype(np.uint8), connectivity=connectivity)
    # (the areas tested at once: a textured wall's blob less its wall colour leaves thousands of flecks)
    for k in (np.flatnonzero(stats[1:, 4] >= min_area) + 1).tolist():
        x, y, w, h, a = stats[k].tolist()
        yield ya + y, xa + x, lab[y:y + h, x:x + w] == k, a


def _check_inputs(image, labels, depth, intrinsics, instances) -> Context:
    if not isinstance(image, np.ndarray) or image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise NpsimInputError(f"image must be an HxWx3 uint8 sRGB array, got "
                              f"{getattr(image, 'shape', type(image).__name__)} {getattr(image, 'dtype', '')}")
    H, W = image.shape[:2]
    if not isinstance(labels, np.ndarray) or labels.shape != (H, W):
        raise NpsimInputError(f"labels must be HxW labelIds matching the image ({H}x{W}), got "
                              f"{getattr(labels, 'shape', type(labels).__name__)}")
    if not np.issubdtype(labels.dtype, np.integer):
        raise NpsimInputError(f"labels must be integer Cityscapes labelIds, got {labels.dtype}")
    labels = labels.astype(np.uint8) if labels.dtype != np.uint8 else labels
    import cv2

    # The ids present, from one histogram of the 8-bit ids (numpy's unique sorts the frame: 8x slower).
    present = np.flatnonzero(cv2.calcHist([np.ascontiguousarray(labels)], [0], None, [256], [0, 256]).ravel())
    cityscapes().validate(present.astype(np.uint8), "labels")
    if depth is not None:
        if not isinstance(depth, np.ndarray) or depth.shape != (H, W) or not np.issubdtype(depth.dtype, np.floating):
            raise NpsimInputError(f"depth must be an HxW float array in metres matching the image ({H}x{W}), got "
                                  f"{getattr(depth, 'shape', type(depth).__name__)} {getattr(depth, 'dtype', '')}")
        depth = depth.astype(np.float32, copy=False)
        bad = ~(np.isfinite(depth) & (depth > 0))  # invalid depth (docs: <= 0, inf) is masked once, here
        if bad.any():
            depth = np.where(bad, np.float32(np.nan), depth)
        if not np.isfinite(depth).any():
            depth = None  # nothing usable: behave as without depth
    if intrinsics is None:
        intrinsics = Intrinsics.cityscapes(W, H)
    elif not isinstance(intrinsics, Intrinsics):
        raise NpsimInputError(f"intrinsics must be an npsim_core.camera.Intrinsics, got {type(intrinsics).__name__}")
    elif (intrinsics.width, intrinsics.height) != (W, H):
        raise NpsimInputError(f"intrinsics are for {intrinsics.width}x{intrinsics.height} but the image is {W}x{H}; "
                              f"use Intrinsics.resized({W}, {H})")
    if instances is not None:
        if not isinstance(instances, np.ndarray) or instances.shape != (H, W) \
                or not np.issubdtype(instances.dtype, np.integer):
            raise NpsimInputError(f"instances must be an HxW integer Cityscapes instanceIds map matching the image "
                                  f"({H}x{W}), got {getattr(instances, 'shape', type(instances).__name__)}")
        instances = instances.astype(np.int32, copy=False)
    return Context(image, labels, depth, intrinsics, instances, ProposalParams())


def _assemble(shape: tuple[int, int], items: list[Light | Group], window_min_share: float = 0.0,
              window_tiny_px: int = 0, window_tiny_conf: float = 1.0) -> LightProposals:
    """Paint lights in order (earlier proposals own contested pixels) and number ids per class.

    A building window (class 1) that the lights painted before it (a sign, a car's lamp, an overlapping
    window) leave under ``window_min_share`` of its pixels, or under ``window_tiny_px`` of them, keeps at
    most ``window_tiny_conf``: its confidence was judged on its whole mask, and what is proposed is a sliver
    of it (``ProposalParams.window_min_painted_share``, the tiny windows' cap; docs/proposals.md "Fifteenth
    pass: windows at 512x256 -- the touch-ups and the false windows")."""
    m = np.zeros(shape, np.int32)
    counters: dict[int, int] = {}
    conf: dict[int, float] = {}
    groups: dict[int, GroupInstance] = {}
    colours: dict[str, str] = {}
    states: dict[str, str] = {}
    kinds: dict[str, str] = {}
    directions: dict[str, str] = {}

    def new_id(cls: int) -> int | None:
        k = counters.get(cls, 0) + 1
        if k >= 1000:
            return None
        counters[cls] = k
        return cls * 1000 + k

    def paint(li: Light) -> int | None:
        h, w = li.mask.shape
        y0, x0 = max(li.y0, 0), max(li.x0, 0)
        y1, x1 = min(li.y0 + h, shape[0]), min(li.x0 + w, shape[1])
        if y1 <= y0 or x1 <= x0:
            return None
        sub = li.mask[y0 - li.y0:y1 - li.y0, x0 - li.x0:x1 - li.x0]
        region = m[y0:y1, x0:x1]
        free = sub & (region == 0)
        if not free.any():
            return None
        n_free, n_all = int(free.sum()), int(sub.sum())
        sliver = li.class_id == 1 and n_free < n_all and (n_free < window_min_share * n_all
                                                          or n_free < window_tiny_px)
        lid = new_id(li.class_id)
        if lid is None:
            return None
        region[free] = lid
        conf[lid] = float(np.clip(li.confidence, 0.0, 1.0))
        if sliver:
            conf[lid] = min(conf[lid], window_tiny_conf)
        if li.colour:
            colours[str(lid)] = li.colour
        if li.kind:
            kinds[str(lid)] = li.kind
        return lid

    for it in items:
        if isinstance(it, Light):
            paint(it)
            continue
        members = [lid for li in it.members if (lid := paint(li)) is not None]
        if not members:
            continue
        gid = new_id(it.class_id)
        if gid is None:
            continue
        groups[gid] = GroupInstance(gid, tuple(members))
        conf[gid] = float(np.clip(it.confidence, 0.0, 1.0))
        if it.state:
            states[str(gid)] = it.state
        if it.direction:
            directions[str(gid)] = it.direction
    meta = {k: v for k, v in (("lamp_colours", colours), ("traffic_light_states", states), ("light_kinds", kinds),
                              ("traffic_light_direction", directions)) if v}
    return LightProposals(LightAnnotation(m, groups, meta=meta), conf)


def propose_lights(image: np.ndarray, labels: np.ndarray, depth: np.ndarray | None = None,
                   intrinsics: Intrinsics | None = None, instances: np.ndarray | None = None,
                   params: ProposalParams = ProposalParams()) -> LightProposals:
    """Propose a light annotation from a daytime frame (docs/proposals.md).

    Parameters
    ----------
    image : (H, W, 3) uint8
        Daytime sRGB image.
    labels : (H, W) integer
        Cityscapes labelIds.
    depth : (H, W) float, optional
        z-depth in metres (NaN invalid); gives metric sizes and heights. Without it the
        proposers fall back to pixel-relative rules and lower confidences.
    intrinsics : Intrinsics, optional
        Pinhole camera for this image size (default: Cityscapes' camera resized).
    instances : (H, W) integer, optional
        Cityscapes instanceIds (``labelId*1000 + k`` on cars, trucks, buses...); without them
        each connected component of a vehicle class is one vehicle.
    params : ProposalParams
        Thresholds.

    Returns
    -------
    LightProposals
        All proposals with a confidence per light and group; deterministic in the inputs.
    """
    from . import ads, street_lamps, traffic_lights, vehicles, windows

    ctx = _check_inputs(image, labels, depth, intrinsics, instances)
    if not isinstance(params, ProposalParams):
        raise NpsimInputError(f"params must be a ProposalParams, got {type(params).__name__}")
    ctx.params = params
    known = {"traffic_lights": traffic_lights.propose, "street_lamps": street_lamps.propose,
             "vehicles": vehicles.propose, "ads": ads.propose, "windows": windows.propose}
    bad = [c for c in params.categories if c not in known]
    if bad:
        raise NpsimInputError(f"params.categories: unknown {bad}; choose from {', '.join(known)}")
    items: list[Light | Group] = []
    for name, fn in known.items():  # fixed order: small, sure lights first own contested pixels
        if name in params.categories:
            items.extend(fn(ctx))
    return _assemble(ctx.shape, items, params.window_min_painted_share, params.window_tiny_px,
                     params.window_tiny_max_confidence)


def propose_for_scene(scene, params: ProposalParams = ProposalParams(), depth: np.ndarray | None = None
                      ) -> LightProposals:
    """:func:`propose_lights` on a :class:`npsim_core.scene.Scene`.

    Depth: the scene's ``depth``, else its ``depth_stereo``, else ``depth`` given here, else none.
    Instances: the scene's ``instances`` when it has that field and it is set.
    """
    d = scene.depth if scene.depth is not None else scene.depth_stereo
    if d is None:
        d = depth
    if isinstance(params, ProposalParams):
        params = replace(params, camera_height_m=float(scene.camera_height),
                         camera_pitch_rad=float(scene.camera_pitch))
    return propose_lights(scene.image, scene.labels, d, scene.intrinsics, getattr(scene, "instances", None),
                          params)


def summarize(proposals: LightProposals, threshold: float = 0.0) -> dict[str, dict]:
    """Per category: number of lights with confidence >= ``threshold``, groups holding them,
    and their confidence range (for logs and the CLI)."""
    ann = proposals.above(threshold)
    group_of = ann.group_index()
    out: dict[str, dict] = {}
    for cat, classes in CATEGORY_CLASSES.items():
        ids = [i for i in ann.instance_ids() if class_of(i) in classes]
        conf = [proposals.confidence.get(i, 0.0) for i in ids]
        out[cat] = {"lights": len(ids), "groups": len({group_of[i] for i in ids if i in group_of}),
                    "confidence": [round(min(conf), 3), round(max(conf), 3)] if conf else None}
    return out
