"""Light annotation: superpixel speed against segmentation error, edit and file costs.

    .venv/bin/python benchmarks/annotation.py [--size 2048x1024] [--repeat 1]

Table 1 (superpixels on the synthetic street scene): time per method and
region size, number of superpixels, and two standard errors against the
scene's ground truth -- ASA (achievable segmentation accuracy: the fraction of
pixels labelled right when every superpixel takes its majority class; higher
is better) for the semantic labels and for the light masks, and the
fraction of light-instance boundary pixels within 1 px of a superpixel border
(boundary recall).

Table 2 (editing at that size): undoable edits (pixel diffs), the overlay
update a view does after a stroke, and the atomic save / checked load.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np


def asa(sp: np.ndarray, gt: np.ndarray) -> float:
    """Achievable segmentation accuracy of superpixels ``sp`` for the label map ``gt``."""
    n = int(sp.max()) + 1
    _, g = np.unique(gt, return_inverse=True)
    k = int(g.max()) + 1
    joint = np.bincount(sp.ravel().astype(np.int64) * k + g.ravel(), minlength=n * k).reshape(n, k)
    return float(joint.max(axis=1).sum() / sp.size)


def light_asa(sp: np.ndarray, inst: np.ndarray) -> float:
    """ASA restricted to light pixels: of all light pixels, the share a superpixel labelling can get right."""
    lit = inst != 0
    if not lit.any():
        return float("nan")
    n = int(sp.max()) + 1
    _, g = np.unique(inst, return_inverse=True)
    g = g.reshape(inst.shape)
    k = int(g.max()) + 1
    joint = np.bincount(sp.ravel().astype(np.int64) * k + g.ravel(), minlength=n * k).reshape(n, k)
    zero = int(np.flatnonzero(np.unique(inst) == 0)[0]) if (~lit).any() else -1
    best = joint.argmax(axis=1)
    right = joint[np.arange(n), best]
    right[best == zero] = 0  # superpixels that go to "no light" contribute no light pixels
    return float(right.sum() / lit.sum())


def boundary_recall(sp: np.ndarray, inst: np.ndarray) -> float:
    import cv2

    from npsim_core.superpixels import boundary_mask

    gt_b = boundary_mask(inst) & ((inst != 0) | np.roll(inst != 0, -1, 1) | np.roll(inst != 0, -1, 0))
    sp_b = cv2.dilate(boundary_mask(sp).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    return float((gt_b & sp_b).sum() / max(gt_b.sum(), 1))


def timed(fn, repeat: int):
    best, out = float("inf"), None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--size", default="2048x1024", help="WxH of the synthetic scene")
    ap.add_argument("--repeat", type=int, default=1, help="timed runs per row (best is shown)")
    args = ap.parse_args(argv)
    W, H = (int(x) for x in args.size.lower().split("x"))

    from npsim_core.annotation import load_annotation, save_annotation
    from npsim_core.annotation_ops import UndoStack, change_class, paint, split_paint
    from npsim_core.superpixels import compute_superpixels, default_region_size, disk_index, line_pixels
    from npsim_core.synthetic import street_scene

    scene = street_scene(W, H)
    inst = scene.lights.instance_map
    print(f"synthetic street scene {W}x{H}; load {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)")
    print()
    print("| method | region px | smooth | time s | superpixels | ASA labels | ASA lights | light boundary recall |")
    print("|---|---|---|---|---|---|---|---|")
    base = default_region_size(W)
    for method, size, smooth in [("seeds", base, 3), ("slic", base, 3), ("slic", base, 0), ("slico", base, 3),
                                 ("mslic", base, 3), ("lsc", base, 3), ("slic", base // 2, 3),
                                 ("seeds", base // 2, 3)]:
        t, sp = timed(lambda: compute_superpixels(scene.image, method, size, 10.0, 10, smooth), args.repeat)
        print(f"| {method} | {size} | {smooth} | {t:.2f} | {int(sp.max()) + 1} | {asa(sp, scene.labels):.4f} | "
              f"{light_asa(sp, inst):.3f} | {boundary_recall(sp, inst):.3f} |")
        sys.stdout.flush()

    print()
    print("| edit at full size | time ms | undo ms | diff memory |")
    print("|---|---|---|---|")
    ann = scene.lights.copy()
    stack = UndoStack(ann)
    xs, ys = line_pixels(W * 0.2, H * 0.6, W * 0.8, H * 0.65)
    rows = []

    def brush():
        idx = disk_index(ann.shape, xs, ys, max(2, W // 256))
        return paint(ann, idx, 12999, overwrite=False)

    rows.append(("brush stroke across the image", brush))
    box = np.zeros(ann.shape, bool)
    box[H // 2:H // 2 + H // 8, W // 4:W // 4 + W // 8] = True
    rows.append((f"paint a {W // 8}x{H // 8} box", lambda: paint(ann, box, 12998)))
    big = max(ann.instance_ids(), key=lambda i: int((ann.instance_map == i).sum()))
    rows.append((f"change class of the largest light ({int((ann.instance_map == big).sum())} px)",
                 lambda: change_class(ann, big, 12)[0]))
    rows.append(("split a box into regions", lambda: split_paint(ann, box | np.roll(box, W // 4, 1), 12)[0]))
    for name, make in rows:
        t0 = time.perf_counter()
        cmd = make()
        stack.push(cmd)
        t_do = time.perf_counter() - t0
        t1 = time.perf_counter()
        stack.undo()
        t_undo = time.perf_counter() - t1
        stack.redo()
        mem = cmd.diff.nbytes if getattr(cmd, "diff", None) is not None else 0
        print(f"| {name} | {1000 * t_do:.1f} | {1000 * t_undo:.1f} | {mem / 1e6:.2f} MB |")

    try:
        from npsim_gui.editor.overlays import lights_region
    except ImportError:  # pragma: no cover - GUI extras missing
        lights_region = None
    if lights_region is not None:
        rgba = np.zeros((H, W, 4), np.uint8)
        t, _ = timed(lambda: lights_region(ann.instance_map, rgba, None, {big}), 3)
        print(f"| overlay: whole light layer (on load) | {1000 * t:.1f} | - | - |")
        r = (W // 2 - 40, H // 2 - 40, W // 2 + 40, H // 2 + 40)
        t, _ = timed(lambda: lights_region(ann.instance_map, rgba, r, {big}), 10)
        print(f"| overlay: 80x80 stroke region | {1000 * t:.2f} | - | - |")
    with tempfile.TemporaryDirectory() as tmp:
        ann.validate()
        t, _ = timed(lambda: save_annotation(ann, tmp, "bench", image=scene.image), args.repeat)
        print(f"| save (instance+class PNG, JSON, COCO RLE; atomic) | {1000 * t:.0f} | - | - |")
        t, _ = timed(lambda: load_annotation(tmp, "bench"), args.repeat)
        print(f"| load (checked) | {1000 * t:.0f} | - | - |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
