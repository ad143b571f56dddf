"""A vehicle light drawn on a car joins that car's group (one car = one car_group): the editor reads the
frame's Cityscapes instanceIds and saves the annotator the grouping gesture per car
(``annotation_ops.vehicle_grouping``, ``EditorSession.lights_created``; issue #26's twelfth pass)."""

from __future__ import annotations

import numpy as np
import pytest

from npsim_core.annotation import LightAnnotation, discover_items
from npsim_core.annotation_ops import group_lights, new_instance, paint, vehicle_grouping
from npsim_core.errors import NpsimInputError
from npsim_core.io import write_image

H, W = 40, 100
CAR_A, CAR_B, TRUCK = 26001, 26002, 27001


def _instances():
    inst = np.full((H, W), 7, np.int32)                     # road
    inst[10:30, 5:35] = CAR_A
    inst[10:30, 40:70] = CAR_B
    inst[5:30, 75:98] = TRUCK
    return inst


def _add(ann, cls, box):
    cmd, nid = new_instance(ann, cls)
    cmd.redo(ann)
    m = np.zeros(ann.shape, bool)
    m[box] = True
    paint(ann, m, nid, overwrite=True).redo(ann)
    return nid


@pytest.fixture
def ann():
    return LightAnnotation.empty(H, W)


def test_a_vehicle_light_goes_into_its_cars_group(ann):
    inst = _instances()
    lamp = _add(ann, 4, np.s_[22:25, 8:12])                  # parked_rear lamp on car A, alone: a group of one
    assert vehicle_grouping(ann, inst, lamp) == (None, (lamp,), 14)
    group_lights(ann, [lamp], 14)[0].redo(ann)
    gid = ann.group_of(lamp)
    pane = _add(ann, 2, np.s_[12:16, 10:30])                # its rear window joins that group
    assert vehicle_grouping(ann, inst, pane) == (gid, (pane,), 14)
    other = _add(ann, 4, np.s_[22:25, 45:49])                # a lamp of car B is not car A's
    assert vehicle_grouping(ann, inst, other) == (None, (other,), 14)
    truck = _add(ann, 7, np.s_[8:12, 80:90])                 # a truck's window: truck_group
    assert vehicle_grouping(ann, inst, truck) == (None, (truck,), 15)


def test_lights_off_a_vehicle_or_of_no_vehicle_class_are_left_alone(ann):
    inst = _instances()
    window = _add(ann, 1, np.s_[12:16, 10:20])               # a building window's class, on a car's pixels
    road = _add(ann, 4, np.s_[32:35, 10:14])                 # a lamp on the road
    half = _add(ann, 4, np.s_[26:34, 30:34])                 # under half of it on car A
    assert vehicle_grouping(ann, inst, window) is None
    assert vehicle_grouping(ann, inst, road) is None
    assert vehicle_grouping(ann, inst, half) is None


def test_a_car_whose_lights_are_in_two_groups_is_left_to_the_annotator(ann):
    inst = _instances()
    a = _add(ann, 4, np.s_[22:25, 8:12])
    b = _add(ann, 4, np.s_[22:25, 28:32])
    group_lights(ann, [a], 14)[0].redo(ann)
    group_lights(ann, [b], 14)[0].redo(ann)
    pane = _add(ann, 2, np.s_[12:16, 10:30])
    assert vehicle_grouping(ann, inst, pane) is None
    c = _add(ann, 4, np.s_[22:25, 45:49])                    # car B: an ungrouped mate is taken along
    d = _add(ann, 4, np.s_[22:25, 62:66])
    assert vehicle_grouping(ann, inst, d) == (None, (c, d), 14)


def test_the_editor_groups_a_car_as_its_lights_are_drawn(qtbot):
    from npsim_gui.editor.session import EditorSession

    s = EditorSession(superpixels=False)
    s.load(np.zeros((H, W, 3), np.uint8), None, None)
    with pytest.raises(NpsimInputError, match="instance ids"):
        s.set_vehicle_instances(np.zeros((H, W + 1), np.int32))
    s.set_vehicle_instances(_instances())

    def draw(cls, box):
        s.begin_stroke("draw")
        cmd, nid = new_instance(s.ann, cls)
        s.apply(cmd)
        m = np.zeros((H, W), bool)
        m[box] = True
        s.apply(paint(s.ann, m, nid, overwrite=True))
        s.lights_created([nid])
        s.end_stroke()
        return nid

    lamp = draw(4, np.s_[22:25, 8:12])
    pane = draw(2, np.s_[12:16, 10:30])
    (gid, g), = s.ann.groups.items()
    assert gid // 1000 == 14 and set(g.members) == {lamp, pane}
    s.undo()                                                   # the draw and its grouping: one undo step
    assert set(s.ann.groups[gid].members) == {lamp} and pane not in s.ann.instance_ids()
    s.redo()
    s.group_by_vehicle = False                                 # the option off: drawn lights stay ungrouped
    loose = draw(4, np.s_[22:25, 45:49])
    assert s.ann.group_of(loose) is None
    s.group_by_vehicle = True
    s.set_active_group(gid)                                    # the active group comes first
    odd = draw(4, np.s_[22:25, 62:66])
    assert s.ann.group_of(odd) == s.ann.group_of(lamp)
    s.load(np.zeros((H, W, 3), np.uint8), None, None)          # a new image: its own instances or none
    assert s.vehicle_instances is None
    s.shutdown()


def test_the_action_benchmark_charges_no_grouping_for_a_car_drawn_with_instance_ids(qtbot):
    from benchmarks.annotation_actions import check_equal, finish_by_hand
    from npsim_core.annotation import GroupInstance
    from npsim_gui.editor.session import EditorSession

    gt_map = np.zeros((H, W), np.int32)
    gt_map[22:25, 8:12], gt_map[22:25, 28:32], gt_map[12:16, 10:30] = 4001, 4002, 2001
    gt = LightAnnotation(gt_map, {14001: GroupInstance(14001, (2001, 4001, 4002))})
    got = {}
    for with_ids in (True, False):
        s = EditorSession(superpixels=False)
        s.load(np.zeros((H, W, 3), np.uint8), None, None)
        if with_ids:
            s.set_vehicle_instances(_instances())
        counts = dict.fromkeys(("draw", "class keys", "group", "tool", "remove", "class fix", "touch up",
                                "ungroup"), 0)
        finish_by_hand(s, gt, counts)
        check_equal(gt, s.ann)
        got[with_ids] = (counts["draw"], counts["group"])
        s.shutdown()
    assert got == {True: (3, 0), False: (3, 1)}


def test_an_annotation_item_finds_the_instance_ids_beside_its_labels(tmp_path):
    img = np.zeros((4, 6, 3), np.uint8)
    write_image(tmp_path / "b_leftImg8bit.png", img)
    write_image(tmp_path / "b_gtFine_labelIds.png", np.zeros((4, 6), np.uint8))
    write_image(tmp_path / "c.png", img)
    write_image(tmp_path / "c_labelIds.png", np.zeros((4, 6), np.uint8))
    inst = np.full((4, 6), 26001, np.uint16)
    write_image(tmp_path / "b_gtFine_instanceIds.png", inst)
    b, c = discover_items(tmp_path)
    assert (b.load_instances((4, 6)) == 26001).all() and b.load_instances((4, 6)).dtype == np.int32
    assert c.load_instances((4, 6)) is None
    write_image(tmp_path / "c_instanceIds.png", np.zeros((3, 6), np.uint16))
    with pytest.raises(NpsimInputError, match="c_instanceIds.png"):
        c.load_instances((4, 6))


def test_a_session_without_superpixels_starts_no_job(qtbot):
    """``EditorSession(superpixels=False)`` (the action benchmark's replays, which draw from given masks)
    never starts a superpixel job: no pool thread runs native code behind a session a script drops (a
    worker crashed in such a test under load)."""
    from PySide6.QtCore import QThreadPool

    from npsim_gui.editor.session import EditorSession

    QThreadPool.globalInstance().waitForDone()
    s = EditorSession(superpixels=False)
    s.load(np.zeros((H, W, 3), np.uint8), None, None)
    assert QThreadPool.globalInstance().activeThreadCount() == 0
    qtbot.wait(50)
    assert s.sp_coarse is None and not s.superpixels_ready
    s.shutdown()
