"""Light table and probabilistic light activation (docs/method.md §6.2, §6.3) -- statistics, no rendering."""

from __future__ import annotations

import json

import numpy as np
import pytest

from npsim_core.annotation import GroupInstance, LightAnnotation
from npsim_core.errors import NpsimInputError
from npsim_core.render.lights import (activate_lights, cct_to_chromaticity, inferred_chromaticity,
                                      load_light_table)


def _windows(n: int, grouped: bool, cls: int = 1) -> LightAnnotation:
    """n one-pixel-row lights of class ``cls`` on a strip, optionally all in one windows_group."""
    m = np.zeros((4, 4 * n), np.int32)
    ids = [cls * 1000 + k + 1 for k in range(n)]
    for k, i in enumerate(ids):
        m[1:3, 4 * k:4 * k + 3] = i
    groups = {13001: GroupInstance(13001, tuple(ids))} if grouped else {}
    return LightAnnotation(m, groups)


def test_default_table_complete_with_origins():
    t = load_light_table()
    assert sorted(t.classes) == list(range(1, 13))
    for spec in t.classes.values():
        assert spec.origin, f"class {spec.name} lacks an origin note"
        assert 0 <= spec.p[0] <= spec.p[1] <= 1
        assert spec.strength[0] <= spec.strength[1]
    # SOLO reference values (docs/method.md §6.2)
    assert t.spec(1).p == (0.3, 0.6) and t.spec(1).strength == (1, 20)
    assert t.spec(8).strength == (850, 1000) and t.spec(8).p == (1.0, 1.0)
    assert t.spec(5).p == (0.95, 1.0) and t.spec(4).strength == (60, 90)
    # sodium street light is orange, LED cooler, rear lamps red
    assert t.spec(9).chromaticity[0] > 2.5 and t.spec(9).chromaticity[1] < 0.15
    assert t.spec(8).chromaticity[0] < t.spec(9).chromaticity[0]
    assert t.spec(6).chromaticity[0] > 3 and t.spec(6).chromaticity[1] < 0.5


def test_blackbody_chromaticity():
    rg, bg = cct_to_chromaticity(6504)  # close to D65 white
    assert abs(rg - 1) < 0.1 and abs(bg - 1) < 0.1
    warm, cool = cct_to_chromaticity(2700), cct_to_chromaticity(5000)
    assert warm[0] > cool[0] > 1 and warm[1] < cool[1] < 1
    with pytest.raises(NpsimInputError):
        cct_to_chromaticity(500)


def test_user_table_overrides_and_validates(tmp_path):
    p = tmp_path / "t.json"
    p.write_text(json.dumps({"classes": {"1": {"p": [0.9, 1.0], "cct_K": 4000}, "4": {"strength": [1, 2]}},
                             "unit_scale": 0.5}))
    t = load_light_table(p)
    assert t.spec(1).p == (0.9, 1.0) and t.spec(1).cct_k == 4000
    assert t.spec(1).chromaticity == pytest.approx(cct_to_chromaticity(4000))
    assert t.spec(4).strength == (1, 2) and t.spec(4).chromaticity == load_light_table().spec(4).chromaticity
    assert t.spec(8).strength == (850, 1000)  # untouched classes keep the default
    assert t.unit_scale == 0.5
    p.write_text(json.dumps({"classes": {"2": {"p": [0.8, 0.2]}}}))
    with pytest.raises(NpsimInputError, match="class 2"):
        load_light_table(p)
    with pytest.raises(NpsimInputError):
        load_light_table(tmp_path / "missing.json")


def test_same_seed_same_night_different_seeds_differ():
    ann = _windows(12, grouped=False)
    t = load_light_table()
    a, b = activate_lights(ann, t, 7), activate_lights(ann, t, 7)
    assert a.to_json() == b.to_json()
    sets = {tuple(activate_lights(ann, t, s).on_ids) for s in range(10)}
    assert len(sets) >= 5
    st = a.lights[1001]
    assert st.on == any(st.radiance) and (not st.on or st.radiance[1] == pytest.approx(t.unit_scale * st.strength))


def test_group_all_together_shares_state():
    ann = _windows(8, grouped=True)
    t = load_light_table()
    n_on = []
    for s in range(200):
        states = {v.on for v in activate_lights(ann, t, s, group_all_together=True).lights.values()}
        assert len(states) == 1
        n_on.append(states.pop())
    assert 0.2 < np.mean(n_on) < 0.7  # p ~ U(.3, .6) for windows


def _count_dispersion(ann, seeds=3000):
    t = load_light_table()
    counts = np.array([len(activate_lights(ann, t, s).on_ids) for s in range(seeds)], float)
    n = len(ann.instance_ids())
    p = counts.mean() / n
    return counts.var() / (n * p * (1 - p))


def test_group_members_correlated_ungrouped_independent():
    # Shared p per (group, class): the number of lit windows is over-dispersed versus a binomial.
    grouped = _count_dispersion(_windows(20, grouped=True))
    alone = _count_dispersion(_windows(20, grouped=False))
    assert grouped > 1.3, grouped
    assert 0.85 < alone < 1.15, alone


def test_forced_and_inferred_colour():
    img = np.zeros((4, 8, 3), np.uint8)
    img[...] = (200, 30, 20)  # a red traffic-light lens in daylight
    ann = LightAnnotation(np.zeros((4, 8), np.int32))
    ann.instance_map[1:3, 2:5] = 12001
    t = load_light_table()
    rg, bg = inferred_chromaticity(img, ann.mask(12001))
    assert rg > 5 and bg < 1
    act = activate_lights(ann, t, 0, image=img, force={12001: False})
    assert not act.lights[12001].on and act.lights[12001].chromaticity == pytest.approx((rg, bg))
    assert activate_lights(None, t, 0).lights == {}


def _signal_heads() -> LightAnnotation:
    """Two three-lamp signal heads (one upright, one horizontal) and a window, as an annotator draws them."""
    m = np.zeros((20, 24), np.int32)
    for k in range(3):
        m[2 + 5 * k:5 + 5 * k, 2:5] = 12001 + k          # upright: top to bottom
        m[2:5, 8 + 4 * k:11 + 4 * k] = 12004 + k         # horizontal: left to right
    m[15:18, 15:20] = 1001
    return LightAnnotation(m, {20001: GroupInstance(20001, (12001, 12002, 12003)),
                               20002: GroupInstance(20002, (12004, 12005, 12006))})


def test_a_traffic_light_group_lights_exactly_one_lamp_in_that_lamps_colour():
    ann, t = _signal_heads(), load_light_table()
    colours = t.traffic_light["colours"]
    place = {12001: "red", 12002: "amber", 12003: "green", 12004: "red", 12005: "amber", 12006: "green"}
    shown = set()
    for seed in range(40):
        act = activate_lights(ann, t, seed, image=np.full((20, 24, 3), 200, np.uint8))
        for gid in (20001, 20002):
            on = [i for i in ann.groups[gid].members if act.lights[i].on]
            assert len(on) == 1, (seed, gid, on)           # one lamp per head, never all three (white)
            st = act.lights[on[0]]
            assert st.chromaticity == pytest.approx(colours[place[on[0]]])
            assert st.radiance[1] > 0 and max(st.radiance) == pytest.approx(
                t.unit_scale * st.strength * max(colours[place[on[0]]][0], 1, colours[place[on[0]]][1]))
        lit = [place[i] for i in act.on_ids if i // 1000 == 12]
        assert lit[0] == lit[1]                              # heads of one direction show the same state
        shown.add(lit[0])
        assert act.lights[1001].chromaticity != act.lights[12001].chromaticity
    assert shown == {"red", "amber", "green"}               # the seed picks the state
    # Colours red and green differ as a night shows them: red lamp redder than green, green greener.
    assert colours["red"][0] > 3 > colours["green"][0] and colours["green"][1] > colours["red"][1]


def test_the_state_the_day_photo_shows_and_an_annotators_colours_win():
    ann, t = _signal_heads(), load_light_table()
    ann.meta["traffic_light_states"] = {"20002": "green"}
    ann.meta["lamp_colours"] = {"12004": "green", "12006": "red"}  # a head ordered the other way round
    for seed in range(10):
        on = activate_lights(ann, t, seed).on_ids
        assert 12003 in on and 12004 in on and not {12001, 12002, 12005, 12006} & set(on)
    ann.meta["traffic_light_direction"] = {"20001": "crossing"}   # another direction: drawn on its own
    states = {tuple(activate_lights(ann, t, s).on_ids) for s in range(30)}
    assert any(12003 not in on for on in states)
    p = load_light_table().traffic_light
    assert abs(sum(p["state_p"].values()) - 1) < 1e-9 and set(p["order"]) <= set(p["colours"])


def test_an_added_or_removed_light_leaves_every_other_lights_draw_as_it_was():
    """A night's draw per light and group is keyed to its id (``render.lights._keyed_rng``): the annotator
    adding a window in a new group, or deleting one, changes no other light's state -- the night preview
    does not relight the whole street after one edit (with one generator run in turn it redrew 72 of the
    synthetic street's 169 lights)."""
    from npsim_core.synthetic import street_scene

    ann = street_scene(256, 128, 0).lights
    t = load_light_table()
    ids = ann.instance_ids()
    free = next(1000 + k for k in range(1, 999) if 1000 + k not in ids)
    gid = next(13000 + k for k in range(1, 999) if 13000 + k not in ann.groups)
    more = LightAnnotation(ann.instance_map.copy(), {**ann.groups, gid: GroupInstance(gid, (free,))})
    more.instance_map[0:2, 0:3] = free
    fewer = LightAnnotation(np.where(ann.instance_map == ids[0], 0, ann.instance_map),
                            {g: GroupInstance(g, tuple(m for m in grp.members if m != ids[0]))
                             for g, grp in ann.groups.items() if set(grp.members) != {ids[0]}})
    for seed in (0, 3):
        a = activate_lights(ann, t, seed).lights
        b = activate_lights(more, t, seed).lights
        c = activate_lights(fewer, t, seed).lights
        assert all(b[i] == a[i] for i in ids)
        assert all(c[i] == a[i] for i in ids[1:])
