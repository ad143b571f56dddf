"""Light annotation model, undoable edits, formats, recovery and superpixels (no Qt)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from npsim_core import annotation as A
from npsim_core.annotation import (LightAnnotation, autosave_path, discover_items, find_recovery,
                                   from_coco, load_annotation, load_coco, load_recovery, rle_decode, rle_encode,
                                   rle_from_indices, rle_to_string, save_annotation, to_coco, write_recovery)
from npsim_core.annotation_ops import (UndoStack, change_class, delete_instance, erase, group_lights, new_instance,
                                       paint, snap_to_superpixels, split_paint, ungroup)
from npsim_core.errors import NpsimInputError
from npsim_core.io import write_image
from npsim_core.superpixels import (METHODS, SuperpixelParams, boundary_mask, cached_superpixels,
                                    compute_superpixels, disk_index, superpixel_index, superpixel_pair)


def rect_mask(shape, x0, y0, x1, y1):
    m = np.zeros(shape, bool)
    m[y0:y1, x0:x1] = True
    return m


def sample_annotation() -> LightAnnotation:
    ann = LightAnnotation.empty(40, 64)
    ann.instance_map[2:6, 3:9] = 1001
    ann.instance_map[2:6, 12:18] = 1002
    ann.instance_map[20:25, 40:44] = 5001
    ann.instance_map[30, 60] = 12001  # single pixel
    ann.extra_ids.add(9001)  # a light without pixels
    ann.groups[13001] = A.GroupInstance(13001, (1001, 1002))
    ann.meta["done"] = True
    return ann


def assert_same(a: LightAnnotation, b: LightAnnotation) -> None:
    np.testing.assert_array_equal(a.instance_map, b.instance_map)
    assert a.instance_ids() == b.instance_ids()
    assert a.groups == b.groups


# --------------------------------------------------------------------------- model and commands
def test_stats_bbox_area():
    st = sample_annotation().stats()
    assert st[1001] == {"area": 24, "bbox": [3, 2, 8, 5]}
    assert st[12001] == {"area": 1, "bbox": [60, 30, 60, 30]}
    assert st[9001] == {"area": 0, "bbox": None}


def test_every_edit_undoes_and_redoes_exactly():
    ann = LightAnnotation.empty(48, 80)
    stack = UndoStack(ann)
    snapshots = [ann.copy()]

    def push(cmd):
        stack.push(cmd)
        snapshots.append(ann.copy())

    cmd, a = new_instance(ann, 1)
    push(cmd)
    push(paint(ann, rect_mask(ann.shape, 2, 2, 10, 8), a))
    cmd, ids = split_paint(ann, rect_mask(ann.shape, 20, 2, 24, 8) | rect_mask(ann.shape, 30, 2, 34, 8), 1)
    assert ids == [1002, 1003]
    push(cmd)
    cmd, g = group_lights(ann, [a, *ids], 13)
    push(cmd)
    push(erase(ann, rect_mask(ann.shape, 0, 0, 6, 48)))  # part of light a
    push(paint(ann, rect_mask(ann.shape, 8, 0, 22, 4), a, overwrite=True))  # steals from 1002
    cmd, moved = change_class(ann, ids[0], 2)
    push(cmd)
    push(delete_instance(ann, ids[1]))
    cmd, g2 = change_class(ann, g, 14)
    push(cmd)
    push(ungroup(ann, g2))
    assert len(stack) == len(snapshots) - 1
    for k in range(len(snapshots) - 1, 0, -1):
        assert_same(ann, snapshots[k])
        stack.undo()
    assert_same(ann, snapshots[0])
    for k in range(1, len(snapshots)):
        stack.redo()
        assert_same(ann, snapshots[k])
    assert stack.redo() is None


def test_invariants():
    ann = LightAnnotation.empty(20, 20)
    ann.instance_map[0:5, 0:5] = 1001
    ann.instance_map[10:15, 10:15] = 1002
    # painting another light's pixels without overwrite leaves them alone
    cmd = paint(ann, rect_mask(ann.shape, 0, 0, 20, 20), 3001)
    cmd.redo(ann)
    assert (ann.instance_map[0:5, 0:5] == 1001).all() and (ann.instance_map == 3001).sum() == 400 - 50
    cmd.undo(ann)
    cmd, g = group_lights(ann, [1001, 1002], 13)
    cmd.redo(ann)
    # erasing every pixel of a grouped light keeps the light and the group valid
    erase(ann, ann.instance_map == 1001).redo(ann)
    assert 1001 in ann.instance_ids()
    ann.validate()
    # deleting both lights removes them from the group and the emptied group
    delete_instance(ann, 1001).redo(ann)
    assert ann.groups[g].members == (1002,)
    delete_instance(ann, 1002).redo(ann)
    assert ann.groups == {} and ann.instance_ids() == []
    with pytest.raises(NpsimInputError):
        group_lights(ann, [5005], 13)  # not an existing light
    with pytest.raises(NpsimInputError):
        new_instance(ann, 14)  # group class is not a light class


def test_regrouping_moves_light_and_change_class_reencodes():
    ann = sample_annotation()
    cmd, g = group_lights(ann, [1002, 5001], 14)
    cmd.redo(ann)
    assert ann.groups[13001].members == (1001,) and ann.groups[g].members == (1002, 5001)
    cmd, nid = change_class(ann, 1001, 7)
    cmd.redo(ann)
    assert nid == 7001 and ann.groups[13001].members == (7001,)
    assert (ann.instance_map == 7001).sum() == 24 and not (ann.instance_map == 1001).any()
    ann.validate()


def test_pixel_diff_stays_small_on_large_images():
    ann = LightAnnotation.empty(1024, 2048)
    cmd = paint(ann, rect_mask(ann.shape, 100, 100, 110, 110), 1001)
    assert cmd.diff.nbytes == 100 * 12  # index + old + new, int32 each
    assert cmd.redo(ann).rect == (100, 100, 110, 110)


def test_snap_to_superpixels():
    ann = LightAnnotation.empty(8, 8)
    labels = np.zeros((8, 8), np.int32)
    labels[:, 4:] = 1
    ann.instance_map[0:5, 0:4] = 1001  # 20 of 32 px of superpixel 0
    ann.instance_map[0, 4] = 1001  # 1 of 32 px of superpixel 1
    snap_to_superpixels(ann, 1001, labels).redo(ann)
    np.testing.assert_array_equal(ann.instance_map == 1001, labels == 0)


def test_split_paint_reading_order_and_min_area():
    ann = LightAnnotation.empty(10, 30)
    m = rect_mask(ann.shape, 20, 1, 23, 4) | rect_mask(ann.shape, 2, 1, 5, 4) | rect_mask(ann.shape, 10, 8, 11, 9)
    cmd, ids = split_paint(ann, m, 1, min_area=2)
    cmd.redo(ann)
    assert ids == [1001, 1002]
    assert (ann.instance_map[1:4, 2:5] == 1001).all() and (ann.instance_map[1:4, 20:23] == 1002).all()
    assert ann.instance_map[8, 10] == 0


# --------------------------------------------------------------------------- formats
@pytest.mark.parametrize("compressed", [False, True])
def test_rle_matches_coco_convention(compressed):
    m = np.array([[0, 1, 1], [0, 0, 1]], bool)
    # column-major: (0,0) | (1,0) | (1,1) -> runs of 2 zeros, 1 one, 1 zero, 2 ones
    assert rle_encode(m) == [2, 1, 1, 2]
    assert rle_encode(np.ones((2, 2), bool)) == [0, 4]
    rng = np.random.default_rng(1)
    for _ in range(20):
        mask = rng.random((int(rng.integers(1, 40)), int(rng.integers(1, 40)))) > rng.random()
        c = rle_encode(mask)
        if compressed:
            c = rle_to_string(c)
            assert isinstance(c, str)
        np.testing.assert_array_equal(rle_decode(c, *mask.shape), mask)


def test_rle_string_known_value():
    # pycocotools.mask.encode of a 4x4 mask with a 2x2 block at rows 1-2, cols 1-2
    m = np.zeros((4, 4), bool)
    m[1:3, 1:3] = True
    assert rle_encode(m) == [5, 2, 2, 2, 5]
    assert rle_to_string([5, 2, 2, 2, 5]) == "52203"


def test_save_load_roundtrip_all_formats(tmp_path):
    ann = sample_annotation()
    img = np.full((40, 64, 3), 7, np.uint8)
    paths = save_annotation(ann, tmp_path, "s", image=img)
    assert set(paths) == {"instance_png", "class_png", "json", "coco_json"}
    back = load_annotation(tmp_path, "s")
    assert_same(ann, back)
    assert back.meta["done"] is True and A.check_image(back, img) and not A.check_image(back, img + 1)
    doc = json.loads(paths["json"].read_text())
    assert doc["version"] == A.FORMAT_VERSION and doc["image_sha256"] == A.image_checksum(img)
    assert {i["id"]: i["group"] for i in doc["instances"]}[1001] == 13001
    assert doc["groups"][0]["bbox"] == [3, 2, 17, 5]
    assert_same(ann, load_coco(paths["coco_json"]))
    assert_same(ann, from_coco(to_coco(ann, compressed=False)))
    cls = A.read_image(paths["class_png"], color=False)
    assert cls.dtype == np.uint8 and cls[3, 4] == 1 and cls[22, 41] == 5


def test_newer_and_corrupt_files_are_refused_untouched(tmp_path):
    ann = sample_annotation()
    paths = save_annotation(ann, tmp_path, "s")
    doc = json.loads(paths["json"].read_text())
    doc["version"] = A.FORMAT_VERSION + 1
    paths["json"].write_text(json.dumps(doc))
    before = paths["json"].read_bytes()
    with pytest.raises(NpsimInputError, match="newer"):
        load_annotation(tmp_path, "s")
    assert paths["json"].read_bytes() == before
    save_annotation(ann, tmp_path, "s")
    paths["json"].write_text(paths["json"].read_text()[:50])  # truncated
    with pytest.raises(NpsimInputError, match="JSON"):
        load_annotation(tmp_path, "s")
    save_annotation(ann, tmp_path, "s")
    other = ann.copy()
    other.instance_map[0, 0] = 1001
    write_image(paths["instance_png"], other.instance_map.astype(np.uint16))  # PNG from another save
    with pytest.raises(NpsimInputError, match="checksum"):
        load_annotation(tmp_path, "s")
    paths["instance_png"].write_bytes(b"not a png")
    with pytest.raises(NpsimInputError):
        load_annotation(tmp_path, "s")


def test_failed_save_leaves_previous_files_intact(tmp_path, monkeypatch):
    ann = sample_annotation()
    paths = save_annotation(ann, tmp_path, "s")
    old = {k: p.read_bytes() for k, p in paths.items()}
    ann2 = ann.copy()
    ann2.instance_map[10:12, 10:12] = 1001
    calls = []
    real = A._write_bytes

    def failing(path, data):
        real(path, data)  # the temp file is fully written...
        calls.append(path)
        if len(calls) == 3:
            raise OSError("disk full")  # ...then the third file fails

    monkeypatch.setattr(A, "_write_bytes", failing)
    with pytest.raises(OSError):
        save_annotation(ann2, tmp_path, "s")
    assert {k: p.read_bytes() for k, p in paths.items()} == old
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths.values())  # no temp left
    assert_same(load_annotation(tmp_path, "s"), ann)


def test_recovery_file(tmp_path):
    ann = sample_annotation()
    assert find_recovery(tmp_path, "s") is None
    write_recovery(ann, tmp_path, "s")
    assert find_recovery(tmp_path, "s") == autosave_path(tmp_path, "s")
    assert_same(load_recovery(autosave_path(tmp_path, "s")), ann)
    autosave_path(tmp_path, "s").write_bytes(b"garbage")
    with pytest.raises(NpsimInputError, match="recovery"):
        load_recovery(autosave_path(tmp_path, "s"))
    A.discard_recovery(tmp_path, "s")
    assert find_recovery(tmp_path, "s") is None


def test_discover_items(tmp_path):
    img = np.zeros((4, 6, 3), np.uint8)
    write_image(tmp_path / "a.png", img)
    write_image(tmp_path / "a_labelIds.png", np.zeros((4, 6), np.uint8))
    write_image(tmp_path / "b_leftImg8bit.png", img)
    write_image(tmp_path / "b_gtFine_labelIds.png", np.zeros((4, 6), np.uint8))
    write_image(tmp_path / "c.jpg", img)
    save_annotation(LightAnnotation.empty(4, 6), tmp_path, "a")
    items = discover_items(tmp_path)
    assert [(i.name, i.labels_path.name if i.labels_path else None) for i in items] == [
        ("a", "a_labelIds.png"), ("b", "b_gtFine_labelIds.png"), ("c", None)]
    assert items[0].has_annotation() and not items[1].has_annotation()
    with pytest.raises(NpsimInputError):
        discover_items(tmp_path / "missing")


def test_discover_items_in_dataset_trees(tmp_path):
    """A Cityscapes or ACDC image keeps its labels in the layout's gt tree: the editor opened on the
    root, a city folder or the image itself finds them (it used to find no labels, or nothing)."""
    img, lab = np.zeros((4, 6, 3), np.uint8), np.full((4, 6), 7, np.uint8)
    cs = tmp_path / "cs"
    write_image(cs / "leftImg8bit/val/town/t_000001_000019_leftImg8bit.png", img)
    write_image(cs / "gtFine/val/town/t_000001_000019_gtFine_labelIds.png", lab)
    write_image(cs / "leftImg8bit/val/town/t_000002_000019_leftImg8bit.png", img)  # no labels: left out
    image = cs / "leftImg8bit/val/town/t_000001_000019_leftImg8bit.png"
    for where in (cs, cs / "leftImg8bit/val/town", image):
        items = discover_items(where)
        assert [(i.stem, i.labels_path) for i in items] == [
            ("t_000001_000019", cs / "gtFine/val/town/t_000001_000019_gtFine_labelIds.png")]
        assert items[0].folder == image.parent  # beside the image, where npsim run looks for it
        assert (items[0].load_labels() == 7).all()
    acdc = tmp_path / "acdc"
    write_image(acdc / "rgb_anon/night/val/GOPR1/GOPR1_frame_000001_rgb_anon.png", img)
    write_image(acdc / "gt/night/val/GOPR1/GOPR1_frame_000001_gt_labelIds.png", lab)
    items = discover_items(acdc)
    assert len(items) == 1 and items[0].labels_path.name == "GOPR1_frame_000001_gt_labelIds.png"


# --------------------------------------------------------------------------- superpixels
def blocks_image(h=64, w=96):
    img = np.zeros((h, w, 3), np.uint8)
    img[:, :] = (90, 90, 100)
    img[8:24, 8:40] = (240, 220, 120)
    img[36:56, 50:90] = (20, 30, 60)
    return img


@pytest.mark.parametrize("method", METHODS)
def test_superpixels_all_methods(method):
    img = blocks_image()
    lab = compute_superpixels(img, method, region_size=8, iterations=4)
    assert lab.shape == img.shape[:2] and lab.dtype == np.int32
    assert lab.min() == 0 and np.unique(lab).size == lab.max() + 1 > 10
    # superpixels follow strong edges: the bright block is covered by labels that stay inside it
    inside = np.unique(lab[10:22, 10:38])
    frac = np.isin(lab, inside)[8:24, 8:40].mean()
    assert frac > 0.9


def test_superpixel_cache_and_pair():
    img = blocks_image()
    p = SuperpixelParams("seeds", region_size=12)
    a = cached_superpixels(img, p)
    assert cached_superpixels(img, p) is a
    coarse, fine = superpixel_pair(img, p)
    assert coarse is a and fine.max() > coarse.max()
    b = boundary_mask(coarse)
    assert b.dtype == bool and 0 < b.mean() < 0.5
    with pytest.raises(NpsimInputError):
        compute_superpixels(img, "watershed")


def test_superpixel_index_and_disk():
    lab = np.arange(12, dtype=np.int32).reshape(3, 4)
    np.testing.assert_array_equal(superpixel_index(lab, [1, 5]), [1, 5])
    idx = disk_index((5, 5), np.array([2]), np.array([2]), 1)
    np.testing.assert_array_equal(np.sort(idx), [7, 11, 12, 13, 17])


def test_similar_superpixels_fixed_and_auto():
    from npsim_core.superpixels import similar_superpixels

    means = np.array([[30, 128, 128], [100, 128, 128], [35, 130, 126], [110, 128, 128], [28, 127, 128]], np.float32)
    np.testing.assert_array_equal(similar_superpixels(means, [1, 2, 3, 4], 0, 10.0), [0, 2, 4])
    # auto: two colour clusters among what was dragged over, the seed's kept
    np.testing.assert_array_equal(similar_superpixels(means, [0, 1, 2, 3, 4], 0), [0, 2, 4])
    np.testing.assert_array_equal(similar_superpixels(means, [0, 1, 2, 3, 4], 3), [1, 3])
    # windows that differ from the wall in different ways (darker, brighter, tinted): the wall is the
    # densest colour, everything else is kept when the drag starts on a window
    wall = [[88, 131, 130], [86, 132, 131], [90, 131, 129], [85, 132, 130]]
    windows = [[75, 128, 122], [108, 128, 119], [58, 127, 120]]
    means = np.array(windows + wall, np.float32)
    np.testing.assert_array_equal(similar_superpixels(means, range(7), 0), [0, 1, 2])
    np.testing.assert_array_equal(similar_superpixels(means, range(7), 4), [3, 4, 5, 6])  # started on the wall


def test_default_region_size_scales_with_width():
    from npsim_core.superpixels import default_region_size

    assert [default_region_size(w) for w in (256, 1024, 2048, 4096)] == [8, 8, 16, 24]
    assert SuperpixelParams.for_image(2048).region_size == 16


def test_cli_annotate_list(tmp_path, capsys):
    from npsim_cli.main import main

    img = np.zeros((4, 6, 3), np.uint8)
    write_image(tmp_path / "a.png", img)
    write_image(tmp_path / "b.png", img)
    ann = LightAnnotation.empty(4, 6)
    ann.meta["done"] = True
    save_annotation(ann, tmp_path, "a")
    assert main(["annotate", str(tmp_path), "--list"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split("\t")[:2] for line in out] == [["a", "done"], ["b", "-"]]
    assert main(["annotate", str(tmp_path / "nothing")]) == 2


def _reference_masks():
    """Masks to check against pycocotools: 1x1, odd and even sizes, all-zero, all-one, sparse, dense, blocks."""
    rng = np.random.default_rng(3)
    yield np.zeros((1, 1), bool)
    yield np.ones((1, 1), bool)
    for h, w in [(1, 7), (7, 1), (2, 2), (3, 5), (5, 3), (17, 31), (64, 48), (33, 129)]:
        yield np.zeros((h, w), bool)
        yield np.ones((h, w), bool)
        for p in (0.02, 0.5, 0.98):
            yield rng.random((h, w)) < p
        m = np.zeros((h, w), bool)
        m[h // 3:h // 3 + max(1, h // 2), w // 4:w // 4 + max(1, w // 3)] = True  # a light-like block
        yield m
        m = np.zeros((h, w), bool)
        m[-1, -1] = True  # last pixel only: no trailing zero run
        yield m
    for _ in range(30):
        h, w = int(rng.integers(1, 40)), int(rng.integers(1, 40))
        yield rng.random((h, w)) > rng.random()


def test_rle_matches_pycocotools():
    from pycocotools import mask as coco_mask

    n = 0
    for mask in _reference_masks():
        h, w = mask.shape
        ref = coco_mask.encode(np.asfortranarray(mask, dtype=np.uint8))
        assert ref["size"] == [h, w]
        counts = rle_encode(mask)
        assert counts == rle_from_indices(np.flatnonzero(mask.ravel(order="F")), h * w)  # the export's path
        assert sum(counts) == h * w and counts[0] >= 0 and all(c > 0 for c in counts[1:])
        assert rle_to_string(counts) == ref["counts"].decode("ascii"), (h, w)
        assert coco_mask.area(ref) == mask.sum()
        for enc in (counts, rle_to_string(counts), ref["counts"]):
            back = rle_decode(enc, h, w)
            assert back.dtype == bool and back.shape == (h, w)
            np.testing.assert_array_equal(back, mask)
        np.testing.assert_array_equal(coco_mask.decode(ref), mask)
        n += 1
    assert n > 60


def test_coco_export_segmentations_match_pycocotools():
    from pycocotools import mask as coco_mask

    ann = sample_annotation()
    doc = to_coco(ann)
    plain = to_coco(ann, compressed=False)
    H, W = ann.shape
    for a, b in zip(doc["annotations"], plain["annotations"]):
        i = a["id"]
        members = ann.groups[i].members if i in ann.groups else (i,)
        mask = np.isin(ann.instance_map, members)
        ref = coco_mask.encode(np.asfortranarray(mask, dtype=np.uint8))
        assert a["segmentation"] == {"size": [H, W], "counts": ref["counts"].decode("ascii")}
        assert b["segmentation"] == {"size": [H, W], "counts": rle_encode(mask)}
        assert a["area"] == int(coco_mask.area(ref))


@pytest.mark.parametrize("counts", [[2, 1, 1, 1], [2, 1, 1, 3], [-1, 7], "52", "5220", "5\x7f", "52203\u00e9",
                                    "522036", "b"])
def test_malformed_rle_is_refused(counts):
    # 4x4 image (16 px): short or long runs, negative runs, truncated numbers, foreign characters
    with pytest.raises(NpsimInputError):
        rle_decode(counts, 4, 4)


def test_undo_stack_clean_marker():
    ann = LightAnnotation.empty(8, 8)
    st = UndoStack(ann)
    assert st.is_clean
    st.push(paint(ann, [1, 2], 1001))
    st.mark_clean()  # saved here
    st.push(paint(ann, [3], 1001))
    assert not st.is_clean
    st.undo()
    assert st.is_clean  # back at the saved state
    st.undo()
    assert not st.is_clean
    st.push(paint(ann, [5], 1001))  # a new branch: the saved state can never come back
    assert not st.is_clean and not st.can_redo
    st.undo()
    assert not st.is_clean
    assert st.push(None).rect is None and len(st) == 0  # no-op commands are not recorded
