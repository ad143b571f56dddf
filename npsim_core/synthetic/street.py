"""The seeded street layout: primitives plus the light instances and groups they carry.

World frame (see :mod:`.primitives`): x right, y up, z along the street, metres.
Cross-section (x): left facades at about -11, left sidewalk [-11, -6], road
[-6, 4.5] with parking strips on both sides, right sidewalk [4.5, 9.5], right
facades at about 9.5. A far building closes the street at z = ``far_z`` so
every ray below the roof lines hits something: sky is only above.

Light instances get ids ``classId*1000 + index`` at layout time (stable across
resolutions); the caller drops the ones that own no pixel.

Variants (``build_street(seed, variant=...)``, docs/synthetic.md "Hard variants") add
the layouts that defeat a naive semantic pop-up prior: long building blocks
receding along the street, facade bases hidden behind continuous rows of parked
cars, people and hedges, corner buildings at cross streets, and poles and trees
in front of the facades. ``variant="default"`` draws exactly the same random
numbers as before, so the default street is unchanged; the extra objects of a
variant come from a second random stream seeded by ``(seed, variant)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .primitives import PrimitiveList, Primitives

# Cityscapes labelIds used here.
ROAD, SIDEWALK, BUILDING, POLE, TRAFFIC_LIGHT, TRAFFIC_SIGN, VEGETATION, SKY, PERSON, CAR = \
    7, 8, 11, 17, 19, 20, 21, 23, 24, 26
EGO_VEHICLE, RECTIFICATION_BORDER, OUT_OF_ROI, RIDER, TRUCK, BUS, BICYCLE = 1, 2, 3, 25, 27, 28, 33
# Light-source classes (resources/light_classes.json).
WINDOW_BUILDING, WINDOW_PARKED, PARKED_FRONT, PARKED_REAR, STREET_LIGHT_HT, ADVERTISEMENT, INFERRED = 1, 2, 3, 4, 8, 10, 12
MOVING_FRONT, MOVING_REAR = 5, 6
STREET_LIGHT_LT = 9
WINDOWS_GROUP, CAR_GROUP, TRAFFIC_LIGHT_GROUP = 13, 14, 20

ROAD_X = (-6.0, 4.5)
LEFT_WALK_X = (-11.0, -6.0)
RIGHT_WALK_X = (4.5, 9.5)
KERB = 0.15
STREET_Z0 = 2.0  # nothing nearer is in view (ground is visible from z ~ 4.5 m); keeps screen boxes tight
# Lights are flush with their host face (same plane, inside its bounds) and win depth ties in
# the ray caster; ``out`` tells the renderer which side is outward (it lifts them 3 mm there
# to avoid z-fighting). A proud pane would leave its host at grazing angles.

FACADE_COLORS = [(0.55, 0.45, 0.35), (0.62, 0.58, 0.50), (0.45, 0.30, 0.22), (0.70, 0.66, 0.58),
                 (0.50, 0.52, 0.55), (0.60, 0.50, 0.38), (0.38, 0.36, 0.34), (0.72, 0.62, 0.45)]
CAR_COLORS = [(0.60, 0.61, 0.62), (0.03, 0.03, 0.035), (0.80, 0.80, 0.78), (0.45, 0.04, 0.03),
              (0.05, 0.12, 0.35), (0.25, 0.26, 0.27), (0.30, 0.33, 0.20), (0.75, 0.55, 0.10)]
GLASS_BUILDING = [(0.05, 0.07, 0.09), (0.04, 0.05, 0.05), (0.07, 0.08, 0.07)]
GLASS_CAR = (0.02, 0.025, 0.03)
CLOTHES = [(0.05, 0.05, 0.06), (0.25, 0.05, 0.05), (0.10, 0.15, 0.35), (0.50, 0.45, 0.35), (0.20, 0.22, 0.18)]


@dataclass(frozen=True)
class _Hard:
    """Which hard-layout features a variant switches on (all off = the default street)."""

    receding: bool = False       # long blocks (40-90 m) along the street, taller, street 150-200 m long
    occluded_base: bool = False  # near-continuous parked cars, people, hedges along the facade bases
    corner: bool = False         # a cross street on each side: corner buildings with two visible facades
    clutter: bool = False        # poles, bollards, signs and trees in front of the facades
    busy: bool = False           # people and riders on bicycles on the sidewalks and the road, a truck or a
    #                              bus, the ego vehicle's hood and the Cityscapes frame-border labels
    canopy: bool = False         # street trees whose crowns overhang the sidewalk, trunks hidden behind people,
    #                              bus shelters, vans and sign boards
    square: bool = False         # the street opens onto a square / crossing; buildings 40-150 m away across it
    shopfront: bool = False      # glazed ground floors, awnings and crowds along the near facades
    lights: bool = False         # light-proposal test bed (docs/proposals.md): stepped gables and dormers, shop
    #                              fronts with awnings and signs, glass office floors, varied windows and balconies,
    #                              plates on every car, cars driving ahead and oncoming, signals showing a state


#: The street variants (docs/synthetic.md): name -> features.
VARIANTS = {
    "default": _Hard(),
    "receding": _Hard(receding=True),
    "occluded_base": _Hard(occluded_base=True),
    "corner": _Hard(corner=True),
    "clutter": _Hard(clutter=True),
    "hard": _Hard(receding=True, occluded_base=True, corner=True, clutter=True),
    "busy": _Hard(busy=True),
    "canopy": _Hard(canopy=True),
    "square": _Hard(square=True),
    "shopfront": _Hard(shopfront=True),
    "hard2": _Hard(receding=True, occluded_base=True, corner=True, clutter=True, canopy=True, square=True,
                   shopfront=True),
    "lights": _Hard(occluded_base=True, lights=True),
}
_VARIANT_CODE = {name: k for k, name in enumerate(VARIANTS)}
_VARIANT_CODE["lights"] = 101  # fixed, so its layout does not depend on the variants listed before it


def check_variant(variant: str) -> str:
    """``variant`` if it names a street variant, else a ValueError listing the names."""
    if variant not in VARIANTS:
        raise ValueError(f"unknown street variant {variant!r}; choose one of {', '.join(VARIANTS)}")
    return variant


@dataclass
class StreetLayout:
    """Primitives and light bookkeeping of one street."""

    prims: Primitives
    groups: dict[int, list[int]]          # group id -> member light ids (before visibility filtering)
    far_z: float
    info: dict = field(default_factory=dict)
    #: Sun azimuth (deg, from +z toward +x) and elevation (deg); the sun is always to the left-front.
    sun: tuple[float, float] = (-35.0, 38.0)


class _Ids:
    """Allocates ``classId*1000 + index`` ids per class."""

    def __init__(self) -> None:
        self.next: dict[int, int] = {}

    def new(self, class_id: int) -> int:
        k = self.next.get(class_id, 1)
        if k >= 1000:
            raise RuntimeError(f"light class {class_id}: more than 999 instances in the synthetic street")
        self.next[class_id] = k + 1
        return class_id * 1000 + k


def _jitter(rng: np.random.Generator, color, amount: float = 0.06) -> np.ndarray:
    c = np.asarray(color) * (1.0 + rng.uniform(-amount, amount, 3))
    return np.clip(c, 0.0, 1.0)


def build_street(seed: int = 0, variant: str = "default") -> StreetLayout:
    """Lay out the street for ``seed`` and ``variant`` (pure function of both; see :data:`VARIANTS`)."""
    hard = VARIANTS[check_variant(variant)]
    rng = np.random.default_rng(seed)
    # The variants' extra objects come from their own stream, so the shared draws stay in step.
    xr = np.random.default_rng([int(seed), 7919, _VARIANT_CODE[variant]])
    P = PrimitiveList.new()
    ids = _Ids()
    groups: dict[int, list[int]] = {}
    kinds: dict[int, str] = {}  # lights variant: light id -> kind of window (facade_kind docstring)
    far_z = float(rng.uniform(95.0, 120.0))
    if hard.receding:  # a longer street, so the long blocks recede toward the vanishing point
        far_z = 150.0 + 2.0 * (far_z - 95.0)
    # Cross streets (corner variant): side -> (z0, z1) of the mouth, sidewalk corners included.
    cross: dict[int, tuple[float, float]] = {}
    if hard.corner:
        for side, (lo, hi) in ((1, (18.0, 26.0)), (-1, (30.0, 42.0))):
            z0 = float(xr.uniform(lo, hi))
            cross[side] = (z0, z0 + float(xr.uniform(13.0, 17.0)))
    # Square variant: the street (blocks, road, sidewalks, parked cars) ends at square_z, past the cross streets.
    square_z = None
    if hard.square:
        square_z = float(xr.uniform(28.0, 45.0))
        if cross:
            square_z = max(square_z, max(b for _, b in cross.values()) + 6.0)
        far_z = square_z

    # --- ground: road, markings, sidewalks (the sidewalk's inner face is the kerb)
    P.box((ROAD_X[0], -0.3, STREET_Z0), (ROAD_X[1], 0.0, far_z), ROAD, _jitter(rng, (0.13, 0.13, 0.14), 0.03))
    # Sidewalks run on under the (set-back) buildings so no gap opens at a facade's foot.
    if not cross:
        P.box((LEFT_WALK_X[0] - 15.0, -0.3, STREET_Z0), (LEFT_WALK_X[1], KERB, far_z), SIDEWALK,
              (0.42, 0.40, 0.38))
        P.box((RIGHT_WALK_X[0], -0.3, STREET_Z0), (RIGHT_WALK_X[1] + 15.0, KERB, far_z), SIDEWALK,
              (0.42, 0.40, 0.38))
    else:
        for side, (wx0, wx1) in ((-1, (LEFT_WALK_X[0] - 15.0, LEFT_WALK_X[1])),
                                 (1, (RIGHT_WALK_X[0], RIGHT_WALK_X[1] + 15.0))):
            c0, c1 = cross[side]
            for za, zb in ((STREET_Z0, c0 + 2.5), (c1 - 2.5, far_z)):  # the corners' sidewalks wrap round
                P.box((wx0, -0.3, za), (wx1, KERB, zb), SIDEWALK, (0.42, 0.40, 0.38))
            _cross_street(P, xr, side, c0, c1)
    mark_x = -1.2
    z = float(rng.uniform(2.0, 6.0))
    while z < far_z - 3.0:
        P.rect(1, 0.002, (mark_x - 0.06, z), (mark_x + 0.06, z + 3.0), ROAD, (0.75, 0.75, 0.72))
        z += 9.0

    # --- facades on both sides, then the far building closing the street
    facades: dict[int, list[tuple[float, float, float]]] = {-1: [], 1: []}  # side -> (z0, z1, facade x)
    for side in (-1, 1):
        facade_x0 = LEFT_WALK_X[0] if side < 0 else RIGHT_WALK_X[1]
        z = STREET_Z0
        first = True
        corner = False
        while z < far_z:
            w = float(rng.uniform(12.0, 26.0))
            if hard.receding:
                w = 40.0 + (w - 12.0) * 50.0 / 14.0   # long blocks: 40-90 m
            z1 = min(z + w, far_z)
            if far_z - z1 < 6.0:
                z1 = far_z
            if side in cross and z < cross[side][0] < z1:
                z1 = cross[side][0]                    # the block ends at the cross street
            h = float(rng.uniform(8.0, 20.0))
            if hard.receding:
                h += 4.0
            setback = 0.0 if first else float(rng.uniform(0.0, 0.8))
            first = False
            if corner:
                setback = 0.0
            fx = facade_x0 + side * setback            # facade plane, faces the street
            back = fx + side * (22.0 if corner else 12.0)
            col = _jitter(rng, FACADE_COLORS[int(rng.integers(len(FACADE_COLORS)))])
            P.box((min(fx, back), 0.0, z), (max(fx, back), h, z1), BUILDING, col)
            facades[side].append((z, z1, fx))
            # Very long streets: no panes on the far blocks (sub-pixel there, and ids stay < 1000).
            shop = bool(rng.random() < 0.6)
            if not (hard.receding and z > 90.0):
                _facade_windows(P, rng, ids, groups, axis=0, plane=fx, out=-side, along=(z, z1), height=h,
                                ground_shop=shop, style=xr if hard.lights else None, kinds=kinds)
            if corner:  # the corner building's second facade faces the camera across the cross street
                _facade_windows(P, xr, ids, groups, axis=2, plane=z, out=-1,
                                along=(min(fx, back), max(fx, back)), height=h, ground_shop=True)
            corner = False
            z = z1
            if side in cross and abs(z - cross[side][0]) < 1e-9:
                z = cross[side][1]                     # skip the cross street's mouth
                corner = True
    # Low enough that sky shows above it (the image top is only ~11 deg above the horizon).
    far_h = float(rng.uniform(9.0, 15.0))
    PF = P if square_z is None else PrimitiveList.new()  # (square: no far building; same draws)
    PF.box((-45.0, 0.0, far_z), (45.0, far_h, far_z + 15.0), BUILDING,
           _jitter(rng, FACADE_COLORS[int(rng.integers(len(FACADE_COLORS)))]))
    _facade_windows(PF, rng, ids, groups, axis=2, plane=far_z, out=-1, along=(-25.0, 25.0), height=far_h,
                    ground_shop=True)

    # --- advertisement panels above the shop windows: one on a right-hand facade (often hidden by
    # trees), one on the far building facing the camera (always in view)
    az = float(rng.uniform(27.0, 45.0))  # the right facade enters the view at z ~ 23 m
    z0, z1, fx = next((f for f in facades[1] if f[0] <= az < f[1]), None) or \
        min(facades[1], key=lambda f: abs(f[0] - az))  # (in the cross street's mouth: the corner building)
    az = min(max(az, z0 + 0.3), z1 - 3.5)
    P.rect(0, fx, (2.95, az), (3.75, az + 3.2), BUILDING, (0.7, 0.15, 0.1), "lamp",
           light=ids.new(ADVERTISEMENT), out=-1)
    ax = float(rng.uniform(-4.0, 1.0))
    PF.rect(2, far_z, (ax, 3.0), (ax + 4.0, 3.9), BUILDING, (0.85, 0.75, 0.2), "lamp",
           light=ids.new(ADVERTISEMENT), out=-1)

    # --- parked cars in the parking strips
    n_cars = 0
    # Occupancy varies per side and seed; gaps keep the sidewalk and kerb visible between cars.
    for side, x_in, x_out, p_forward in ((-1, -3.8, -5.85, 0.4), (1, 2.35, 4.35, 0.85)):
        occupancy = float(rng.uniform(0.35, 0.8))
        if hard.occluded_base:
            occupancy = 0.85 + (occupancy - 0.35) * 0.25   # near-continuous rows: 0.85-0.96
        z = float(rng.uniform(4.0, 9.0) if side > 0 else rng.uniform(5.0, 16.0))
        while z < far_z - 12.0:
            length = float(rng.uniform(3.9, 4.8))
            if rng.random() < occupancy and not _in_mouth(cross, side, z, z + length):
                _car(P, rng, ids, groups, x_lo=min(x_in, x_out) + 0.05, x_hi=max(x_in, x_out) - 0.05,
                     z0=z, length=length, forward=bool(rng.random() < p_forward), plate=xr if hard.lights else None)
                n_cars += 1
            gap = float(rng.uniform(0.8, 4.0))
            if hard.occluded_base:
                gap = 0.6 + (gap - 0.8) * 0.45   # 0.6-2.0 m
            z += length + gap

    # --- street lights (poles with arms over the road), trees between them
    pole_zs = []
    for side, px in ((-1, LEFT_WALK_X[1] - 0.4), (1, RIGHT_WALK_X[0] + 0.4)):
        spacing = float(rng.uniform(22.0, 30.0))
        z = float(rng.uniform(8.0, 16.0))
        while z < far_z - 8.0:
            if not _in_mouth(cross, side, z - 0.5, z + 0.5):
                _street_light(P, ids, px, z, toward=-side)
            pole_zs.append((side, z))
            tz = z + spacing * 0.5
            if tz < far_z - 6.0:
                if not _in_mouth(cross, side, tz - 2.0, tz + 2.0):
                    _tree(P, rng, px + side * 1.2, tz)
                else:
                    _tree(PrimitiveList.new(), rng, px + side * 1.2, tz)  # same draws, nothing placed
                pole_zs.append((side, tz))
            z += spacing

    # --- a traffic light and a traffic sign on the right sidewalk, clear of the lamp poles
    tl_z = _free_z(rng, pole_zs, 1, (26.0, 40.0))
    if _in_mouth(cross, 1, tl_z, tl_z) and cross[1][0] + 2.5 <= tl_z <= cross[1][1] - 2.5:
        tl_z = cross[1][0] + 1.2  # at a crossing: on the near corner's sidewalk, not in the cross road
    tl_group = ids.new(TRAFFIC_LIGHT_GROUP)
    tl_state = ("red", "amber", "green")[int(xr.choice(3, p=[0.45, 0.1, 0.45]))] if hard.lights else None
    groups[tl_group] = _traffic_light(P, ids, RIGHT_WALK_X[0] + 0.45, tl_z, state=tl_state)
    sign_z = _free_z(rng, pole_zs + [(1, tl_z)], 1, (12.0, 22.0))
    _traffic_sign(P, rng, RIGHT_WALK_X[0] + 0.35, sign_z)
    # Hedges (vegetation) along the left facade's first metres.
    hz = float(rng.uniform(5.0, 12.0))
    P.box((LEFT_WALK_X[0] + 0.05, KERB, hz), (LEFT_WALK_X[0] + 1.0, KERB + 0.9, hz + float(rng.uniform(4, 8))),
          VEGETATION, _jitter(rng, (0.08, 0.20, 0.05)), "foliage")

    sun = (float(rng.uniform(-55.0, -20.0)), float(rng.uniform(30.0, 55.0)))
    n_people = 0
    if hard.occluded_base:
        _hedges(P, xr, facades, far_z, cross)
        n_people = _people(P, xr, facades, far_z, cross)
    if hard.clutter:
        _clutter(P, xr, facades, far_z, cross)
    busy = _busy(P, xr, far_z) if hard.busy else {}
    if hard.lights:
        busy.update(_light_extras(P, xr, ids, groups, pole_zs + [(1, sign_z)], tl_z, tl_state))
        busy["traffic_light_states"] = {str(g): busy.get("pedestrian_signals", {}).get(str(g), tl_state)
                                        for g, m in groups.items() if g // 1000 == TRAFFIC_LIGHT_GROUP}
        busy["light_kinds"] = {str(k): v for k, v in sorted(kinds.items())}
    if hard.shopfront:
        busy["shop_people"] = _shopfront(P, xr, facades, far_z, cross)
    if hard.canopy:
        busy["canopy_trees"] = _canopy(P, xr, far_z, cross)
    if hard.square:
        busy["square_z"] = round(square_z, 2)
        busy["square_buildings"] = _square(P, xr, ids, groups, square_z)
    info = {"cars": n_cars, "far_z": round(far_z, 2), "primitives": len(P.lo),
            "sun_azimuth_deg": round(sun[0], 1), "sun_elevation_deg": round(sun[1], 1)}
    if variant != "default":
        info = {"variant": variant, **info, "people": n_people,
                "cross_streets": {("left" if k < 0 else "right"): [round(a, 2), round(b, 2)]
                                  for k, (a, b) in cross.items()}, **busy}
    return StreetLayout(prims=P.arrays(), groups=groups, far_z=far_z, sun=sun, info=info)


def _in_mouth(cross: dict, side: int, z0: float, z1: float) -> bool:
    """Whether [z0, z1] on ``side`` overlaps that side's cross-street mouth (corner variant)."""
    return side in cross and z1 > cross[side][0] and z0 < cross[side][1]


def _facade_at(facades: dict, side: int, z: float) -> float | None:
    """The x of ``side``'s facade plane at ``z`` (None in a cross street's mouth)."""
    for z0, z1, fx in facades[side]:
        if z0 <= z < z1:
            return fx
    return None


def _cross_street(P: PrimitiveList, rng: np.random.Generator, side: int, z0: float, z1: float) -> None:
    """A cross street leaving the main street on ``side`` between z0 and z1 (sidewalk corners included).

    Its road runs out to |x| = 70 m; a building closes it there, so no sky shows through the mouth
    below the roof lines. The corner buildings themselves are the facade blocks either side of it.
    """
    x_in = RIGHT_WALK_X[0] if side > 0 else LEFT_WALK_X[1]
    x_far = side * 70.0
    P.box((min(x_in, x_far), -0.3, z0 + 2.5), (max(x_in, x_far), 0.0, z1 - 2.5), ROAD,
          _jitter(rng, (0.13, 0.13, 0.14), 0.03))
    h = float(rng.uniform(10.0, 18.0))
    P.box((min(x_far - side * 25.0, x_far), 0.0, z0 - 20.0), (max(x_far - side * 25.0, x_far), h, z1 + 20.0),
          BUILDING, _jitter(rng, FACADE_COLORS[int(rng.integers(len(FACADE_COLORS)))]))


def _hedges(P: PrimitiveList, rng: np.random.Generator, facades: dict, far_z: float, cross: dict) -> None:
    """Hedges against the facades' feet (0.9-1.4 m tall, 0.6-1.0 m deep) along stretches of the street."""
    for side in (-1, 1):
        z = float(rng.uniform(3.0, 8.0))
        while z < far_z - 10.0:
            length = float(rng.uniform(6.0, 18.0))
            fx = _facade_at(facades, side, z)
            fx1 = _facade_at(facades, side, z + length)
            if fx is not None and fx1 == fx and not _in_mouth(cross, side, z, z + length):
                depth = float(rng.uniform(0.6, 1.0))
                top = KERB + float(rng.uniform(0.9, 1.4))
                P.box((fx - side * depth, KERB, z), (fx, top, z + length), VEGETATION,
                      _jitter(rng, (0.07, 0.18, 0.05), 0.2), "foliage")
            z += length + float(rng.uniform(2.0, 10.0))


def _people(P: PrimitiveList, rng: np.random.Generator, facades: dict, far_z: float, cross: dict) -> int:
    """People-sized boxes (person, 0.5 x 1.6-1.9 x 0.35 m) on both sidewalks, most near the facades."""
    n = 0
    for side in (-1, 1):
        walk = LEFT_WALK_X if side < 0 else RIGHT_WALK_X
        z = float(rng.uniform(4.0, 8.0))
        while z < min(far_z - 10.0, 80.0):
            fx = _facade_at(facades, side, z)
            if fx is not None and not _in_mouth(cross, side, z - 0.5, z + 0.5):
                if rng.random() < 0.6:   # near the facade (in front of any hedge)
                    x = fx - side * float(rng.uniform(1.3, 2.0))
                else:
                    x = float(rng.uniform(walk[0] + 0.5, walk[1] - 0.5))
                tall = float(rng.uniform(1.6, 1.9))
                col = _jitter(rng, CLOTHES[int(rng.integers(len(CLOTHES)))], 0.2)
                P.box((x - 0.25, KERB, z - 0.17), (x + 0.25, KERB + tall, z + 0.17), PERSON, col)
                n += 1
            z += float(rng.uniform(3.0, 9.0))
    return n


def _clutter(P: PrimitiveList, rng: np.random.Generator, facades: dict, far_z: float, cross: dict) -> None:
    """Poles, bollards, sign posts and slim trees standing 0.5-2.5 m in front of the facades."""
    grey = (0.35, 0.36, 0.37)
    for side in (-1, 1):
        z = float(rng.uniform(4.0, 7.0))
        while z < min(far_z - 10.0, 90.0):
            fx = _facade_at(facades, side, z)
            if fx is not None and not _in_mouth(cross, side, z - 1.5, z + 1.5):
                kind = int(rng.integers(4))
                x = fx - side * float(rng.uniform(0.5, 2.5))
                if kind == 0:    # tall pole
                    r = float(rng.uniform(0.06, 0.12))
                    P.box((x - r, KERB, z - r), (x + r, KERB + float(rng.uniform(4.0, 7.0)), z + r), POLE, grey,
                          "metal")
                elif kind == 1:  # bollards
                    for k in range(3):
                        P.box((x - 0.08, KERB, z + 1.2 * k - 0.08), (x + 0.08, KERB + 0.9, z + 1.2 * k + 0.08),
                              POLE, grey, "metal")
                elif kind == 2:  # sign post with a plate facing the camera
                    P.box((x - 0.04, KERB, z - 0.04), (x + 0.04, KERB + 2.6, z + 0.04), POLE, grey, "metal")
                    P.box((x - 0.3, KERB + 2.0, z - 0.06), (x + 0.3, KERB + 2.6, z - 0.04), TRAFFIC_SIGN,
                          (0.02, 0.10, 0.45), "metal")
                else:            # slim tree
                    x = fx - side * float(rng.uniform(1.5, 2.5))
                    P.box((x - 0.1, KERB, z - 0.1), (x + 0.1, 2.2, z + 0.1), VEGETATION, (0.12, 0.08, 0.05),
                          "foliage")
                    r = float(rng.uniform(0.8, 1.2))
                    P.box((x - r, 2.0, z - r), (x + r, 2.0 + float(rng.uniform(2.0, 3.5)), z + r), VEGETATION,
                          _jitter(rng, (0.07, 0.16, 0.04), 0.25), "foliage")
            z += float(rng.uniform(4.0, 9.0))


def _shopfront(P: PrimitiveList, rng: np.random.Generator, facades: dict, far_z: float, cross: dict) -> int:
    """Shopfront variant: glazed ground floors (0.2-3.0 m), awnings 1.2-2.2 m deep at 2.6-2.9 m and crowds
    (1-2 rows of people 0.3-2.6 m in front) along every facade block that starts before z = 60 m.

    The glazing is a glass rectangle on the facade (labelled building, as Cityscapes labels shop windows);
    awnings are building-labelled slabs with a front valance. Returns the number of people.
    """
    n = 0
    glass = GLASS_BUILDING[0]
    for side in (-1, 1):
        for z0, z1, fx in facades[side]:
            if z0 >= 60.0:
                continue
            a0, a1 = z0 + 0.4, min(z1, 80.0) - 0.4
            if a1 - a0 < 2.0:
                continue
            P.rect(0, fx, (0.2, a0), (3.0, a1), BUILDING, glass, "glass", out=-side)
            za = a0
            while za < a1 - 1.5:                                   # awnings over stretches of 4-12 m
                zb = min(a1, za + float(rng.uniform(4.0, 12.0)))
                if rng.random() < 0.75:
                    dep = float(rng.uniform(1.2, 2.2))
                    y0 = float(rng.uniform(2.6, 2.9))
                    col = _jitter(rng, FACADE_COLORS[int(rng.integers(len(FACADE_COLORS)))], 0.3)
                    xo = fx - side * dep
                    P.box((min(fx, xo), y0, za), (max(fx, xo), y0 + 0.12, zb), BUILDING, col)
                    P.box((min(xo, xo + side * 0.05), y0 - 0.3, za), (max(xo, xo + side * 0.05), y0 + 0.12, zb),
                          BUILDING, col)
                za = zb + float(rng.uniform(0.3, 2.0))
            z = a0 + float(rng.uniform(0.0, 1.0))
            while z < min(a1, 60.0):                               # the crowd: 1-2 rows along the base
                if not _in_mouth(cross, side, z - 0.5, z + 0.5):
                    for row in range(int(rng.integers(1, 3))):
                        x = fx - side * (float(rng.uniform(0.3, 1.2)) + 1.1 * row)
                        _person(P, rng, x, z + float(rng.uniform(-0.3, 0.3)), KERB)
                        n += 1
                z += float(rng.uniform(0.6, 2.0))
    return n


def _canopy(P: PrimitiveList, rng: np.random.Generator, far_z: float, cross: dict) -> int:
    """Canopy variant: large street trees every 9-15 m on both sidewalks (up to z = 75 m), trunks 1.0-1.6 m
    from the kerb, crowns 4.4-6.4 m wide from 2.1-2.5 m up (over the sidewalk and the parking strip), each
    trunk hidden from the camera by a group of people, a bus shelter (labelled building, as Cityscapes
    does), a van in the parking strip (labelled car) or a sign board. Returns the number of trees."""
    n = 0
    for side in (-1, 1):
        kerb = ROAD_X[0] if side < 0 else ROAD_X[1]
        z = float(rng.uniform(7.0, 12.0))
        while z < min(far_z - 10.0, 75.0):
            if _in_mouth(cross, side, z - 3.5, z + 3.5):
                z += float(rng.uniform(9.0, 15.0))
                continue
            xt = kerb + side * float(rng.uniform(1.0, 1.6))
            rt = float(rng.uniform(0.15, 0.2))
            yb = float(rng.uniform(2.1, 2.5))
            top = yb + float(rng.uniform(3.5, 5.5))
            rc = float(rng.uniform(2.2, 3.2))
            green = _jitter(rng, (0.06, 0.15, 0.04), 0.25)
            P.box((xt - rt, KERB, z - rt), (xt + rt, yb + 0.2, z + rt), VEGETATION, (0.12, 0.08, 0.05), "foliage")
            P.box((xt - rc, yb, z - rc), (xt + rc, top - 1.0, z + rc), VEGETATION, green, "foliage")
            P.box((xt - 0.7 * rc, top - 1.0, z - 0.7 * rc), (xt + 0.7 * rc, top, z + 0.7 * rc), VEGETATION,
                  green * 0.9, "foliage")
            n += 1

            def on_ray(zq):  # the x at which the camera's ray to the trunk passes z = zq
                return xt * zq / z

            kind = int(rng.integers(4))
            if kind == 0:      # people in front of the trunk, on its ray
                zp = z - float(rng.uniform(0.8, 1.5))
                for dx in (0.0, -0.45, 0.45)[:int(rng.integers(2, 4))]:
                    _person(P, rng, on_ray(zp) + dx, zp + float(rng.uniform(-0.2, 0.2)), KERB)
            elif kind == 1:    # a bus shelter: roof, end panels (glass), back panel, trunk behind it
                L = float(rng.uniform(3.5, 4.5))
                za, zb = z - 0.5 - L, z - 0.5
                xc = on_ray(0.5 * (za + zb))
                x0, x1 = xc - 0.9, xc + 0.9
                col = (0.30, 0.32, 0.33)
                P.box((x0, 2.45, za), (x1, 2.6, zb), BUILDING, col, "metal")
                for zz in (za, zb):
                    P.box((x0, KERB + 0.1, zz), (x1, 2.45, zz + 0.04), BUILDING, (0.10, 0.12, 0.13), "glass")
                xb = x1 if side > 0 else x0
                P.box((xb - 0.02, KERB + 0.1, za), (xb + 0.02, 2.45, zb), BUILDING, (0.10, 0.12, 0.13), "glass")
            elif kind == 2:    # a van in the parking strip, where the trunk's ray crosses it
                xa, xb = (2.45, 4.25) if side > 0 else (-5.75, -3.95)
                zc = z * 0.5 * (xa + xb) / xt
                L = float(rng.uniform(4.8, 5.6))
                tall = float(rng.uniform(2.1, 2.5))
                paint = _jitter(rng, CAR_COLORS[int(rng.integers(len(CAR_COLORS)))], 0.04)
                P.box((xa, 0.3, zc - L / 2), (xb, tall, zc + L / 2), CAR, paint, "paint")
                for wz in (zc - L / 2 + 0.8, zc + L / 2 - 0.8):
                    for wx0, wx1 in ((xa - 0.02, xa + 0.22), (xb - 0.22, xb + 0.02)):
                        P.box((wx0, 0.0, wz - 0.33), (wx1, 0.64, wz + 0.33), CAR, (0.02, 0.02, 0.02))
            else:              # a sign board on two legs, 0.8 m in front of the trunk
                zs_ = z - 0.8
                xc = on_ray(zs_)
                for dx in (-0.4, 0.4):
                    P.box((xc + dx - 0.03, KERB, zs_ - 0.03), (xc + dx + 0.03, 0.4, zs_ + 0.03), POLE,
                          (0.35, 0.36, 0.37), "metal")
                col = [(0.02, 0.10, 0.45), (0.65, 0.50, 0.02), (0.9, 0.9, 0.88)][int(rng.integers(3))]
                P.box((xc - 0.5, 0.4, zs_ - 0.02), (xc + 0.5, 2.5, zs_ + 0.02), TRAFFIC_SIGN, col, "metal")
            z += float(rng.uniform(9.0, 15.0))
    return n


def _square(P: PrimitiveList, rng: np.random.Generator, ids: _Ids, groups: dict, z0: float) -> int:
    """Square variant: beyond z0 a 12 m cross road, then a paved square (sidewalk, kerb high) with the main
    road running on through it; across it a row of blocks whose fronts stand 40-150 m from the camera
    (12-32 m tall, windows on the nearer ones), blocks along the square's sides at |x| 28-45 m, a closing
    wall at z 200 m, and people, trees and lamp posts on the square. Returns the number of blocks."""
    road = _jitter(rng, (0.13, 0.13, 0.14), 0.03)
    paving = (0.42, 0.40, 0.38)
    zc1 = z0 + 12.0
    P.box((-250.0, -0.3, z0), (250.0, 0.0, zc1), ROAD, road)                 # the cross road
    P.box((ROAD_X[0], -0.3, zc1), (ROAD_X[1], 0.0, 260.0), ROAD, road)       # the main road runs on
    P.box((-250.0, -0.3, zc1), (ROAD_X[0], KERB, 260.0), SIDEWALK, paving)
    P.box((ROAD_X[1], -0.3, zc1), (250.0, KERB, 260.0), SIDEWALK, paving)
    n = 0
    x = -200.0
    while x < 200.0:                                                         # blocks across the square
        w = float(rng.uniform(15.0, 35.0))
        zf = float(rng.uniform(max(40.0, z0 + 20.0), 150.0))
        h = float(rng.uniform(12.0, 32.0))
        col = _jitter(rng, FACADE_COLORS[int(rng.integers(len(FACADE_COLORS)))])
        P.box((x, KERB, zf), (x + w, h, zf + 20.0), BUILDING, col)
        if zf < 100.0 and abs(x + w / 2) < 60.0:
            _facade_windows(P, rng, ids, groups, axis=2, plane=zf, out=-1, along=(x, x + w), height=h,
                            ground_shop=True)
        n += 1
        x += w
    for side in (-1, 1):                                                     # the square's sides
        xs = side * float(rng.uniform(28.0, 45.0))
        z = zc1 + 2.0
        while z < 150.0:
            L = float(rng.uniform(15.0, 30.0))
            h = float(rng.uniform(12.0, 25.0))
            P.box((min(xs, xs + side * 15.0), KERB, z), (max(xs, xs + side * 15.0), h, z + L), BUILDING,
                  _jitter(rng, FACADE_COLORS[int(rng.integers(len(FACADE_COLORS)))]))
            n += 1
            z += L
    P.box((-400.0, KERB, 200.0), (400.0, 30.0, 215.0), BUILDING, (0.5, 0.5, 0.52))   # closes every ray
    for _ in range(int(rng.integers(4, 9))):                                  # people on the square
        side = 1 if rng.random() < 0.5 else -1
        _person(P, rng, side * float(rng.uniform(6.0, 25.0)), float(rng.uniform(zc1 + 2.0, z0 + 45.0)), KERB)
    for _ in range(int(rng.integers(2, 5))):                                  # trees on the square
        side = 1 if rng.random() < 0.5 else -1
        _tree(P, rng, side * float(rng.uniform(7.0, 25.0)), float(rng.uniform(zc1 + 4.0, z0 + 40.0)))
    for side in (-1, 1):                                                      # lamp posts along the main road
        z = zc1 + float(rng.uniform(3.0, 8.0))
        while z < 120.0:
            px = (ROAD_X[0] - 0.5) if side < 0 else (ROAD_X[1] + 0.5)
            P.box((px - 0.08, KERB, z - 0.08), (px + 0.08, 6.0, z + 0.08), POLE, (0.32, 0.33, 0.34), "metal")
            z += float(rng.uniform(20.0, 30.0))
    return n


SKIN = [(0.45, 0.30, 0.22), (0.30, 0.20, 0.14), (0.55, 0.42, 0.34)]
#: The ego vehicle's bonnet: top face height (m, world), front edge z = EGO_EDGE_Z - EGO_EDGE_CURVE * x^2.
EGO_TOP_Y, EGO_EDGE_Z, EGO_EDGE_CURVE = 1.0, 0.97, 0.65


def _busy(P: PrimitiveList, rng: np.random.Generator, far_z: float) -> dict:
    """The ``busy`` variant's objects: pedestrians on both sidewalks and two crossing the road
    8-15 m ahead, riders on bicycles in the right lane, an oncoming truck or bus in the left lane,
    and the ego vehicle's hood. Returns the counts for the layout summary."""
    n_walk = 0
    for side, (x0, x1) in ((-1, (-9.7, -8.3)), (1, (7.0, 8.8))):   # clear of hedges, poles, trees
        z = float(rng.uniform(5.0, 9.0))
        while z < min(far_z - 10.0, 60.0):
            _person(P, rng, float(rng.uniform(x0, x1)), z, KERB)
            n_walk += 1
            z += float(rng.uniform(4.0, 10.0))
    n_cross = 0
    for z in sorted(float(v) for v in rng.uniform(8.0, 15.0, 2)):   # crossing in the ego headlights
        _person(P, rng, float(rng.uniform(-2.5, 1.5)), z, 0.0)
        n_cross += 1
    n_riders = int(rng.integers(1, 3))
    z = float(rng.uniform(9.0, 14.0))
    for _ in range(n_riders):
        _rider(P, rng, float(rng.uniform(1.2, 1.9)), z)
        z += float(rng.uniform(6.0, 14.0))
    kind = "bus" if rng.random() < 0.4 else "truck"
    _big_vehicle(P, rng, float(rng.uniform(-3.5, -3.1)), float(rng.uniform(24.0, 34.0)), kind)
    _ego_hood(P)
    return {"pedestrians": n_walk + n_cross, "crossing": n_cross, "riders": n_riders, kind: 1, "ego_hood": True}


def _person(P: PrimitiveList, rng: np.random.Generator, x: float, z: float, y0: float) -> None:
    """A pedestrian (labelId 24) standing at (x, y0, z): legs, torso and head boxes, 1.6-1.9 m tall."""
    tall = float(rng.uniform(1.6, 1.9))
    top = _jitter(rng, CLOTHES[int(rng.integers(len(CLOTHES)))], 0.2)
    legs = _jitter(rng, CLOTHES[int(rng.integers(len(CLOTHES)))], 0.2)
    skin = SKIN[int(rng.integers(len(SKIN)))]
    P.box((x - 0.17, y0, z - 0.12), (x + 0.17, y0 + 0.47 * tall, z + 0.12), PERSON, legs)
    P.box((x - 0.23, y0 + 0.47 * tall, z - 0.14), (x + 0.23, y0 + 0.87 * tall, z + 0.14), PERSON, top)
    P.box((x - 0.1, y0 + 0.87 * tall, z - 0.11), (x + 0.1, y0 + tall, z + 0.11), PERSON, skin)


def _rider(P: PrimitiveList, rng: np.random.Generator, x: float, z: float) -> None:
    """A bicycle (labelId 33) riding along +z with its rider (labelId 25); wheel base 1.05 m."""
    frame = _jitter(rng, CAR_COLORS[int(rng.integers(len(CAR_COLORS)))], 0.1)
    tyre = (0.03, 0.03, 0.03)
    for zc in (z, z + 1.05):                                   # wheels: a tyre cross seen from behind
        P.box((x - 0.02, 0.0, zc - 0.33), (x + 0.02, 0.66, zc + 0.33), BICYCLE, tyre, "metal")
    P.box((x - 0.03, 0.42, z), (x + 0.03, 0.62, z + 1.05), BICYCLE, frame, "metal")
    P.box((x - 0.3, 0.98, z + 0.95), (x + 0.3, 1.02, z + 1.0), BICYCLE, (0.2, 0.2, 0.2), "metal")  # handlebar
    top = _jitter(rng, CLOTHES[int(rng.integers(len(CLOTHES)))], 0.2)
    P.box((x - 0.17, 0.35, z + 0.3), (x + 0.17, 0.95, z + 0.55), RIDER, (0.08, 0.08, 0.1))          # legs
    P.box((x - 0.22, 0.95, z + 0.3), (x + 0.22, 1.55, z + 0.62), RIDER, top)                         # torso
    P.box((x - 0.1, 1.55, z + 0.4), (x + 0.1, 1.8, z + 0.62), RIDER, SKIN[int(rng.integers(len(SKIN)))])


def _big_vehicle(P: PrimitiveList, rng: np.random.Generator, x0: float, z0: float, kind: str) -> None:
    """An oncoming truck (labelId 27: cab + box body) or bus (28) in the left lane, front at z0."""
    paint = _jitter(rng, CAR_COLORS[int(rng.integers(len(CAR_COLORS)))], 0.05)
    label, w = (BUS, 2.5) if kind == "bus" else (TRUCK, 2.4)
    x1 = x0 + w
    if kind == "bus":
        P.box((x0, 0.35, z0), (x1, 3.1, z0 + 11.5), label, paint, "paint")
    else:
        P.box((x0 + 0.05, 0.5, z0), (x1 - 0.05, 2.9, z0 + 2.1), label, paint, "paint")        # cab
        P.box((x0, 0.9, z0 + 2.3), (x1, 3.7, z0 + 9.0), label, _jitter(rng, (0.7, 0.7, 0.68)), "paint")
    for wz in (z0 + 1.2, z0 + 7.5):
        for wx0, wx1 in ((x0 - 0.02, x0 + 0.3), (x1 - 0.3, x1 + 0.02)):
            P.box((wx0, 0.0, wz - 0.5), (wx1, 1.0, wz + 0.5), label, (0.02, 0.02, 0.02))


def _ego_hood(P: PrimitiveList) -> None:
    """The ego vehicle's bonnet (labelId 1) in front of and below the camera, with a chrome emblem.

    Strips 2.5 cm wide whose front edges follow ``z = EGO_EDGE_Z - EGO_EDGE_CURVE x^2``: the
    top face (y = EGO_TOP_Y) fills about the bottom 8 % of the rows at the image centre and 3 %
    at the sides, like the bonnet in every Cityscapes frame.
    """
    paint = (0.03, 0.032, 0.036)
    xs = np.arange(-0.75, 0.75 + 1e-9, 0.025)
    for a, b in zip(xs[:-1], xs[1:]):
        xm = 0.5 * (a + b)
        P.box((a, 0.45, 0.25), (b, EGO_TOP_Y, EGO_EDGE_Z - EGO_EDGE_CURVE * xm * xm), EGO_VEHICLE, paint, "paint")
    ez = EGO_EDGE_Z - 0.09
    P.box((-0.012, EGO_TOP_Y, ez - 0.012), (0.012, EGO_TOP_Y + 0.012, ez), EGO_VEHICLE, (0.75, 0.75, 0.72), "metal")


def frame_border_labels(width: int, height: int) -> np.ndarray:
    """(H, W) uint8: Cityscapes' image-space border labels, 0 elsewhere.

    ``RECTIFICATION_BORDER`` (2) in the four corners the rectification leaves without data
    (outside the ellipse ``(x/1.0)^2 + (y/1.0)^2 = 1.9`` in coordinates normalised to the
    half-size) and ``OUT_OF_ROI`` (3) on a frame 0.6 % of the width wide on the left, right and
    top borders. The busy variant's day image is black on the rectification border.
    """
    u = (np.arange(width) + 0.5) / width * 2.0 - 1.0
    v = (np.arange(height) + 0.5) / height * 2.0 - 1.0
    out = np.zeros((height, width), np.uint8)
    b = max(1, int(round(0.006 * width)))
    out[:, :b] = OUT_OF_ROI
    out[:, width - b:] = OUT_OF_ROI
    out[:b, :] = OUT_OF_ROI
    out[(u[None, :] ** 2 + v[:, None] ** 2) > 1.9] = RECTIFICATION_BORDER
    return out


def _free_z(rng: np.random.Generator, taken: list, side: int, rng_z: tuple[float, float]) -> float:
    for _ in range(50):
        z = float(rng.uniform(*rng_z))
        if all(abs(z - tz) > 4.5 for s, tz in taken if s == side):
            return z
    return float(rng_z[1])


def _facade_windows(P: PrimitiveList, rng: np.random.Generator, ids: _Ids, groups: dict, *, axis: int,
                    plane: float, out: int, along: tuple[float, float], height: float, ground_shop: bool,
                    style: np.random.Generator | None = None, kinds: dict | None = None) -> None:
    """Rows of window panes on a facade (``axis`` 0: facade x = const, runs along z; 2: z = const, runs along x).

    Each floor's panes form one windows_group. With ``style`` (the lights variant's stream) the
    facade takes one of :func:`_styled_facade`'s kinds instead, and ``kinds`` records each light's kind.
    """
    a0, a1 = along
    span = a1 - a0
    win_w = float(rng.uniform(1.0, 1.5))
    win_h = float(rng.uniform(1.3, 1.8))
    pitch = float(rng.uniform(2.4, 3.2))
    glass = GLASS_BUILDING[int(rng.integers(len(GLASS_BUILDING)))]
    n = int((span - 1.5) // pitch)
    if n < 1:
        return
    start = a0 + (span - n * pitch) / 2.0 + (pitch - win_w) / 2.0
    if style is not None:
        _styled_facade(P, style, ids, groups, kinds if kinds is not None else {}, axis=axis, plane=plane, out=out,
                       height=height, ground_shop=ground_shop, n=n, start=start, pitch=pitch, win_w=win_w,
                       win_h=win_h, glass=glass)
        return
    floors = []
    if ground_shop:
        floors.append((0.8, 2.9, 1.6))  # shop windows: sill, top, width
    y = 4.0
    while y + 1.0 + win_h < height - 0.8:
        floors.append((y + 0.9, y + 0.9 + win_h, win_w))
        y += 3.2
    for sill, top, width in floors:
        gid = ids.new(WINDOWS_GROUP)
        members = []
        for k in range(n):
            c0 = start + k * pitch
            lid = ids.new(WINDOW_BUILDING)
            color = glass
            if axis == 0:
                P.rect(0, plane, (sill, c0), (top, c0 + width), BUILDING, color, "glass", lid, out)
            else:
                P.rect(2, plane, (c0, sill), (c0 + width, top), BUILDING, color, "glass", lid, out)
            members.append(lid)
        groups[gid] = members


#: Facade kinds of the lights variant (:func:`_styled_facade`).
FACADE_KINDS = ("plain", "varied", "gable", "dormers", "office")
SIGN_COLORS = [(0.75, 0.08, 0.06), (0.05, 0.25, 0.65), (0.85, 0.70, 0.05), (0.10, 0.50, 0.15)]


def _styled_facade(P: PrimitiveList, rng: np.random.Generator, ids: _Ids, groups: dict, kinds: dict, *,
                   axis: int, plane: float, out: int, height: float, ground_shop: bool, n: int, start: float,
                   pitch: float, win_w: float, win_h: float, glass) -> None:
    """The lights variant's facades (docs/proposals.md "The synthetic street's lights"), one kind per block:

    * ``plain``: the default grid; ``varied``: widths 0.6-1.25x per bay, French windows over balcony
      slabs (1 m deep) on 30 % of the bays;
    * ``gable``: the default grid, then a stepped gable on the roof line (3 steps of 2 m) with
      3 + 2 + 1 windows (kind ``gable``, one windows_group per step);
    * ``dormers``: a mansard roof set back 1.5 m with a dormer (window kind ``dormer``) on every
      other bay;
    * ``office``: a glass curtain wall: one window_building light per floor band (kind
      ``office_band``, 2.2 m of glass per 3.4 m floor).

    Ground floors with shops get shop fronts instead of bay windows (kind ``shop``: 0.35-2.6 m glass
    over two bays), awnings (1.3 m deep, 2.55-2.9 m) on 70 % and an advertisement sign above on 60 %.
    ``kinds`` maps each light id to its kind (``window`` for the grid windows).
    """
    kind = FACADE_KINDS[int(rng.integers(len(FACADE_KINDS)))]

    def box(c0, c1, y0, y1, o0, o1, color, material="diffuse"):  # o: metres outward from the facade plane
        n0, n1 = sorted((plane + out * o0, plane + out * o1))
        if axis == 0:
            P.box((n0, y0, c0), (n1, y1, c1), BUILDING, color, material)
        else:
            P.box((c0, y0, n0), (c1, y1, n1), BUILDING, color, material)

    def pane(c0, c1, y0, y1, o, what, color=glass, cls=WINDOW_BUILDING, material="glass"):
        at, lid = plane + out * o, ids.new(cls)
        if axis == 0:
            P.rect(0, at, (y0, c0), (y1, c1), BUILDING, color, material, lid, out)
        else:
            P.rect(2, at, (c0, y0), (c1, y1), BUILDING, color, material, lid, out)
        kinds[lid] = what
        return lid

    def floor(members):
        if members:
            groups[ids.new(WINDOWS_GROUP)] = members

    a0, a1 = start - (pitch - win_w) / 2.0, start - (pitch - win_w) / 2.0 + n * pitch   # the bays' span
    if ground_shop:
        shops, k = [], 0
        while k < n:
            m = min(2, n - k)
            c0, c1 = start + k * pitch - 0.25, start + (k + m - 1) * pitch + win_w + 0.25
            shops.append(pane(c0, c1, 0.35, 2.6, 0.0, "shop"))
            if rng.random() < 0.7:
                col = _jitter(rng, FACADE_COLORS[int(rng.integers(len(FACADE_COLORS)))], 0.3)
                box(c0 - 0.15, c1 + 0.15, 2.78, 2.9, 0.0, 1.3, col)
                box(c0 - 0.15, c1 + 0.15, 2.55, 2.9, 1.25, 1.3, col)
            if rng.random() < 0.6:
                pane(c0 + 0.3, c1 - 0.3, 3.05, 3.55, 0.0, "sign", SIGN_COLORS[int(rng.integers(len(SIGN_COLORS)))],
                     ADVERTISEMENT, "lamp")
            k += m
        floor(shops)
    if kind == "office":
        tint = (0.08, 0.14, 0.18)
        y = 3.8
        while y + 3.0 < height - 0.5:
            floor([pane(a0 + 0.3, a1 - 0.3, y + 0.8, y + 3.0, 0.0, "office_band", tint)])
            y += 3.4
        return
    widths = [win_w] * n
    balcony = [False] * n
    if kind == "varied":
        widths = [float(min(pitch - 0.5, win_w * rng.uniform(0.6, 1.25))) for _ in range(n)]
        balcony = [bool(rng.random() < 0.3) for _ in range(n)]
    y = 4.0
    while y + 1.0 + win_h < height - 0.8:
        members = []
        for k in range(n):
            c = start + k * pitch + win_w / 2.0
            c0, c1 = c - widths[k] / 2.0, c + widths[k] / 2.0
            sill = y + 0.9
            if balcony[k]:
                box(c0 - 0.3, c1 + 0.3, y + 0.05, y + 0.2, 0.0, 1.0, (0.6, 0.6, 0.58))
                sill = y + 0.25
            members.append(pane(c0, c1, sill, y + 0.9 + win_h, 0.0, "window"))
        floor(members)
        y += 3.2
    c = (a0 + a1) / 2.0
    if kind == "gable" and a1 - a0 >= 7.0:
        hw = min(6.0, (a1 - a0) / 2.0 - 0.5)
        wall = _jitter(rng, FACADE_COLORS[int(rng.integers(len(FACADE_COLORS)))])
        for step in range(3):
            half = hw * (1.0 - step / 3.0)
            y0 = height + 2.0 * step
            box(c - half, c + half, y0, y0 + 2.0, -8.0, 0.0, wall)
            cnt = 3 - step
            floor([pane(c - half + (j + 0.5) * 2 * half / cnt - 0.4, c - half + (j + 0.5) * 2 * half / cnt + 0.4,
                        y0 + 0.45, y0 + 1.65, 0.0, "gable") for j in range(cnt)])
    elif kind in ("gable", "dormers"):
        roof = (0.30, 0.22, 0.20)
        box(a0 - 0.5, a1 + 0.5, height, height + 2.8, -8.0, -1.5, roof)
        members = []
        for k in range(0, n, 2):
            cc = start + k * pitch + win_w / 2.0
            box(cc - 0.7, cc + 0.7, height + 0.2, height + 2.3, -1.6, -0.6, roof)
            members.append(pane(cc - 0.45, cc + 0.45, height + 0.55, height + 1.85, -0.6, "dormer"))
        floor(members)


def _light_extras(P: PrimitiveList, rng: np.random.Generator, ids: _Ids, groups: dict, pole_zs: list,
                  tl_z: float, tl_state: str) -> dict:
    """The lights variant's road users and signals: a car driving ahead in the ego lane (moving_rear
    lamps toward the camera), an oncoming car in the left lane (moving_front), both with plates, a
    second signal on the left sidewalk showing the same state as the right one (one direction), and a
    pedestrian signal at the right kerb 7-9 m before or after the right one (its own direction: red
    while the vehicles' signal is green or amber, green while it is red; placed without a random
    draw, so the variant's other objects are unchanged)."""
    _car(P, rng, ids, groups, x_lo=-0.55, x_hi=1.65, z0=float(rng.uniform(11.0, 22.0)),
         length=float(rng.uniform(4.0, 4.6)), forward=True, plate=rng, lamp_classes=(MOVING_FRONT, MOVING_REAR))
    _car(P, rng, ids, groups, x_lo=-3.65, x_hi=-1.45, z0=float(rng.uniform(26.0, 40.0)),
         length=float(rng.uniform(4.0, 4.6)), forward=False, plate=rng, lamp_classes=(MOVING_FRONT, MOVING_REAR))
    z2 = _free_z(rng, pole_zs, -1, (24.0, 40.0))
    groups[ids.new(TRAFFIC_LIGHT_GROUP)] = _traffic_light(P, ids, LEFT_WALK_X[1] - 0.45, z2, state=tl_state)
    zp = next((z for z in (tl_z - 9.0, tl_z - 7.0, tl_z + 9.0)  # apart from the signal in the image too
               if all(abs(z - tz) > 1.5 for s_, tz in pole_zs if s_ == 1)), tl_z - 9.0)
    ped_state = "green" if tl_state == "red" else "red"
    ped = ids.new(TRAFFIC_LIGHT_GROUP)
    groups[ped] = _pedestrian_signal(P, ids, RIGHT_WALK_X[0] + 0.3, zp, state=ped_state)
    return {"moving_cars": 2, "traffic_lights": 3, "traffic_light_state": tl_state,
            "pedestrian_signals": {str(ped): ped_state}}


def _car(P: PrimitiveList, rng: np.random.Generator, ids: _Ids, groups: dict, *, x_lo: float, x_hi: float,
         z0: float, length: float, forward: bool, plate: np.random.Generator | None = None,
         lamp_classes: tuple[int, int] = (PARKED_FRONT, PARKED_REAR)) -> None:
    """A parked car: body + cabin boxes, wheels, window panes, front/rear lamps; one car_group.

    ``plate`` (the lights variant's stream): number plates (0.52 x 0.11 m, white or yellow, 2 mm
    proud of the body, centred below the lamps; never lights) front and rear. ``lamp_classes``:
    (front, rear) light classes, moving_front/moving_rear for a car driving."""
    width = float(rng.uniform(1.7, 1.9))
    xc = (x_lo + x_hi) / 2.0
    xa, xb = xc - width / 2, xc + width / 2
    z1 = z0 + length
    body_lo = 0.3
    body_top = body_lo + float(rng.uniform(0.5, 0.65))
    cab_top = body_top + float(rng.uniform(0.45, 0.58))
    paint = _jitter(rng, CAR_COLORS[int(rng.integers(len(CAR_COLORS)))], 0.04)
    P.box((xa, body_lo, z0), (xb, body_top, z1), CAR, paint, "paint")
    # Cabin sits toward the rear (bonnet is longer than the boot).
    if forward:   # front at z1
        cz0, cz1 = z0 + 0.2 * length, z1 - 0.32 * length
    else:         # front at z0
        cz0, cz1 = z0 + 0.32 * length, z1 - 0.2 * length
    ca, cb = xa + 0.1, xb - 0.1
    P.box((ca, body_top, cz0), (cb, cab_top, cz1), CAR, paint, "paint")
    for wz in (z0 + 0.75, z1 - 0.75):
        for wx0, wx1 in ((xa - 0.02, xa + 0.22), (xb - 0.22, xb + 0.02)):
            P.box((wx0, 0.0, wz - 0.32), (wx1, 0.62, wz + 0.32), CAR, (0.02, 0.02, 0.02), "diffuse")
    members = []
    gy0, gy1 = body_top + 0.07, cab_top - 0.07
    for x, out in ((ca, -1), (cb, 1)):                                   # side windows
        lid = ids.new(WINDOW_PARKED)
        P.rect(0, x, (gy0, cz0 + 0.12), (gy1, cz1 - 0.12), CAR, GLASS_CAR, "glass", lid, out)
        members.append(lid)
    for z, out in ((cz0, -1), (cz1, 1)):                                 # wind-screen and rear window
        lid = ids.new(WINDOW_PARKED)
        P.rect(2, z, (ca + 0.08, gy0), (cb - 0.08, gy1), CAR, GLASS_CAR, "glass", lid, out)
        members.append(lid)
    front, rear = ((z1, 1), (z0, -1)) if forward else ((z0, -1), (z1, 1))
    ly0, ly1 = body_top - 0.22, body_top - 0.07
    if plate is not None:
        for z, out in (front, rear):
            col = (0.82, 0.82, 0.78) if plate.random() < 0.7 else (0.80, 0.66, 0.12)
            zp = z + out * 0.002
            P.box((xc - 0.26, body_lo + 0.12, min(z, zp)), (xc + 0.26, body_lo + 0.23, max(z, zp)), CAR, col)
    for cls, (z, out), col in ((lamp_classes[0], front, (0.75, 0.75, 0.72)),
                               (lamp_classes[1], rear, (0.45, 0.03, 0.02))):
        for lx0, lx1 in ((xa + 0.08, xa + 0.38), (xb - 0.38, xb - 0.08)):
            lid = ids.new(cls)
            P.rect(2, z, (lx0, ly0), (lx1, ly1), CAR, col, "lamp", lid, out)
            members.append(lid)
    groups[ids.new(CAR_GROUP)] = members


def _street_light(P: PrimitiveList, ids: _Ids, px: float, pz: float, toward: int) -> None:
    """Pole, arm reaching over the road (direction ``toward`` in x), lamp head; or, for every third
    pole position (a hash of ``pz``, so the random streams are untouched), a 4.2 m post with a small
    lantern on top (street_light_LT).

    The light instance is the head's diffuser: its underside and its end facing the
    camera (-z), two panes on the head sharing one instance id. A lantern's light is its
    camera-facing and road-facing glass, one id.
    """
    grey = (0.32, 0.33, 0.34)
    if int(round(pz * 100.0)) % 3 == 0:
        top = 4.2
        P.box((px - 0.07, KERB, pz - 0.07), (px + 0.07, top, pz + 0.07), POLE, grey, "metal")
        P.box((px - 0.18, top, pz - 0.18), (px + 0.18, top + 0.55, pz + 0.18), POLE, grey, "metal")
        lid = ids.new(STREET_LIGHT_LT)
        glass = (0.66, 0.64, 0.56)
        P.rect(2, pz - 0.18, (px - 0.13, top + 0.07), (px + 0.13, top + 0.45), POLE, glass, "lamp", lid, -1)
        P.rect(0, px + toward * 0.18, (top + 0.07, pz - 0.13), (top + 0.45, pz + 0.13), POLE, glass, "lamp", lid,
               toward)
        return
    top = 8.0
    P.box((px - 0.09, KERB, pz - 0.09), (px + 0.09, top, pz + 0.09), POLE, grey, "metal")
    ax = px + toward * 1.8
    P.box((min(px, ax), top - 0.14, pz - 0.05), (max(px, ax), top - 0.02, pz + 0.05), POLE, grey, "metal")
    h0, h1 = top - 0.40, top - 0.12
    P.box((ax - 0.4, h0, pz - 0.2), (ax + 0.4, h1, pz + 0.2), POLE, grey, "metal")
    lid = ids.new(STREET_LIGHT_HT)
    lens = (0.62, 0.62, 0.58)
    P.rect(1, h0, (ax - 0.34, pz - 0.15), (ax + 0.34, pz + 0.15), POLE, lens, "lamp", lid, -1)
    P.rect(2, pz - 0.2, (ax - 0.34, h0 + 0.03), (ax + 0.34, h1 - 0.03), POLE, lens, "lamp", lid, -1)


def _tree(P: PrimitiveList, rng: np.random.Generator, x: float, z: float) -> None:
    P.box((x - 0.13, KERB, z - 0.13), (x + 0.13, 2.6, z + 0.13), VEGETATION, (0.12, 0.08, 0.05), "foliage")
    green = _jitter(rng, (0.07, 0.16, 0.04), 0.25)
    r = float(rng.uniform(1.2, 1.7))
    P.box((x - r, 2.4, z - r), (x + r, 4.8, z + r), VEGETATION, green, "foliage")
    r2 = r * 0.65
    P.box((x - r2, 4.8, z - r2), (x + r2, 5.9, z + r2), VEGETATION, green * 0.9, "foliage")


#: Signal lamp albedo by day when the lamp is lit (it glows: brighter, saturated) and when dark.
SIGNAL_LIT = {"red": (0.95, 0.10, 0.06), "amber": (0.95, 0.62, 0.05), "green": (0.10, 0.85, 0.45)}
SIGNAL_DARK = {"red": (0.16, 0.03, 0.03), "amber": (0.16, 0.11, 0.02), "green": (0.02, 0.12, 0.05)}


def _traffic_light(P: PrimitiveList, ids: _Ids, x: float, z: float, state: str | None = None) -> list[int]:
    """Pole + housing facing the camera (-z) with red/amber/green lamps (class 'inferred'), top to bottom.

    ``state`` (lights variant): that lamp is lit by day (:data:`SIGNAL_LIT`), the others dark."""
    P.box((x - 0.07, KERB, z - 0.07), (x + 0.07, 2.5, z + 0.07), POLE, (0.25, 0.26, 0.27), "metal")
    P.box((x - 0.2, 2.5, z - 0.14), (x + 0.2, 3.5, z + 0.14), TRAFFIC_LIGHT, (0.05, 0.05, 0.05), "metal")
    members = []
    cols = ((0.35, 0.04, 0.03), (0.35, 0.22, 0.02), (0.03, 0.25, 0.08)) if state is None else \
        tuple((SIGNAL_LIT if name == state else SIGNAL_DARK)[name] for name in ("red", "amber", "green"))
    for yc, col in zip((3.33, 3.0, 2.67), cols):
        lid = ids.new(INFERRED)
        P.rect(2, z - 0.14, (x - 0.12, yc - 0.12), (x + 0.12, yc + 0.12), TRAFFIC_LIGHT, col, "lamp", lid, -1)
        members.append(lid)
    return members


def _pedestrian_signal(P: PrimitiveList, ids: _Ids, x: float, z: float, state: str) -> list[int]:
    """Post + a pedestrian signal head facing the camera (-z): a 0.32 x 0.68 m housing 2.1 m up with a
    red (top) and a green lamp (class 'inferred', 0.24 m squares, plain: no walking figure is drawn);
    ``state``'s lamp is lit by day (:data:`SIGNAL_LIT`)."""
    P.box((x - 0.05, KERB, z - 0.05), (x + 0.05, 2.1, z + 0.05), POLE, (0.25, 0.26, 0.27), "metal")
    P.box((x - 0.16, 2.1, z - 0.1), (x + 0.16, 2.78, z + 0.1), TRAFFIC_LIGHT, (0.05, 0.05, 0.05), "metal")
    members = []
    for yc, name in ((2.61, "red"), (2.27, "green")):
        lid = ids.new(INFERRED)
        col = (SIGNAL_LIT if name == state else SIGNAL_DARK)[name]
        P.rect(2, z - 0.1, (x - 0.12, yc - 0.12), (x + 0.12, yc + 0.12), TRAFFIC_LIGHT, col, "lamp", lid, -1)
        members.append(lid)
    return members


def _traffic_sign(P: PrimitiveList, rng: np.random.Generator, x: float, z: float) -> None:
    P.box((x - 0.04, KERB, z - 0.04), (x + 0.04, 2.3, z + 0.04), POLE, (0.4, 0.4, 0.4), "metal")
    col = [(0.02, 0.10, 0.45), (0.55, 0.03, 0.03), (0.65, 0.50, 0.02)][int(rng.integers(3))]
    P.box((x - 0.32, 2.3, z - 0.06), (x + 0.32, 2.94, z - 0.04), TRAFFIC_SIGN, col, "metal")
