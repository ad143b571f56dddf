"""Light proposals (docs/proposals.md): each proposer on hand-checkable frames, the result type, input
errors, the dataset's instance ids, and `npsim propose`."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from npsim_core.annotation import class_of, load_annotation
from npsim_core.camera import Intrinsics
from npsim_core.errors import NpsimInputError
from npsim_core.proposals import LightProposals, ProposalParams, propose_for_scene, propose_lights
from npsim_core.proposals.evaluate import score_category

from proposal_helpers import FLAT, canvas, iou

SKY, ROAD, BUILDING, POLE, TRAFFIC_LIGHT, CAR = 23, 7, 11, 17, 19, 26


def _lights(props: LightProposals, classes, threshold=0.5):
    ann = props.above(threshold)
    return ann, [i for i in ann.instance_ids() if class_of(i) in classes]


def test_traffic_light_component_yields_three_lamps_in_one_group():
    img, lab = canvas()
    lab[30:60, 90:100] = TRAFFIC_LIGHT                       # 10 x 30 px housing, upright
    img[30:60, 90:100] = (15, 15, 15)
    for k, col in enumerate(((200, 20, 20), (200, 140, 0), (20, 180, 60))):
        img[32 + 10 * k:38 + 10 * k, 92:98] = col
    lab[60:110, 94:96] = POLE
    props = propose_lights(img, lab)
    ann, lamps = _lights(props, (12,))
    assert len(lamps) == 3
    groups = [g for g in ann.groups.values() if g.class_id == 20]
    assert len(groups) == 1 and sorted(groups[0].members) == sorted(lamps)
    rows = [np.nonzero(ann.mask(i))[0].mean() for i in groups[0].members]
    assert sorted(rows) == pytest.approx([35, 45, 55], abs=1.5)   # one lamp per third, top to bottom
    for i in lamps:
        m = ann.mask(i)
        assert (lab[m] == TRAFFIC_LIGHT).all() and 16 <= m.sum() <= 64
    assert all(0.5 <= props.confidence[i] <= 1 for i in lamps + [groups[0].id])


def test_pole_top_yields_one_lamp_at_its_head():
    img, lab = canvas(H=200, W=200)
    lab[150:, :] = ROAD
    depth = np.full((200, 200), 20.0, np.float32)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=99.5, cy=99.5, width=200, height=200)
    # 8 m pole at 20 m (10 px per metre): foot at the ground row, top 80 px above it; arm 2 m to the right.
    foot = int(99.5 + 1.22 * 10)
    top = foot - 80
    lab[top:foot, 60:62] = POLE
    img[top:foot, 60:62] = (80, 80, 85)
    lab[top:top + 2, 60:80] = POLE                            # arm
    img[top:top + 2, 60:80] = (80, 80, 85)
    lab[top + 1:top + 4, 72:80] = POLE                        # head, bright diffuser underneath
    img[top + 2:top + 4, 72:80] = (200, 200, 190)
    # a 1 m bollard: no lamp
    lab[foot - 10:foot, 150:152] = POLE
    props = propose_lights(img, lab, depth, intr, params=FLAT)
    ann, lamps = _lights(props, (8, 9))
    assert len(lamps) == 1 and class_of(lamps[0]) == 8       # top 8 m above the ground: a high lamp
    ys, xs = np.nonzero(ann.mask(lamps[0]))
    assert xs.min() >= 70 and xs.max() <= 80 and ys.max() <= top + 5   # at the arm's far end, at the top
    assert props.confidence[lamps[0]] >= 0.75


def _car_frame(rear_color=(200, 20, 20), paint=(40, 60, 140)):
    """A car seen from behind at 10 m (50 px per metre): 1.8 m wide body, cabin above, red lamps."""
    img, lab = canvas()
    lab[95:, :] = ROAD
    img[95:] = (70, 70, 75)
    depth = np.full(lab.shape, 10.0, np.float32)
    intr = Intrinsics(fx=500.0, fy=500.0, cx=99.5, cy=59.5, width=200, height=120)
    # Rows: height h above the ground at 10 m (no pitch) is at v = 59.5 + (1.22 - h) * 50.
    row = lambda h: int(round(59.5 + (1.22 - h) * 50))  # noqa: E731
    x0, x1 = 55, 145                                          # 90 px = 1.8 m
    lab[row(0.9):row(0.3), x0:x1] = CAR                        # body
    img[row(0.9):row(0.3), x0:x1] = paint
    lab[row(1.4):row(0.9), x0 + 5:x1 - 5] = CAR                # cabin (narrower)
    img[row(1.4):row(0.9), x0 + 5:x1 - 5] = paint
    img[row(1.33):row(0.97), x0 + 9:x1 - 9] = (20, 22, 25)     # rear window
    lamp_rows = slice(row(0.84), row(0.69))
    img[lamp_rows, x0 + 4:x0 + 19] = rear_color
    img[lamp_rows, x1 - 19:x1 - 4] = rear_color
    inst = np.where(lab == CAR, CAR * 1000, lab.astype(np.int32))   # int32 first: in uint8, 26000 was 144
    truth = [np.zeros(lab.shape, bool), np.zeros(lab.shape, bool)]
    truth[0][lamp_rows, x0 + 4:x0 + 19] = True
    truth[1][lamp_rows, x1 - 19:x1 - 4] = True
    return img, lab, depth, intr, inst, truth


def test_car_with_red_rear_lamps_yields_a_rear_pair_in_one_car_group():
    img, lab, depth, intr, inst, truth = _car_frame()
    props = propose_lights(img, lab, depth, intr, inst, params=FLAT)
    ann, lamps = _lights(props, (3, 4, 5, 6))
    assert len(lamps) == 2 and all(class_of(i) == 6 for i in lamps)     # red by day: rear lamps; in the lane: moving
    masks = sorted((ann.mask(i) for i in lamps), key=lambda m: np.nonzero(m)[1].mean())
    assert iou(masks[0], truth[0]) >= 0.5 and iou(masks[1], truth[1]) >= 0.5
    gid = ann.group_of(lamps[0])
    assert gid is not None and class_of(gid) == 14 and ann.group_of(lamps[1]) == gid
    panes = [i for i in ann.groups[gid].members if class_of(i) == 2]
    assert panes and all((img[ann.mask(i)].mean(0) < 60).all() for i in panes)   # the dark rear window


def test_white_lamps_are_front_lamps():
    img, lab, depth, intr, inst, _ = _car_frame(rear_color=(240, 240, 230))
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert len(lamps) == 2 and all(class_of(i) == 5 for i in lamps)


def test_facade_grid_of_dark_windows_yields_windows_grouped_per_floor():
    img, lab = canvas(H=160, W=240)
    lab[20:150, 20:220] = BUILDING
    img[20:150, 20:220] = (170, 150, 120)
    lab[150:, :] = ROAD
    depth = np.full(lab.shape, 20.0, np.float32)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=119.5, cy=79.5, width=240, height=160)   # 10 px per metre
    truth = []
    for r in range(3):
        for c in range(5):
            y, x = 35 + 35 * r, 35 + 38 * c
            img[y:y + 15, x:x + 12] = (30, 35, 45)                  # 1.2 x 1.5 m panes
            m = np.zeros(lab.shape, bool)
            m[y:y + 15, x:x + 12] = True
            truth.append((r, m))
    props = propose_lights(img, lab, depth, intr, params=FLAT)
    ann, wins = _lights(props, (1,))
    assert len(wins) == 15
    for r, m in truth:
        best = max(wins, key=lambda i: iou(ann.mask(i), m))
        assert iou(ann.mask(best), m) >= 0.8
    floors = [g for g in ann.groups.values() if g.class_id == 13]
    assert len(floors) == 3 and all(len(g.members) == 5 for g in floors)
    for g in floors:  # one floor per group: the members share their rows
        rows = {int(np.nonzero(ann.mask(i))[0].min()) for i in g.members}
        assert len(rows) == 1


def test_proposals_are_deterministic_and_match_the_street_traffic_light(street_small):
    a = propose_for_scene(street_small)
    b = propose_for_scene(street_small)
    assert np.array_equal(a.annotation.instance_map, b.annotation.instance_map)
    assert a.confidence == b.confidence and a.annotation.groups == b.annotation.groups
    a.annotation.validate()
    s = score_category(street_small.lights, a.above(0.5), "traffic_light_lamps")
    assert s.n_gt == 3 and s.n_match == 3 and s.n_pred == 3


@pytest.fixture(scope="module")
def street_small():
    from npsim_core.synthetic import street_scene

    return street_scene(512, 256, 0)


def test_above_keeps_confident_lights_and_trims_groups():
    img, lab = canvas()
    lab[30:60, 90:100] = TRAFFIC_LIGHT
    lab[30:60, 150:170] = TRAFFIC_LIGHT                       # squat: low confidence
    props = propose_lights(img, lab)
    tl = sorted(g for g in props.annotation.groups if class_of(g) == 20)
    assert len(tl) == 2
    conf = [props.confidence[g] for g in tl]
    hi, lo = (tl[0], tl[1]) if conf[0] > conf[1] else (tl[1], tl[0])
    t = (props.confidence[hi] + props.confidence[lo]) / 2
    kept = props.above(t)
    assert hi in kept.groups and lo not in kept.groups
    assert set(kept.instance_ids()) == set(props.ids_in_group(hi))
    assert props.ids_in_group(999999) == ()
    assert props.above(0.0).instance_ids() == props.annotation.instance_ids()


@pytest.mark.parametrize("case", ["image_dtype", "labels_shape", "labels_unknown", "depth_int", "depth_shape",
                                  "intrinsics_size", "instances_shape", "category"])
def test_bad_input_raises_a_named_error(case):
    img, lab = canvas()
    kw: dict = {}
    if case == "image_dtype":
        img = img.astype(np.float32)
    elif case == "labels_shape":
        lab = lab[:, :-1]
    elif case == "labels_unknown":
        lab = lab.copy()
        lab[0, 0] = 250
    elif case == "depth_int":
        kw["depth"] = np.ones(lab.shape, np.int32)
    elif case == "depth_shape":
        kw["depth"] = np.ones((10, 10), np.float32)
    elif case == "intrinsics_size":
        kw["intrinsics"] = Intrinsics.cityscapes(100, 50)
    elif case == "instances_shape":
        kw["instances"] = np.zeros((3, 3), np.int32)
    else:
        kw["params"] = ProposalParams(categories=("lamp_posts",))
    word = {"image_dtype": "image", "labels_shape": "labels", "labels_unknown": "labels", "depth_int": "depth",
            "depth_shape": "depth", "intrinsics_size": "intrinsics", "instances_shape": "instances",
            "category": "categories"}[case]
    with pytest.raises(NpsimInputError, match=word):
        propose_lights(img, lab, **kw)


def test_all_nan_depth_behaves_like_no_depth():
    img, lab = canvas()
    lab[30:60, 90:100] = TRAFFIC_LIGHT
    a = propose_lights(img, lab)
    b = propose_lights(img, lab, depth=np.full(lab.shape, np.nan, np.float32))
    assert np.array_equal(a.annotation.instance_map, b.annotation.instance_map)


def test_scene_instances_field_is_validated_and_loaded_from_a_dataset(tmp_path):
    import cv2

    from npsim_core.datasets import iter_folder
    from npsim_core.io import write_image
    from npsim_core.scene import Scene

    img, lab = canvas(H=32, W=64)
    with pytest.raises(NpsimInputError, match="instances"):
        Scene("x", img, lab, Intrinsics.cityscapes(64, 32), instances=np.zeros((3, 3), np.int32))
    write_image(tmp_path / "f.png", img)
    write_image(tmp_path / "f_labelIds.png", lab)
    src = next(iter_folder(tmp_path))
    assert src.load().instances is None
    inst = np.full((32, 64), 23, np.uint16)
    inst[10:20, 10:30] = 26001
    cv2.imwrite(str(tmp_path / "f_instanceIds.png"), inst)
    got = src.load().instances
    assert got is not None and got.dtype == np.int32 and int(got[15, 15]) == 26001


def test_cli_propose_writes_the_editor_files(tmp_path, capsys):
    from npsim_cli.main import main

    assert main(["sample", "--size", "256x128", "-o", str(tmp_path / "scene"), "--no-preview"]) == 0
    capsys.readouterr()
    assert main(["propose", str(tmp_path / "scene"), "-o", str(tmp_path / "out")]) == 0
    text = capsys.readouterr().out
    assert "traffic_light_lamps: 3 lights in 1 group," in text and "windows:" in text
    name = json.loads((tmp_path / "scene" / "scene.json").read_text())["name"]
    ann = load_annotation(tmp_path / "out", name)
    doc = json.loads((tmp_path / "out" / f"{name}_lights.json").read_text())
    conf = doc["meta"]["proposal_confidence"]
    assert set(conf) == {str(i) for i in ann.instance_ids()} | {str(g) for g in ann.groups}
    assert all(0.5 <= v <= 1 for v in conf.values())
    assert (tmp_path / "out" / f"{name}_lights_coco.json").exists()
    assert (tmp_path / "out" / f"{name}_lights_classIds.png").exists()


def test_cli_propose_bad_input_exits_2(tmp_path, capsys):
    from npsim_cli.main import main

    assert main(["propose", str(tmp_path / "missing"), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "missing" in err and len(err.strip().splitlines()) == 1
    assert main(["propose", str(tmp_path), "-o", str(tmp_path / "o"), "--min-confidence", "2"]) == 2


def test_touching_vehicles_without_instance_ids_split_where_depth_jumps():
    from npsim_core.proposals.core import _check_inputs
    from npsim_core.proposals.vehicles import _split_by_depth

    img, lab = canvas(H=60, W=120)
    lab[20:50, 10:110] = CAR                                  # one component in the image...
    depth = np.full(lab.shape, 30.0, np.float32)
    depth[20:50, 10:60] = 10.0                                # ...but two cars, 10 m and 16 m away
    depth[20:50, 60:110] = 16.0
    ctx = _check_inputs(img, lab, depth, None, None)
    m = lab[20:50, 10:110] == CAR
    parts = _split_by_depth(ctx, 20, 10, m)
    assert len(parts) == 2
    spans = sorted((x0, x0 + pm.shape[1]) for _, x0, pm in parts)   # the cut pixels go to the nearer piece
    assert spans[0][0] == 10 and spans[1][1] == 110 and abs(spans[0][1] - 60) <= 1 and spans[0][1] == spans[1][0]
    depth[20:50, 10:110] = 10.0 + np.linspace(0, 1.0, 100)[None, :]   # one car's side receding: no split
    assert len(_split_by_depth(_check_inputs(img, lab, depth, None, None), 20, 10, m)) == 1


def test_a_proposed_signal_head_lights_one_lamp_the_one_the_day_photo_shows():
    from npsim_core.render.lights import activate_lights, load_light_table

    img, lab = canvas()
    lab[30:60, 90:100] = TRAFFIC_LIGHT
    img[30:60, 90:100] = (15, 15, 15)
    for k, col in enumerate(((60, 10, 10), (60, 45, 5), (40, 250, 150))):    # green lit, red and amber dark
        img[32 + 10 * k:38 + 10 * k, 92:98] = col
    props = propose_lights(img, lab)
    ann = props.above(0.5)
    (gid,) = [g for g in ann.groups if class_of(g) == 20]
    members = sorted(ann.groups[gid].members, key=lambda i: np.nonzero(ann.mask(i))[0].mean())
    assert [ann.meta["lamp_colours"][str(i)] for i in members] == ["red", "amber", "green"]
    assert ann.meta["traffic_light_states"] == {str(gid): "green"}
    table = load_light_table()
    for seed in range(5):
        act = activate_lights(ann, table, seed, image=img)
        assert [i for i in members if act.lights[i].on] == [members[2]]
        assert act.lights[members[2]].chromaticity == pytest.approx(table.traffic_light["colours"]["green"])
    img[52:58, 92:98] = (20, 60, 40)                                # nothing lit by day: no state, the seed picks
    assert "traffic_light_states" not in propose_lights(img, lab).above(0.5).meta


def test_a_car_seen_from_behind_gives_two_symmetric_rear_lamps_and_none_on_its_plate():
    img, lab, depth, intr, inst, truth = _car_frame(paint=(150, 150, 155))
    row = lambda h: int(round(59.5 + (1.22 - h) * 50))  # noqa: E731
    img[row(0.56):row(0.43), 87:113] = (235, 235, 225)              # a white plate, centred, below the lamps
    img[row(0.84):row(0.69), 55 + 19:55 + 23] = (200, 20, 20)       # the right-hand lamp's red runs on asymmetrically
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert len(lamps) == 2 and len({class_of(i) for i in lamps}) == 1 and class_of(lamps[0]) in (4, 6)
    plate = np.zeros(lab.shape, bool)
    plate[row(0.56):row(0.43), 87:113] = True
    masks = sorted((ann.mask(i) for i in lamps), key=lambda m: np.nonzero(m)[1].mean())
    for mk in masks:
        assert not (mk & plate).any()                                 # plates are never lamps
    (ya, xa), (yb, xb) = (np.nonzero(mk) for mk in masks)
    assert (ya.min(), ya.max()) == (yb.min(), yb.max())               # same rows
    axis = (xa.min() + xb.max()) / 2.0
    assert abs(axis - (55 + 145 - 1) / 2.0) <= 1.5                    # about the car's vertical axis
    assert abs((axis - xa.max()) - (xb.min() - axis)) <= 1 and len(xa) == len(xb)   # mirror images
    assert iou(masks[0], truth[0]) >= 0.5 and iou(masks[1], truth[1]) >= 0.5


def test_a_car_at_the_kerb_is_parked_a_car_in_the_lane_is_driving():
    img, lab, depth, intr, inst, _ = _car_frame()
    row = lambda h: int(round(59.5 + (1.22 - h) * 50))  # noqa: E731
    lab[row(0.6):, 145:160] = 8                                      # sidewalk 0.3 m right of the car
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert len(lamps) == 2 and all(class_of(i) == 4 for i in lamps)  # parked_rear
    img, lab, depth, intr, inst, _ = _car_frame()
    side = Intrinsics(fx=500.0, fy=500.0, cx=99.5 + 160, cy=59.5, width=200, height=120)   # 3.2 m to the left
    ann, lamps = _lights(propose_lights(img, lab, depth, side, inst, params=FLAT), (3, 4, 5, 6))
    assert lamps and all(class_of(i) == 4 for i in lamps)            # beside the driving lanes: parked


LAYOUT_CLASSES = (SKY, ROAD, 8, BUILDING, POLE, TRAFFIC_LIGHT, CAR, 27, 28, 21, 24)


@st.composite
def _label_layouts(draw):
    """A random street-like frame: rectangles of random classes, colours and depths, some depth
    missing or invalid, instance ids on some vehicles (others crowd)."""
    H, W = draw(st.sampled_from([(24, 48), (40, 64), (64, 128)]))
    rng = np.random.default_rng(draw(st.integers(0, 2**31 - 1)))
    lab = np.full((H, W), SKY, np.uint8)
    img = rng.integers(0, 256, (H, W, 3)).astype(np.uint8) if draw(st.booleans()) else \
        np.full((H, W, 3), draw(st.integers(0, 255)), np.uint8)
    depth = np.full((H, W), np.nan, np.float32)
    inst = np.zeros((H, W), np.int32)
    for k in range(draw(st.integers(0, 12))):
        c = LAYOUT_CLASSES[int(rng.integers(len(LAYOUT_CLASSES)))]
        y0, x0 = int(rng.integers(0, H)), int(rng.integers(0, W))
        y1, x1 = min(H, y0 + int(rng.integers(1, H))), min(W, x0 + int(rng.integers(1, W)))
        lab[y0:y1, x0:x1] = c
        img[y0:y1, x0:x1] = rng.integers(0, 256, 3)
        depth[y0:y1, x0:x1] = float(rng.choice([np.nan, np.inf, -1.0, 0.0, rng.uniform(0.5, 200.0)]))
        if c in (CAR, 27, 28) and rng.random() < 0.7:
            inst[y0:y1, x0:x1] = c * 1000 + k
    inst = np.where(inst > 0, inst, lab).astype(np.int32)
    return img, lab, depth if draw(st.booleans()) else None, inst if draw(st.booleans()) else None


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_label_layouts())
def test_random_label_layouts_give_no_warning_no_nan_and_a_valid_annotation(case):
    """Empty sets (no lamp pixel, a face beyond the frame, all-invalid depth) are handled where they arise."""
    import warnings

    from npsim_core.render.lights import activate_lights, load_light_table

    img, lab, depth, inst = case
    with warnings.catch_warnings():
        warnings.simplefilter("error")                      # numpy's "Mean of empty slice" included
        props = propose_lights(img, lab, depth, None, inst)
        ann = props.above(0.0)
        act = activate_lights(ann, load_light_table(), 0, image=img)
    ann.validate()
    areas = ann.areas()
    assert all(areas.get(i, 0) > 0 for i in ann.instance_ids())        # no empty light
    assert all(np.isfinite(v) and 0.0 <= v <= 1.0 for v in props.confidence.values())
    assert all(np.isfinite(s.radiance).all() for s in act.lights.values())
    for gid, g in ann.groups.items():
        if g.class_id == 20 and len(g.members) == 3:
            assert sum(act.lights[m].on for m in g.members) == 1


def test_a_vehicle_whose_lamp_rows_fall_below_it_gives_no_empty_slice_warning():
    """A squat, near vehicle: its lamp rows lie below its silhouette, so no lamp pixel is left (the old
    code averaged that empty set: numpy's 'Mean of empty slice' and a NaN colour)."""
    import warnings

    img, lab = canvas(H=60, W=120, color=(120, 120, 120))
    lab[50:53, 20:70] = CAR
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        props = propose_lights(img, lab, np.full(lab.shape, 1.5, np.float32))
    assert not [i for i in props.annotation.instance_ids() if class_of(i) in (3, 4, 5, 6)]


def _facade(H=160, W=240, wall=(170, 150, 120)):
    """A facade at 20 m, 10 px per metre, seen straight on."""
    img, lab = canvas(H=H, W=W)
    lab[20:150, 20:220] = BUILDING
    img[20:150, 20:220] = wall
    lab[150:, :] = ROAD
    depth = np.full(lab.shape, 20.0, np.float32)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=119.5, cy=79.5, width=W, height=H)
    return img, lab, depth, intr


def test_a_facade_grid_gives_one_window_per_cell_and_none_across_cells():
    img, lab, depth, intr = _facade()
    cells = {}
    for r in range(3):
        for c in range(5):
            y, x = 35 + 35 * r, 35 + 38 * c
            img[y:y + 15, x:x + 12] = (30, 35, 45)                    # 1.2 x 1.5 m panes
            cells[(r, c)] = (y, y + 15, x, x + 12)
    img[40:46, 47:111] = (30, 35, 45)     # a shadow band joining three panes of the top floor (bays 0-2)
    img[84:106, 149:153] = (35, 38, 46)   # a dark downpipe joining two floors of bay 3
    props = propose_lights(img, lab, depth, intr, params=FLAT)
    ann, wins = _lights(props, (1,))
    owner = {}
    for i in wins:
        ys, xs = np.nonzero(ann.mask(i))
        hit = [k for k, (y0, y1, x0, x1) in cells.items()
               if ys.min() < y1 + 3 and ys.max() >= y0 - 3 and xs.min() < x1 + 3 and xs.max() >= x0 - 3]
        assert len(hit) == 1, (i, hit)                                 # no window across cells
        owner.setdefault(hit[0], []).append(i)
    assert sorted(owner) == sorted(cells) and all(len(v) == 1 for v in owner.values())   # one per cell
    for k, (i,) in owner.items():
        y0, y1, x0, x1 = cells[k]
        m = np.zeros(lab.shape, bool)
        m[y0:y1, x0:x1] = True
        assert iou(ann.mask(i), m) >= 0.6


def test_a_gable_with_six_windows_gives_six():
    img, lab, depth, intr = _facade(H=200)
    lab[:, :] = SKY
    img[:] = (150, 170, 200)
    lab[150:, :] = ROAD
    img[150:] = (70, 70, 75)
    wall, brick = (170, 150, 120), (120, 80, 60)
    lab[100:150, 40:200] = BUILDING                                   # the top storey...
    img[100:150, 40:200] = wall
    for k, (x0, x1) in enumerate(((50, 190), (75, 165), (100, 140))):  # ...and a stepped gable of darker brick
        y = 100 - 20 * (k + 1)
        lab[y:y + 20, x0:x1] = BUILDING
        img[y:y + 20, x0:x1] = brick
    truth = []
    for k, n in enumerate((3, 2, 1)):
        x0, x1 = ((50, 190), (75, 165), (100, 140))[k]
        y = 100 - 20 * (k + 1) + 4
        for j in range(n):
            xc = x0 + (j + 0.5) * (x1 - x0) / n
            xa = int(round(xc - 4))
            img[y:y + 12, xa:xa + 8] = (25, 30, 40)
            m = np.zeros(lab.shape, bool)
            m[y:y + 12, xa:xa + 8] = True
            truth.append(m)
    for c in range(4):                                                # the storey below: 4 windows
        img[112:127, 55 + 38 * c:67 + 38 * c] = (30, 35, 45)
    depth = np.full(lab.shape, 20.0, np.float32)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=119.5, cy=99.5, width=240, height=200)
    props = propose_lights(img, lab, depth, intr, params=FLAT)
    ann, wins = _lights(props, (1,))
    gable = [i for i in wins if np.nonzero(ann.mask(i))[0].max() < 100]
    assert len(gable) == 6
    for m in truth:
        assert max(iou(ann.mask(i), m) for i in gable) >= 0.6
    assert len(wins) == 10


@pytest.mark.parametrize("seed", [0, 2])
def test_the_lights_street_signals_are_read_as_shown_and_lit_alone_at_night(seed):
    """The lights street's signals show one lit lamp by day (its ground truth in the layout); the
    proposals read that state and the night lights exactly that lamp in every head."""
    from npsim_core.render.lights import activate_lights, load_light_table
    from npsim_core.synthetic import street_scene

    scene = street_scene(256, 128, seed, "lights")
    layout = scene.provenance["layout"]
    ped = layout["pedestrian_signals"]                                 # one pedestrian signal, its own state
    truth = {v for g, v in layout["traffic_light_states"].items() if g not in ped}
    ann = propose_for_scene(scene).above(0.5)
    seen = ann.meta.get("traffic_light_states", {})
    direction = ann.meta.get("traffic_light_direction", {})
    assert len(truth) == 1 and len(ped) == 1 and seen
    assert {v for g, v in seen.items() if direction.get(g) != "pedestrian"} == truth
    act = activate_lights(ann, load_light_table(), 7, image=scene.image)
    heads = {gid: g for gid, g in ann.groups.items() if g.class_id == 20}
    assert sorted(len(g.members) for g in heads.values()) == [2, 3, 3]
    for gid, g in heads.items():
        want = set(ped.values()) if direction.get(str(gid)) == "pedestrian" else truth
        lit = [ann.meta["lamp_colours"][str(m)] for m in g.members if act.lights[m].on]
        assert lit == list(want)


def test_no_lamp_on_a_vehicle_side_that_recedes_from_the_camera():
    """The same silhouette and red patches, but the depth recedes across it (6 -> 10.5 m over 90 px,
    about 3 m of depth per metre across: the car's side, its end face beyond the frame): no lamp;
    facing the camera (flat depth) it keeps its pair."""
    img, lab, depth, intr, inst, _ = _car_frame()
    ys, xs = np.nonzero(lab == CAR)
    side = depth.copy()
    side[ys, xs] = 6.0 + 0.05 * (xs - xs.min())
    _, lamps = _lights(propose_lights(img, lab, side, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert lamps == []
    _, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert len(lamps) == 2


def test_a_rear_lamp_in_shade_is_a_rear_lamp():
    """A rear lamp in shade is dark and only reddish (69, 50, 59 on 99, 107, 125 paint: not red by the
    absolute test) -- its departure from the paint leans to red: a rear lamp; white lamps on blue
    paint stay front lamps."""
    img, lab, depth, intr, inst, _ = _car_frame(rear_color=(69, 50, 59), paint=(99, 107, 125))
    _, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert len(lamps) == 2 and all(class_of(i) in (4, 6) for i in lamps)
    img, lab, depth, intr, inst, _ = _car_frame(rear_color=(240, 240, 230), paint=(40, 60, 140))
    _, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert len(lamps) == 2 and all(class_of(i) in (3, 5) for i in lamps)


def test_a_dark_signal_head_and_a_cabin_band_pass_the_editors_default_slider():
    """Accepted at the editor's default threshold (0.9): a signal head elongated like one, even with its
    lamps dark by day (no contrast bonus). A cabin whose glass is no darker than the paint is still
    proposed as panes at the default 0.5 (the band above the body is mostly glass)."""
    img, lab = canvas()
    lab[30:60, 90:100] = TRAFFIC_LIGHT
    img[30:60, 90:100] = (15, 15, 15)
    props = propose_lights(img, lab)
    tl = [g for g in props.annotation.groups if class_of(g) == 20]
    assert len(tl) == 1 and len(props.above(0.9).groups[tl[0]].members) == 3
    img, lab, depth, intr, inst, _ = _car_frame()
    img[lab == CAR] = (40, 60, 140)                                  # the rear window painted over
    ann = propose_lights(img, lab, depth, intr, inst, params=FLAT).above(0.5)
    assert [i for i in ann.instance_ids() if class_of(i) == 2]


def test_a_sign_on_a_facade_receding_along_the_street_is_an_advertisement():
    """A 3 x 0.6 m red sign on a wall 5 m left of the camera, 31-34 m away, is 7 px wide (0.46 m of
    image width at its depth): its area is measured along the wall (1.8 m^2), not across the image."""
    img, lab = canvas()
    intr = Intrinsics(fx=500.0, fy=500.0, cx=99.5, cy=59.5, width=200, height=120)
    u = np.arange(200, dtype=np.float64)
    z_wall = np.where(u < 95, -5.0 * 500.0 / np.minimum(u - 99.5, -1.0), 80.0)      # the wall at X = -5 m
    depth = np.broadcast_to(z_wall, lab.shape).astype(np.float32).copy()
    lab[:, :95] = BUILDING
    img[:, :95] = (150, 140, 130)
    cols = (u >= 99.5 - 2500.0 / 31.4) & (u <= 99.5 - 2500.0 / 34.4)
    rows = slice(40, 49)                                                               # 0.6 m at ~33 m
    img[rows, cols] = (200, 30, 25)
    ann = propose_lights(img, lab, depth, intr, params=ProposalParams(categories=("ads",))).above(0.5)
    ads = [i for i in ann.instance_ids() if class_of(i) == 10]
    assert len(ads) == 1 and ann.mask(ads[0])[rows, cols].mean() > 0.8


def test_a_car_whose_lower_body_is_hidden_by_the_car_in_front_keeps_its_lamps_on_the_body():
    """The car in front (6 m, nearer) hides the left 40 px of the body: the cabin rows are now wider
    than what shows of the body, so the silhouette's fullest rows are the cabin's (top 1.3 m above
    the ground, too high for a car's body): the lamps stay at the body's height, the visible
    right-hand one on its truth."""
    img, lab, depth, intr, inst, truth = _car_frame()
    row = lambda h: int(round(59.5 + (1.22 - h) * 50))  # noqa: E731
    lab[row(1.4):row(1.3)], img[row(1.4):row(1.3)], inst[row(1.4):row(1.3)] = SKY, (150, 170, 200), SKY
    hide = (slice(row(0.9), row(0.3) + 10), slice(40, 95))
    lab[hide], img[hide], depth[hide], inst[hide] = CAR, (200, 200, 200), 6.0, CAR * 1000 + 1
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    mine = [i for i in lamps if (ann.mask(i) & truth[1]).any() or np.nonzero(ann.mask(i))[1].min() >= 95]
    assert mine and all(np.nonzero(ann.mask(i))[0].min() >= row(0.9) for i in mine)
    assert max(iou(ann.mask(i), truth[1]) for i in mine) >= 0.5


def _parked_row(far_depth_m: float, near_depth_m: float | None):
    """A road, a red car in front (15 m, columns 100-150) and everything else at ``far_depth_m``;
    the car in front's depth is ``near_depth_m`` (None: the depth does not see it). Returns
    (img, lab, intr, depth, inst, row) with ``row(h, z)`` the image row of height ``h`` m at ``z`` m."""
    img, lab = canvas()
    lab[95:], img[95:] = ROAD, (70, 70, 75)
    intr = Intrinsics(fx=500.0, fy=500.0, cx=99.5, cy=59.5, width=200, height=120)
    depth = np.full(lab.shape, far_depth_m, np.float32)
    inst = lab.astype(np.int32)

    def row(h: float, z: float) -> int:
        return int(round(59.5 + (1.22 - h) * 500.0 / z))

    near = (slice(row(1.4, 15.0), 101), slice(100, 150))
    lab[near], img[near], inst[near] = CAR, (160, 40, 40), CAR * 1000
    if near_depth_m is not None:
        depth[near] = near_depth_m
    return img, lab, intr, depth, inst, row


def test_no_lamp_on_a_far_car_of_which_only_a_strip_beside_the_car_in_front_shows():
    """Far down a row of parked cars only a strip of a car's side shows beside the nearer car in front
    (5 px at 30 m here, receding): its end face is hidden, so it gets no lamp. The old code laid the
    face out from the occluder's edge as if that were the car's own and put a lamp on the strip."""
    img, lab, intr, depth, inst, row = _parked_row(80.0, 15.0)      # the car in front at 15 m
    strip = (slice(row(1.4, 30.0), row(0.3, 30.0)), slice(150, 155))          # the far car's side, 30-31 m
    lab[strip], img[strip], inst[strip] = CAR, (40, 60, 140), CAR * 1000 + 1
    depth[strip] = 30.0 + 0.25 * (np.arange(150, 155) - 150)
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert not any((ann.mask(i) & (inst == CAR * 1000 + 1)).any() for i in lamps)


def test_a_pedestrian_signal_is_proposed_as_such():
    """Beside a vehicle signal (0.4 x 1.0 m housing, 2.5 m up, three lamps) a pedestrian signal (0.32 x
    0.68 m, two lamps, its green figure lit by day), both at 20 m: two lamps, red over green, its group
    marked ``pedestrian`` (its own state) and its state read; the vehicle head keeps three lamps. The
    old proposer gave it three lamps in the vehicles' direction."""
    img, lab = canvas()
    intr = Intrinsics(fx=500.0, fy=500.0, cx=99.5, cy=59.5, width=200, height=120)
    depth = np.full(lab.shape, 60.0, np.float32)
    row = lambda h: int(round(59.5 + (1.22 - h) * 25))  # noqa: E731  (20 m: 25 px per metre)
    car = (slice(row(3.5), row(2.5)), slice(40, 50))                # vehicle head, 25 x 10 px
    ped = (slice(row(2.78), row(2.1)), slice(140, 148))             # pedestrian head, 17 x 8 px
    for hs in (car, ped):
        lab[hs], img[hs], depth[hs] = TRAFFIC_LIGHT, (15, 15, 15), 20.0
    for k, col in enumerate(((60, 10, 10), (60, 45, 5), (20, 60, 40))):
        img[row(3.5) + 1 + 8 * k:row(3.5) + 7 + 8 * k, 42:48] = col
    img[row(2.73):row(2.49), 141:147] = (60, 10, 10)                # red figure, dark
    img[row(2.39):row(2.15), 141:147] = (40, 250, 150)              # green figure, lit
    ann = propose_lights(img, lab, depth, intr, params=FLAT).above(0.5)
    heads = {g: ann.groups[g].members for g in ann.groups if class_of(g) == 20}
    assert sorted(len(m) for m in heads.values()) == [2, 3]
    (gid,) = [g for g, m in heads.items() if len(m) == 2]
    assert ann.meta["traffic_light_direction"] == {str(gid): "pedestrian"}
    lamps = sorted(heads[gid], key=lambda i: np.nonzero(ann.mask(i))[0].mean())
    assert [ann.meta["lamp_colours"][str(i)] for i in lamps] == ["red", "green"]
    assert ann.meta["traffic_light_states"][str(gid)] == "green"
    truth_green = np.zeros(lab.shape, bool)
    truth_green[row(2.39):row(2.15), 141:147] = True
    assert iou(ann.mask(lamps[1]), truth_green) >= 0.5


def test_a_far_pole_whose_arm_the_labels_lost_gets_its_lamp_at_the_head_beside_its_top():
    """An 8 m pole at 100 m (2 px per metre): the 0.12 m arm is under a pixel and not labelled, so the
    head is a speck of pole 1.8 m beside the trunk's top. The lamp is that speck (the old proposer put
    a low-confidence lamp on the bare trunk top and skipped the speck)."""
    img, lab = canvas(H=200, W=200)
    lab[150:, :] = ROAD
    depth = np.full((200, 200), 100.0, np.float32)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=99.5, cy=99.5, width=200, height=200)
    foot = int(round(99.5 + 1.22 * 2))
    top = foot - 16
    lab[top:foot, 60], img[top:foot, 60] = POLE, (80, 80, 85)          # the trunk, 1 px
    lab[top + 1:top + 2, 63:66], img[top + 1:top + 2, 63:66] = POLE, (200, 200, 190)   # the head
    props = propose_lights(img, lab, depth, intr, params=FLAT)
    ann, lamps = _lights(props, (8, 9))
    assert len(lamps) == 1 and class_of(lamps[0]) == 8
    ys, xs = np.nonzero(ann.mask(lamps[0]))
    assert (ys.min(), ys.max(), xs.min(), xs.max()) == (top + 1, top + 1, 63, 65)


def test_no_lamp_on_a_car_showing_a_fraction_of_its_end_face_even_when_depth_misses_the_car_in_front():
    """The same far strip, but the predicted depth has blurred the car in front to the far car's depth
    (no occluder is seen beside it): a silhouette under a third of a car's width at its depth
    (``vehicle_min_face_share``) still gets no lamp."""
    img, lab, intr, depth, inst, row = _parked_row(30.0, None)
    strip = (slice(row(1.4, 30.0), row(0.3, 30.0)), slice(150, 157))          # 7 px of a 30 px face
    lab[strip], img[strip], inst[strip] = CAR, (40, 60, 140), CAR * 1000 + 1
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert not any((ann.mask(i) & (inst == CAR * 1000 + 1)).any() for i in lamps)


def test_a_far_pole_whose_foot_is_hidden_still_gets_its_lamp():
    """The same far pole with all but its top 8 px hidden behind a hedge: an 8-px trunk is a pole
    (``pole_min_area_px`` 6; it was 10, so its lamp was missed)."""
    img, lab = canvas(H=200, W=200)
    lab[150:, :] = ROAD
    depth = np.full((200, 200), 100.0, np.float32)
    intr = Intrinsics(fx=200.0, fy=200.0, cx=99.5, cy=99.5, width=200, height=200)
    top = int(round(99.5 + 1.22 * 2)) - 16
    lab[top:top + 8, 60], img[top:top + 8, 60] = POLE, (80, 80, 85)
    lab[top + 8:top + 20, 50:75], img[top + 8:top + 20, 50:75] = 21, (30, 70, 30)      # the hedge
    lab[top + 1:top + 2, 63:66], img[top + 1:top + 2, 63:66] = POLE, (200, 200, 190)
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, params=FLAT), (8, 9))
    assert len(lamps) == 1 and np.nonzero(ann.mask(lamps[0]))[1].min() == 63


def test_a_car_whose_cabin_shows_over_the_car_in_front_keeps_its_lamp_on_the_body():
    """A van in front (6 m) hides the right 35 px of a car at 10 m up to its cabin (rows from 1.14 m at
    6 m), so over columns 110-140 only the car's cabin shows, and predicted depth has bled the van's
    nearness into those columns (7 m). The end face is laid out from the columns the silhouette holds at
    body height: the visible left lamp is proposed on its truth. The old code took the cabin strip's
    depth for the car's nearer side, laid the face out from there and proposed no lamp on the left."""
    img, lab, depth, intr, inst, truth = _car_frame()
    van = (slice(66, 120), slice(110, 200))
    lab[van], img[van], depth[van], inst[van] = CAR, (200, 200, 200), 6.0, CAR * 1000 + 1
    cab = (slice(0, 66), slice(110, 145))
    depth[cab] = np.where(inst[cab] == CAR * 1000, 7.0, depth[cab])     # the van's depth bled into the cabin
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert max((iou(ann.mask(i), truth[0]) for i in lamps), default=0.0) >= 0.5


def test_a_car_cut_by_the_car_in_front_gets_the_lamp_its_end_face_strip_shows():
    """In a parked row the car in front (7 m) hides all but the inner 20 px of a car's end face at 10 m
    (under a quarter of its 90 px width); beside the strip the car's side recedes to 14 m. The strip
    holds the inner lamp, whole: it is proposed on its truth. The old code looked for the face's inner
    edge from a third of a face width on, found none and proposed no lamp on the car."""
    img, lab, depth, intr, inst, truth = _car_frame()
    row = lambda h: int(round(59.5 + (1.22 - h) * 50))  # noqa: E731
    side = (slice(row(0.9), row(0.3)), slice(20, 55))
    lab[side], img[side], inst[side] = CAR, (28, 42, 100), CAR * 1000          # the side, in shade
    depth[side] = 10.0 + 0.12 * (55 - np.arange(20, 55))
    front = (slice(30, 120), slice(75, 200))
    lab[front], img[front], depth[front], inst[front] = CAR, (200, 200, 200), 7.0, CAR * 1000 + 1
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert max((iou(ann.mask(i), truth[0]) for i in lamps), default=0.0) >= 0.5


def test_a_rear_window_half_covered_by_a_reflection_is_proposed_whole():
    """The right 55 % of a car's rear window mirrors the bright sky: the pane proposed is the cabin
    band, whole (IoU >= 0.5 with the window). The old code, seeing 30 % of the band darker than the
    paint, proposed only the dark part (IoU under 0.5)."""
    img, lab, depth, intr, inst, _ = _car_frame()
    row = lambda h: int(round(59.5 + (1.22 - h) * 50))  # noqa: E731
    window = np.zeros(lab.shape, bool)
    window[row(1.33):row(0.97), 64:136] = True
    img[row(1.33):row(0.97), 96:136] = (185, 195, 210)               # the reflection
    ann, panes = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (2,))
    assert max((iou(ann.mask(i), window) for i in panes), default=0.0) >= 0.5


def _window_row_annotation():
    """Three windows in a row (one windows_group) and a lamp beside them, on a 40 x 80 image."""
    from npsim_core.annotation import GroupInstance, LightAnnotation

    m = np.zeros((40, 80), np.int32)
    for k in range(3):
        m[10:16, 10 + 12 * k:16 + 12 * k] = 1001 + k
    m[30:33, 70:75] = 8001                                           # a street lamp below, in no group
    return LightAnnotation(m, {13001: GroupInstance(13001, (1001, 1002, 1003))})


def test_editor_actions_count_drawn_lights_as_selected_and_a_band_over_accepted_ones(qapp):
    """The action model of ``benchmarks.annotation_actions`` (its module doc): a row of three windows
    drawn from scratch is 3 strokes, 1 class key per class drawn (windows, the lamp) and Ctrl+G -- the
    editor leaves the lights of consecutive one-light-per-region strokes selected -- where the older
    model clicked each again (3 + 1); three accepted windows are grouped with one rubber band and
    Ctrl+G (2), not 3 clicks and Ctrl+G."""
    from benchmarks.annotation_actions import check_equal, finish_by_hand
    from npsim_core.annotation_ops import new_instance, paint
    from npsim_gui.editor.session import EditorSession

    gt = _window_row_annotation()
    img = np.zeros((40, 80, 3), np.uint8)
    kinds = ("draw", "class keys", "group", "remove", "class fix", "touch up", "ungroup")
    totals = {}
    for old in (False, True):
        for accepted in (False, True):
            s = EditorSession(superpixels=False)
            s.load(img, None, None)
            if accepted:                                             # the windows are there, ungrouped
                for i in (1001, 1002, 1003):
                    cmd, nid = new_instance(s.ann, 1)
                    s.apply(cmd)
                    s.apply(paint(s.ann, gt.instance_map == i, nid, overwrite=True))
            counts = dict.fromkeys(kinds, 0)
            finish_by_hand(s, gt, counts, per_member_grouping=old, stroke_group=False)  # Ctrl+G after the band
            check_equal(gt, s.ann)
            s.shutdown()
            totals[old, accepted] = (counts["draw"], counts["class keys"], counts["group"])
    assert totals[False, False] == (4, 2, 1) and totals[True, False] == (4, 2, 4)
    assert totals[False, True] == (1, 1, 2) and totals[True, True] == (1, 1, 4)


def test_a_few_columns_of_a_cut_car_seen_past_the_car_in_front_do_not_place_its_end_face():
    """The strip of the end face as above, and 2 columns of the same car's body at its own depth seen
    through a notch of the car in front, 15 px further right. The end face's inner edge comes from the
    face's run of near columns, and the strip's lamp is proposed; the old code took the run that starts
    at the outermost near column (the notch's two), found no edge and laid the face out from the
    silhouette's far end."""
    img, lab, depth, intr, inst, truth = _car_frame()
    row = lambda h: int(round(59.5 + (1.22 - h) * 50))  # noqa: E731
    side = (slice(row(0.9), row(0.3)), slice(20, 55))
    lab[side], img[side], inst[side] = CAR, (28, 42, 100), CAR * 1000
    depth[side] = 10.0 + 0.12 * (55 - np.arange(20, 55))
    front = (slice(30, 120), slice(75, 200))
    lab[front], img[front], depth[front], inst[front] = CAR, (200, 200, 200), 7.0, CAR * 1000 + 1
    notch = (slice(row(0.9), row(0.5)), slice(90, 92))
    lab[notch], img[notch], depth[notch], inst[notch] = CAR, (40, 60, 140), 10.0, CAR * 1000
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    assert max((iou(ann.mask(i), truth[0]) for i in lamps), default=0.0) >= 0.5


def test_the_boot_lid_seen_over_the_end_face_does_not_lift_the_lamps():
    """Seen from 1.22 m, a car's boot lid (0.9 m up) shows over its end face as 6 rows of paint whose
    depth grows upward (10.3-12 m), as wide as the body: the silhouette's full rows start at the lid's
    top. The face's top comes from where the depth stops being the face's, and both lamps (the paint's
    colour here: nothing to snap to) lie on their truth; the old code put them 6 rows high."""
    img, lab, depth, intr, inst, truth = _car_frame(rear_color=(40, 60, 140))
    row = lambda h: int(round(59.5 + (1.22 - h) * 50))  # noqa: E731
    top = row(0.9)
    lid = (slice(top - 6, top), slice(55, 145))
    lab[lid], img[lid], inst[lid] = CAR, (40, 60, 140), CAR * 1000
    depth[lid] = (10.0 + 0.3 * (top - np.arange(top - 6, top)))[:, None]
    ann, lamps = _lights(propose_lights(img, lab, depth, intr, inst, params=FLAT), (3, 4, 5, 6))
    for t in truth:
        assert max((iou(ann.mask(i), t) for i in lamps), default=0.0) >= 0.5


def test_core_speed_helpers_give_numpys_and_opencvs_own_values():
    """core.median / nanmedian / pixels and components are speed-ups (docs/proposals.md, "Seventeenth pass:
    the time of the other proposers"): numpy's values, dtypes and types (a -0.0 median is 0.0, as numpy's),
    and OpenCV's components in the order of labelling the whole mask -- the box's corner at an even row and
    column (an odd one reorders OpenCV's 2x2-block scan)."""
    import warnings

    import cv2

    from npsim_core.proposals.core import components, median, nanmedian, pixels

    rng = np.random.default_rng(0)
    for _ in range(300):
        n, k = int(rng.integers(1, 30)), int(rng.integers(1, 4))
        a = np.round(rng.normal(size=(n, k)), 1).astype(rng.choice([np.float32, np.float64]))
        a[rng.random(a.shape) < 0.1] = -0.0
        for x, kw in ((a, {"axis": 0}), (a, {"axis": 1}), (a[:, 0], {}), ((a * 10).astype(np.int64), {})):
            want, got = np.median(x, **kw), median(x, **kw)
            assert type(got) is type(want) and np.array_equal(got, want)
            assert np.array_equal(np.signbit(got), np.signbit(want))
        b = a.copy()
        b[rng.random(b.shape) < 0.4] = np.nan
        for ax in (0, 1):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                want = np.nanmedian(b, axis=ax)
            got = nanmedian(b, ax)
            assert got.dtype == want.dtype and np.array_equal(got, want, equal_nan=True)
        if not np.isnan(b).all():
            want, got = np.nanmedian(b), nanmedian(b)  # axis None: over the whole array
            assert type(got) is type(want) and np.array_equal(got, want)
            assert np.array_equal(np.signbit(got), np.signbit(want))
        b[0, 0] = np.inf  # an inf: numpy's own result
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            assert np.array_equal(nanmedian(b, 0), np.nanmedian(b, axis=0), equal_nan=True)
        img = rng.normal(size=(n, k + 3, 3)).astype(np.float32)
        sel = rng.random((n, k + 3)) < 0.5
        assert np.array_equal(pixels(img[:, 1:], sel[:, 1:]), img[:, 1:][sel[:, 1:]])
    for _ in range(200):
        h, w = (int(v) for v in rng.integers(8, 120, 2))
        m = np.zeros((h, w), bool)
        for _ in range(int(rng.integers(1, 20))):
            y, x = int(rng.integers(0, h)), int(rng.integers(0, w))
            m[y:y + int(rng.integers(1, 8)), x:x + int(rng.integers(1, 8))] = True
        m &= rng.random((h, w)) < 0.7
        for conn in (4, 8):
            n, lab, stats, _ = cv2.connectedComponentsWithStats(m.astype(np.uint8), connectivity=conn)
            want = [(int(s[1]), int(s[0]), lab[s[1]:s[1] + s[3], s[0]:s[0] + s[2]] == q, int(s[4]))
                    for q, s in enumerate(stats) if q > 0 and s[4] >= 2]
            got = list(components(m, 2, conn))
            assert len(got) == len(want)
            for g, wnt in zip(got, want):
                assert g[:2] == wnt[:2] and g[3] == wnt[3] and np.array_equal(g[2], wnt[2])


def test_the_same_proposals_check_tells_any_difference():
    """benchmarks.proposals_same (the check of work meant to change no proposal) finds a single pixel, a
    group member or a confidence that differs, and its frame sets are the benchmark's."""
    from benchmarks.proposals_same import differences, frames

    assert len(frames()) == 27 and len(frames(quick=True)) == 12 and len(frames(textured=True)) == 6
    ref = dict(mask=np.zeros((4, 6), np.int32), groups={13001: (1001, 1002)}, meta={"light_kinds": {}},
               conf={1001: 0.9, 1002: 0.5, 13001: 0.7})
    same = {k: (v.copy() if isinstance(v, np.ndarray) else dict(v)) for k, v in ref.items()}
    assert differences(same, ref) == []
    px = dict(same, mask=same["mask"].copy())
    px["mask"][2, 3] = 1001
    assert differences(px, ref) == ["mask (1 px)"]
    assert differences(dict(same, groups={13001: (1001,)}), ref) == ["groups"]
    assert differences(dict(same, conf={**same["conf"], 1002: 0.5000001}), ref) == ["conf"]
    assert differences(dict(same, mask=np.zeros((4, 5), np.int32)), ref)[0].startswith("mask shape")
