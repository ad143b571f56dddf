"""Night light table and probabilistic light activation (docs/method.md §6.2, §6.3).

Light table
-----------
``resources/light_table.json`` holds, per light class 1..12: a colour (black-body
CCT in kelvin or an explicit chromaticity ``[r/g, b/g]`` in linear sRGB), a
strength range ``[lo, hi]`` in SOLO's emission units, a ``spread`` (std of the
per-light log-chromaticity jitter), an activation probability range, whether
the lamp also *throws* light into the scene through a spot emitter, and an
``origin`` note saying where each number comes from. A user table with the same
layout overrides any field (merged per class) -- :func:`load_light_table`.

Units: Mitsuba radiance = ``unit_scale * s * (r/g, 1, b/g)`` (docs/method.md §6.2, with one
global scale), so SOLO's relative strengths hold.

Activation
----------
:func:`activate_lights`: each light instance is Bernoulli(p). For lights in a
group, ``p ~ U(p_lo, p_hi)`` is drawn once per (group, member class) and shared
by those members (so they are correlated); ``group_all_together`` switches a
group as one (one Bernoulli with the member-count-weighted mean p). Ungrouped
lights draw their own p. Everything comes from one ``numpy.random.Generator``
seeded with ``seed`` and visits lights in sorted id order: the same seed gives
the same night.

Traffic lights: a signal head shows one lamp. In a ``traffic_light_group`` of two or three
``inferred`` lamps exactly one is lit, the lamp whose colour (red / amber / green) is the
state of the group's direction; the state is drawn once per direction and seed from the
table's ``traffic_light.state_p`` (a second stream, so the other lights' draws are
unchanged) unless the annotation says what the day photo shows, and the lit lamp takes the
table's colour for that state instead of its daytime colour (:func:`traffic_light_states`).
"""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..annotation import LightAnnotation, class_of
from ..errors import NpsimInputError
from ..labels import light_classes
from ..resources import load_json_resource

LIGHT_CLASS_IDS = tuple(range(1, 13))
INFERRED_CLASS = 12

# CIE XYZ -> linear sRGB (D65), IEC 61966-2-1.
_XYZ_TO_SRGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                         [-0.9692660, 1.8760108, 0.0415560],
                         [0.0556434, -0.2040259, 1.0572252]])


def cct_to_xy(cct_k: float) -> tuple[float, float]:
    """CIE 1931 xy of a black body at ``cct_k`` kelvin (Kim et al. 2002 cubic fit, 1667..25000 K)."""
    T = float(cct_k)
    if not (1667.0 <= T <= 25000.0):
        raise NpsimInputError(f"colour temperature {T} K is outside 1667..25000 K (the black-body fit's range)")
    if T <= 4000.0:
        x = -0.2661239e9 / T**3 - 0.2343589e6 / T**2 + 0.8776956e3 / T + 0.179910
    else:
        x = -3.0258469e9 / T**3 + 2.1070379e6 / T**2 + 0.2226347e3 / T + 0.240390
    if T <= 2222.0:
        y = -1.1063814 * x**3 - 1.34811020 * x**2 + 2.18555832 * x - 0.20219683
    elif T <= 4000.0:
        y = -0.9549476 * x**3 - 1.37418593 * x**2 + 2.09137015 * x - 0.16748867
    else:
        y = 3.0817580 * x**3 - 5.87338670 * x**2 + 3.75112997 * x - 0.37001483
    return x, y


def cct_to_chromaticity(cct_k: float) -> tuple[float, float]:
    """Linear-sRGB chromaticity ``(r/g, b/g)`` of a black body at ``cct_k`` kelvin.

    Negative channels (outside the sRGB gamut, e.g. blue below ~1900 K) are
    clipped to a small positive floor.
    """
    x, y = cct_to_xy(cct_k)
    xyz = np.array([x / y, 1.0, (1.0 - x - y) / y])
    rgb = np.maximum(_XYZ_TO_SRGB @ xyz, 1e-3)
    return float(rgb[0] / rgb[1]), float(rgb[2] / rgb[1])


@dataclass(frozen=True)
class LightClassSpec:
    """Night appearance of one light class.

    Attributes
    ----------
    class_id, name : light class (1..12) and its name.
    chromaticity : (r/g, b/g) in linear sRGB.
    strength : (lo, hi) SOLO emission units; per light s ~ U(lo, hi).
    spread : std of the per-light jitter of log(r/g), log(b/g).
    p : (lo, hi) activation probability range.
    throw : the lamp also lights the scene through a spot emitter (lamp heads, car lamps).
    share_in_group : members of one group with this class share strength and colour.
    cct_k : colour temperature the chromaticity came from (None for explicit colours).
    origin : where the numbers come from.
    """

    class_id: int
    name: str
    chromaticity: tuple[float, float]
    strength: tuple[float, float]
    spread: float
    p: tuple[float, float]
    throw: bool
    share_in_group: bool
    cct_k: float | None
    origin: str


@dataclass(frozen=True)
class LightTable:
    """Light classes plus the global settings of the night (units, ego headlights, throw spots, sky)."""

    classes: dict[int, LightClassSpec]
    unit_scale: float
    ego_headlight: dict
    throw: dict
    sky_radiance: tuple[float, float, float]
    source: str = "default"
    #: Signal heads: lamp colours (name -> (r/g, b/g)), lamp order in a head, state probabilities.
    traffic_light: dict = field(default_factory=dict)

    def spec(self, class_id: int) -> LightClassSpec:
        try:
            return self.classes[int(class_id)]
        except KeyError:
            raise NpsimInputError(f"light table has no class {class_id}; light classes are 1..12") from None

    def radiance(self, strength: float, chromaticity: tuple[float, float]) -> np.ndarray:
        """Mitsuba radiance RGB ``unit_scale * s * (r/g, 1, b/g)``."""
        rg, bg = chromaticity
        return (self.unit_scale * float(strength) * np.array([rg, 1.0, bg])).astype(np.float64)

    def ego_chromaticity(self) -> tuple[float, float]:
        e = self.ego_headlight
        if "chromaticity" in e:
            return tuple(float(v) for v in e["chromaticity"])  # type: ignore[return-value]
        return cct_to_chromaticity(float(e.get("cct_K", 5000)))


def _merge(default: dict, user: dict) -> dict:
    out = copy.deepcopy(default)
    for key, val in user.items():
        if key == "classes":
            if not isinstance(val, dict):
                raise NpsimInputError("light table: 'classes' must be an object keyed by class id ('1'..'12')")
            for cid, fields in val.items():
                cur = out["classes"].setdefault(str(cid), {})
                if not isinstance(fields, dict):
                    raise NpsimInputError(f"light table: class {cid} must be an object of fields")
                # A user CCT replaces a default explicit colour (and vice versa).
                if "cct_K" in fields and "chromaticity" not in fields:
                    cur.pop("chromaticity", None)
                if "chromaticity" in fields and "cct_K" not in fields:
                    cur.pop("cct_K", None)
                cur.update(fields)
        elif isinstance(val, dict) and isinstance(out.get(key), dict):
            out[key] = {**out[key], **val}
        else:
            out[key] = val
    return out


def _range(doc: dict, key: str, where: str, lo_bound: float, hi_bound: float) -> tuple[float, float]:
    v = doc.get(key)
    if not (isinstance(v, (list, tuple)) and len(v) == 2):
        raise NpsimInputError(f"{where}: '{key}' must be a [low, high] pair, got {v!r}")
    lo, hi = float(v[0]), float(v[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and lo_bound <= lo <= hi <= hi_bound):
        raise NpsimInputError(f"{where}: '{key}' = {v} must satisfy {lo_bound} <= low <= high <= {hi_bound}")
    return lo, hi


def parse_light_table(doc: dict, source: str = "light table") -> LightTable:
    """Validate a (merged) light-table document and build a :class:`LightTable`."""
    names = {c.id: c.name for c in light_classes() if not c.is_group}
    classes: dict[int, LightClassSpec] = {}
    raw = doc.get("classes", {})
    for cid in LIGHT_CLASS_IDS:
        where = f"{source}: class {cid} ({names.get(cid)})"
        c = raw.get(str(cid))
        if c is None:
            raise NpsimInputError(f"{where} is missing; every light class 1..12 needs an entry")
        cct = c.get("cct_K")
        if "chromaticity" in c:
            ch = c["chromaticity"]
            if not (isinstance(ch, (list, tuple)) and len(ch) == 2 and all(float(x) > 0 for x in ch)):
                raise NpsimInputError(f"{where}: 'chromaticity' must be [r/g, b/g] with positive values, got {ch!r}")
            chroma = (float(ch[0]), float(ch[1]))
            cct = None
        elif cct is not None:
            chroma = cct_to_chromaticity(float(cct))
        else:
            raise NpsimInputError(f"{where}: give 'cct_K' (kelvin) or 'chromaticity' [r/g, b/g]")
        spread = float(c.get("spread", 0.0))
        if not (0.0 <= spread <= 2.0):
            raise NpsimInputError(f"{where}: 'spread' must be in [0, 2] (log-chromaticity std), got {spread}")
        classes[cid] = LightClassSpec(
            class_id=cid, name=str(c.get("name", names.get(cid, str(cid)))), chromaticity=chroma,
            strength=_range(c, "strength", where, 0.0, 1e9), spread=spread, p=_range(c, "p", where, 0.0, 1.0),
            throw=bool(c.get("throw", False)), share_in_group=bool(c.get("share_in_group", False)),
            cct_k=None if cct is None else float(cct), origin=str(c.get("origin", "")))
    unit = float(doc.get("unit_scale", 0.01))
    if not (math.isfinite(unit) and unit > 0):
        raise NpsimInputError(f"{source}: 'unit_scale' must be a positive number, got {doc.get('unit_scale')!r}")
    sky = doc.get("sky", {}).get("radiance", [0.0, 0.0, 0.0])
    if not (len(sky) == 3 and all(math.isfinite(float(v)) and float(v) >= 0 for v in sky)):
        raise NpsimInputError(f"{source}: sky.radiance must be three non-negative numbers, got {sky!r}")
    ego = dict(doc.get("ego_headlight", {}))
    _range(ego, "strength", f"{source}: ego_headlight", 0.0, 1e9)
    return LightTable(classes=classes, unit_scale=unit, ego_headlight=ego, throw=dict(doc.get("throw", {})),
                      sky_radiance=tuple(float(v) for v in sky), source=source,  # type: ignore[arg-type]
                      traffic_light=_traffic_light_section(doc.get("traffic_light", {}), source))


def _traffic_light_section(doc: dict, source: str) -> dict:
    """Validated ``traffic_light`` section: colours {name: (r/g, b/g)}, order, order_two, state_p (sums to 1)."""
    where = f"{source}: traffic_light"
    if not isinstance(doc, dict):
        raise NpsimInputError(f"{where} must be an object with 'colours', 'order' and 'state_p'")
    colours = {}
    for name, ch in dict(doc.get("colours", {})).items():
        if not (isinstance(ch, (list, tuple)) and len(ch) == 2 and all(float(x) > 0 for x in ch)):
            raise NpsimInputError(f"{where}: colour {name!r} must be [r/g, b/g] with positive values, got {ch!r}")
        colours[str(name)] = (float(ch[0]), float(ch[1]))
    order = [str(c) for c in doc.get("order", [])]
    order_two = [str(c) for c in doc.get("order_two", [])]
    state_p = {str(k): float(v) for k, v in dict(doc.get("state_p", {})).items()}
    for what, names in (("order", order), ("order_two", order_two), ("state_p", list(state_p))):
        bad = [c for c in names if c not in colours]
        if bad:
            raise NpsimInputError(f"{where}: {what} names {bad}, which have no entry in 'colours'")
    if state_p and (any(v < 0 for v in state_p.values()) or abs(sum(state_p.values()) - 1.0) > 1e-6):
        raise NpsimInputError(f"{where}: state_p must be non-negative probabilities summing to 1, got {state_p}")
    return {"colours": colours, "order": order, "order_two": order_two, "state_p": state_p}


def load_light_table(path: str | Path | None = None) -> LightTable:
    """The default light table, with the user table at ``path`` (JSON) merged over it.

    The user file may give any subset of fields, e.g.
    ``{"classes": {"1": {"p": [0.8, 1.0]}}, "unit_scale": 0.02}``.
    """
    default = load_json_resource("light_table.json")
    if path is None:
        return parse_light_table(copy.deepcopy(default), "resources/light_table.json")
    p = Path(path)
    if not p.is_file():
        raise NpsimInputError(f"{p}: light table not found; pass a JSON file laid out like resources/light_table.json")
    try:
        user = json.loads(p.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise NpsimInputError(f"{p}: not valid JSON ({exc})") from None
    if not isinstance(user, dict):
        raise NpsimInputError(f"{p}: a light table must be a JSON object")
    return parse_light_table(_merge(default, user), str(p))


# --------------------------------------------------------------------------- activation
@dataclass(frozen=True)
class LightState:
    """One light instance in one night."""

    id: int
    class_id: int
    on: bool
    strength: float
    chromaticity: tuple[float, float]
    #: Mitsuba radiance RGB (zero when off).
    radiance: tuple[float, float, float]
    p: float
    group: int | None


@dataclass(frozen=True)
class ActiveLights:
    """The result of :func:`activate_lights`: every annotated light's state."""

    lights: dict[int, LightState]
    seed: int
    group_all_together: bool
    table_source: str = "default"
    info: dict = field(default_factory=dict)

    @property
    def on_ids(self) -> list[int]:
        return [i for i, s in sorted(self.lights.items()) if s.on]

    def to_json(self) -> dict:
        return {"seed": self.seed, "group_all_together": self.group_all_together, "table": self.table_source,
                "n_lights": len(self.lights), "n_on": len(self.on_ids),
                "lights": [{"id": s.id, "class_id": s.class_id, "class_name": _class_name(s.class_id), "on": s.on,
                            "p": round(s.p, 6), "strength": round(s.strength, 6),
                            "chromaticity": [round(v, 6) for v in s.chromaticity],
                            "radiance": [round(v, 8) for v in s.radiance], "group": s.group}
                           for _, s in sorted(self.lights.items())]}


def _class_name(cid: int) -> str:
    for c in light_classes():
        if c.id == cid:
            return c.name
    return str(cid)


def inferred_chromaticity(image: np.ndarray, mask: np.ndarray) -> tuple[float, float] | None:
    """(r/g, b/g) of the mean linearised daytime colour under ``mask`` (None if empty or black)."""
    if not mask.any():
        return None
    lin = srgb_to_linear(image[mask].astype(np.float32) / 255.0).mean(axis=0)
    if lin[1] <= 1e-4:
        return None
    return (float(np.clip(lin[0] / lin[1], 0.05, 20.0)), float(np.clip(lin[2] / lin[1], 0.05, 20.0)))


def _lamp_order(annotation: LightAnnotation, members: list[int]) -> list[int]:
    """Lamps of one signal head in reading order: top to bottom, or left to right when the head's
    lamps spread wider than tall (a horizontal head)."""
    cent = {}
    for m in members:
        ys, xs = np.nonzero(annotation.instance_map == m)
        cent[m] = (float(ys.mean()), float(xs.mean())) if ys.size else (0.0, 0.0)
    ys = [c[0] for c in cent.values()]
    xs = [c[1] for c in cent.values()]
    axis = 1 if (max(xs) - min(xs)) > (max(ys) - min(ys)) else 0
    return sorted(members, key=lambda m: (cent[m][axis], m))


def traffic_light_states(annotation: LightAnnotation | None, table: LightTable, seed: int
                         ) -> dict[int, tuple[str, str]]:
    """Which lamp of every signal head is lit: ``{lamp id: (lamp colour, state of its head)}``.

    A signal head is a ``traffic_light_group`` (20) holding two or three ``inferred`` (12) lamps
    and nothing else. A lamp's colour is ``annotation.meta["lamp_colours"][str(id)]`` when given,
    else its place in the head (:func:`_lamp_order`; ``traffic_light.order`` or ``order_two``). The
    state of a direction (``meta["traffic_light_direction"][str(group id)]``, default ``"ahead"``:
    every head facing the camera) is what the day photo shows (``meta["traffic_light_states"]``, the
    first head of that direction that has one), else a draw from ``traffic_light.state_p`` with
    ``default_rng([seed, 20])`` per direction in sorted order; a head without a lamp of that colour
    (a two-lamp head on amber) shows red. Empty without a ``traffic_light`` table section.
    """
    tl = table.traffic_light
    if annotation is None or not tl or not tl.get("colours") or not tl.get("state_p"):
        return {}
    meta = annotation.meta or {}
    given_col = {int(k): str(v) for k, v in dict(meta.get("lamp_colours") or {}).items()}
    seen = {int(k): str(v) for k, v in dict(meta.get("traffic_light_states") or {}).items()}
    direction = {int(k): str(v) for k, v in dict(meta.get("traffic_light_direction") or {}).items()}
    heads: dict[int, dict[int, str]] = {}
    for gid in sorted(annotation.groups):
        g = annotation.groups[gid]
        mem = [int(m) for m in g.members]
        if g.class_id != 20 or not 2 <= len(mem) <= 3 or any(class_of(m) != INFERRED_CLASS for m in mem):
            continue
        order = tl["order"] if len(mem) == 3 else tl["order_two"]
        placed = _lamp_order(annotation, mem)
        heads[gid] = {m: given_col.get(m, order[k] if k < len(order) else "") for k, m in enumerate(placed)}
    if not heads:
        return {}
    rng = np.random.default_rng([int(seed), 20])
    names = list(tl["state_p"])
    probs = np.array([tl["state_p"][n] for n in names], float)
    state: dict[str, str] = {}
    for d in sorted({direction.get(g, "ahead") for g in heads}):
        drawn = names[int(rng.choice(len(names), p=probs / probs.sum()))]  # always drawn: stable per seed
        obs = [seen[g] for g in sorted(heads) if direction.get(g, "ahead") == d and seen.get(g) in tl["colours"]]
        state[d] = obs[0] if obs else drawn
    out: dict[int, tuple[str, str]] = {}
    for gid, lamps in heads.items():
        st = state[direction.get(gid, "ahead")]
        if st not in lamps.values():
            st = "red" if "red" in lamps.values() else next(iter(lamps.values()))
        for m, col in lamps.items():
            out[m] = (col, st)
    return out


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decoding of values in [0, 1]."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)


#: The streams of :func:`_keyed_rng` (distinct from ``traffic_light_states``' ``[seed, 20]``).
_SHARED, _GROUP_ON, _LIGHT = 31, 32, 33


def _keyed_rng(seed: int, stream: int, *key: int) -> np.random.Generator:
    """A generator for one draw of one night: seeded by the night's seed, the draw's stream and the id(s)
    it is for, so that it does not depend on which other lights and groups the annotation holds."""
    return np.random.default_rng([int(seed), int(stream), *(int(k) for k in key)])


def activate_lights(annotation: LightAnnotation | None, table: LightTable, seed: int, *,
                    group_all_together: bool = False, image: np.ndarray | None = None,
                    force: dict[int, bool] | None = None) -> ActiveLights:
    """Draw one night: which annotated lights are on, how strong and what colour.

    Parameters
    ----------
    annotation : light instances and groups (None -> no lights).
    table : the light table.
    seed : seeds the night: every light's and group's draw comes from ``numpy.random.default_rng([seed,
        stream, id])`` (:func:`_keyed_rng`); same seed -> same night, and a light keeps its draw whatever
        else the annotation holds.
    group_all_together : a group switches as one (all members on or all off).
    image : (H, W, 3) uint8 daytime sRGB; gives ``inferred`` lights their colour.
    force : optional ``{id: on}`` overrides applied after the draw (e.g. a GUI toggle).

    Returns
    -------
    ActiveLights with a :class:`LightState` per light id (radiance zero when off).
    """
    if annotation is None:
        return ActiveLights({}, int(seed), group_all_together, table.source)
    ids = annotation.instance_ids()
    member_group: dict[int, int] = {}
    for gid in sorted(annotation.groups):
        for m in annotation.groups[gid].members:
            member_group.setdefault(int(m), gid)

    # Every draw comes from a generator keyed by (seed, what it is for, the id it is for), never from
    # one generator run in turn: a light or group added, removed or regrouped then leaves every other
    # light's state as it was (with one shared generator, adding one window group to a street redrew
    # 72 of its 169 lights -- the night preview changed all over after one edit).
    shared: dict[tuple[int, int], dict] = {}
    for gid in sorted(annotation.groups):
        classes = sorted({class_of(m) for m in annotation.groups[gid].members if member_group.get(m) == gid})
        for cid in classes:
            spec = table.spec(cid)
            rng = _keyed_rng(seed, _SHARED, gid, cid)
            shared[(gid, cid)] = {"p": float(rng.uniform(*spec.p)), "s": float(rng.uniform(*spec.strength)),
                                  "jit": rng.normal(0.0, 1.0, 2)}
    group_on: dict[int, bool] = {}
    if group_all_together:
        for gid in sorted(annotation.groups):
            mem = [m for m in annotation.groups[gid].members if member_group.get(m) == gid]
            if mem:
                p = float(np.mean([shared[(gid, class_of(m))]["p"] for m in mem]))
                group_on[gid] = bool(_keyed_rng(seed, _GROUP_ON, gid).random() < p)

    signal = traffic_light_states(annotation, table, seed)
    states: dict[int, LightState] = {}
    for lid in ids:
        cid = class_of(lid)
        spec = table.spec(cid)
        gid = member_group.get(lid)
        rng = _keyed_rng(seed, _LIGHT, lid)
        own_p, own_s, own_jit, u = (float(rng.uniform(*spec.p)), float(rng.uniform(*spec.strength)),
                                    rng.normal(0.0, 1.0, 2), float(rng.random()))
        if gid is not None:
            sh = shared[(gid, cid)]
            p = sh["p"]
            s, jit = (sh["s"], sh["jit"]) if spec.share_in_group else (own_s, own_jit)
            on = group_on[gid] if group_all_together else bool(u < p)
        else:
            p, s, jit, on = own_p, own_s, own_jit, bool(u < own_p)
        chroma = spec.chromaticity
        if lid in signal:  # one lamp per signal head, in its table colour (not its daytime look)
            colour, shown = signal[lid]
            on = on and colour == shown
            chroma = table.traffic_light["colours"].get(colour, chroma)
        elif cid == INFERRED_CLASS and image is not None:
            chroma = inferred_chromaticity(image, annotation.mask(lid)) or chroma
        if force and lid in force:
            on = bool(force[lid])
        if spec.spread > 0:
            chroma = (chroma[0] * math.exp(spec.spread * jit[0]), chroma[1] * math.exp(spec.spread * jit[1]))
        rad = table.radiance(s, chroma) if on else np.zeros(3)
        states[lid] = LightState(id=lid, class_id=cid, on=on, strength=s, chromaticity=chroma,
                                 radiance=tuple(float(v) for v in rad), p=p, group=gid)
    return ActiveLights(states, int(seed), group_all_together, table.source)



def visible_head_radiance(instance_map: np.ndarray, active: ActiveLights, table: LightTable,
                          spot_ids: Iterable[int]) -> np.ndarray | None:
    """The radiance of the visible heads of throwing lamps, for the camera's glare.

    A lamp that lights the scene through a spot (street-lamp heads, car front lamps; ``spot_ids``,
    the lights that have one) emits the spot's intensity ``I = throw.gain · L · A`` from its head's
    area ``A``, so the head seen from inside the beam has radiance ``I / A = throw.gain · L`` (L =
    the light's table radiance): 40 x L, about 10^4 times the road it lights, as real luminaires
    (10^4-10^5 cd/m²) are over roads of 0.3-2 cd/m². The render shows the head capped at
    ``throw.max_visible_radiance`` (fireflies; docs/relight.md) plus whatever light its geometry
    catches (on stereo geometry the spot can light its own head a hundredfold) -- saturated
    either way, but a camera's glare (:func:`.camera_post.lens_glare`) needs the head's own energy,
    the same whatever the geometry. Returns an (H, W, 3) float32 map of that radiance on the heads'
    pixels and NaN elsewhere (replace the linear render's pixels where it is finite), or None when
    no head is lit.
    """
    gain = float(table.throw.get("gain", 20.0))
    inst = np.asarray(instance_map)
    lut: dict[int, tuple[float, float, float]] = {}
    for lid in spot_ids:
        st = active.lights.get(int(lid))
        if st is not None and st.on and max(st.radiance) > 0:
            lut[int(lid)] = tuple(gain * float(v) for v in st.radiance)
    if not lut:
        return None
    ids = np.array(sorted(lut), np.int64)
    vals = np.array([lut[int(i)] for i in ids], np.float32)
    pos = np.clip(np.searchsorted(ids, inst), 0, ids.size - 1)
    hit = ids[pos] == inst
    if not hit.any():
        return None
    return np.where(hit[..., None], vals[pos], np.float32(np.nan)).astype(np.float32)
