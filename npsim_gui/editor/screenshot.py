"""Make the documentation screenshots of the editor (run under Xvfb).

``xvfb-run -a -s "-screen 0 1280x1024x24" .venv/bin/python -m npsim_gui.editor.screenshot docs/img [NAME ...]``
writes ``editor.png`` (the synthetic street scene, 256x128, with its light
annotation, one windows_group selected), ``editor_row.png`` (512x256, a
window row labelled with the recipe from docs/annotation.md) and
``editor_selection.png`` (1024x512, a car's lamps and windows Shift+clicked,
grouped with Ctrl+G and made active with A); NAMEs (``editor``, ``row``,
``selection``) pick some of them.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from PySide6.QtCore import QPointF, Qt
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication

from npsim_core.annotation import discover_items
from npsim_core.scene import save_scene

from .window import EditorWindow


def front_window_row(lights):
    """The windows_group to label in the docs' recipe and the drag through it.

    Picks the row with the most unoccluded front-facing windows -- as large as the
    row's largest (within 15 %) and on the same image rows (within 1 px), which is
    what a facade facing the camera looks like -- and keeps its visible windows (at
    least half that area). Returns (group, member ids left to right, drag points =
    window centres in pixel-centre coordinates).
    """
    st = lights.stats()
    best, best_score = None, -1
    for g in sorted(lights.groups.values(), key=lambda g: g.id):
        boxes = {m: st[m] for m in g.members if st[m]["bbox"]}
        if g.class_id != 13 or not boxes:
            continue
        ref = max(boxes, key=lambda m: boxes[m]["area"])
        top, (ry0, ry1) = boxes[ref]["area"], (boxes[ref]["bbox"][1], boxes[ref]["bbox"][3])
        score = sum(b["area"] >= 0.85 * top and abs(b["bbox"][1] - ry0) <= 1 and abs(b["bbox"][3] - ry1) <= 1
                    for b in boxes.values()) if top >= 20 else 0
        if score > best_score:
            best, best_score = g, score
    top = max(st[m]["area"] for m in best.members)
    members = sorted((m for m in best.members if st[m]["area"] >= 0.5 * top), key=lambda m: st[m]["bbox"][0])
    centres = [((st[m]["bbox"][0] + st[m]["bbox"][2]) // 2 + 0.5, (st[m]["bbox"][1] + st[m]["bbox"][3]) // 2 + 0.5)
               for m in members]
    return best, members, centres


def _settle(app: QApplication, win: EditorWindow) -> None:
    win.activateWindow()
    win.editor.canvas.setFocus()
    while not win.editor.session.superpixels_ready or QApplication.focusWidget() is not win.editor.canvas:
        app.processEvents()
        QTest.qWait(20)
    win.editor.refresh_now()
    app.processEvents()


def _open(folder: Path) -> EditorWindow:
    win = EditorWindow(autosave_ms=10**9)
    win.answers = {"discard": "Discard", "restore": "Discard"}
    win.set_items(discover_items(folder))
    win.show()
    return win


def selection_shot(app: QApplication, tmp: Path, path: Path) -> EditorWindow:
    """The car at the left kerb of the 1024x512 street, ungrouped, then rebuilt through the GUI: Select
    tool, click one light, Shift+click the others, Ctrl+G (car_group preselected), A (active)."""
    from npsim_core.synthetic import street_scene

    scene = street_scene(1024, 512)
    car = min((g for g in scene.lights.groups.values() if g.class_id == 14), key=lambda g: g.id)
    save_scene(scene, tmp / "street_sel")
    win = _open(tmp / "street_sel")
    _settle(app, win)
    ed, s, c = win.editor, win.editor.session, win.editor.canvas
    s.set_selection({car.id})
    ed.ungroup_selected()
    QTest.keyClick(c, Qt.Key.Key_Escape)
    st = s.ann.stats()
    boxes = [st[m]["bbox"] for m in car.members]
    x0, y0 = min(b[0] for b in boxes), min(b[1] for b in boxes)
    x1, y1 = max(b[2] for b in boxes), max(b[3] for b in boxes)
    c.set_zoom(c.viewport().width() / (x1 - x0 + 120))
    c.centerOn(QPointF((x0 + x1 + 1) / 2, (y0 + y1 + 1) / 2))
    _settle(app, win)
    QTest.keyClick(c, Qt.Key.Key_V)
    for k, m in enumerate(car.members):
        ys, xs = (s.ann.instance_map == m).nonzero()
        j = len(xs) // 2
        mods = Qt.KeyboardModifier.ShiftModifier if k else Qt.KeyboardModifier.NoModifier
        QTest.mouseClick(c.viewport(), Qt.MouseButton.LeftButton, mods, c.view_point(xs[j] + 0.5, ys[j] + 0.5))
    assert s.selection == set(car.members), (s.selection, car.members)
    QTest.keyClick(c, Qt.Key.Key_G, Qt.KeyboardModifier.ControlModifier)
    QTest.keyClick(c, Qt.Key.Key_A)
    assert s.active_group is not None and s.ann.groups[s.active_group].members == car.members
    _settle(app, win)
    win.grab().save(str(path))
    return win


def main(out_dir: str = "docs/img", *names: str) -> None:
    from npsim_core.synthetic import street_scene

    app = QApplication.instance() or QApplication(sys.argv[:1])
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = set(names) or {"editor", "row", "selection"}
    with tempfile.TemporaryDirectory() as tmp:
        if "selection" in names:
            selection_shot(app, Path(tmp), out / "editor_selection.png").close()
        if "editor" in names:
            scene = street_scene(256, 128)
            save_scene(scene, Path(tmp) / "street")
            win = _open(Path(tmp) / "street")
            _settle(app, win)
            s = win.editor.session
            # Highlight the row the recipe labels (picked at 512x256, where it is visible best).
            gid = front_window_row(street_scene(512, 256).lights)[0].id
            g = s.ann.groups.get(gid) or front_window_row(s.ann)[0]
            s.set_selection({g.id, *g.members}, current=g.members[0])
            _settle(app, win)
            win.grab().save(str(out / "editor.png"))
            win.answers = {"discard": "Discard"}
            win.close()
        if "row" in names:
            row_shot(app, Path(tmp), out / "editor_row.png").close()


def row_shot(app: QApplication, tmp: Path, path: Path) -> EditorWindow:
    """The window-row recipe at 512x256: 1, R, T, one drag, Ctrl+G."""
    from npsim_core.synthetic import street_scene

    big = street_scene(512, 256)
    _, _, centres = front_window_row(big.lights)
    save_scene(big.with_(lights=None), tmp / "street512")
    win = _open(tmp / "street512")
    _settle(app, win)
    c = win.editor.canvas
    for k in (Qt.Key.Key_1, Qt.Key.Key_R, Qt.Key.Key_T):
        QTest.keyClick(c, k)
    assert win.editor.options.split_regions and win.editor.options.similar_only
    vps = [c.view_point(x, y) for x, y in centres]
    QTest.mousePress(c.viewport(), Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, vps[0])
    for p in vps[1:]:
        QTest.mouseMove(c.viewport(), p)
    QTest.mouseRelease(c.viewport(), Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, vps[-1])
    QTest.keyClick(c, Qt.Key.Key_G, Qt.KeyboardModifier.ControlModifier)
    _settle(app, win)
    # Zoom onto the row so the result is visible.
    x0 = min(cx for cx, _ in centres) - 40
    x1 = max(cx for cx, _ in centres) + 40
    y = sum(cy for _, cy in centres) / len(centres)
    c.set_zoom(c.viewport().width() / (x1 - x0))
    c.centerOn(QPointF((x0 + x1) / 2, y))
    _settle(app, win)
    win.grab().save(str(path))
    return win


if __name__ == "__main__":
    main(*sys.argv[1:])
