"""``EditorWindow``: the annotation editor as an application window.

Adds menus, saving, autosave to a recovery file (debounced after edits and on
close), crash recovery on open, the unsaved marker ``*`` in the title, a
confirmation before discarding edits, and stepping through a folder of images
with per-image done flags (saved in each annotation's JSON ``meta.done``).

Dialogs go through :meth:`EditorWindow.ask` so tests (and scripts) can answer
them without a person: set ``window.answers`` to a dict ``{question_key: answer}``.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QTimer
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QFileDialog, QLabel, QMainWindow, QMessageBox

from npsim_core.annotation import (AnnotationItem, annotation_paths, discover_items, find_recovery, load_annotation,
                                   load_recovery)
from npsim_core.chain.session import frame_annotation_files
from npsim_core.errors import NpsimInputError

from .editor import AnnotationEditor
from .shortcuts import keys as keymap_keys


class EditorWindow(QMainWindow):
    """Main window around an :class:`AnnotationEditor` for a list of images."""

    def __init__(self, items: list[AnnotationItem] | None = None, *, autosave_ms: int = 2000, parent=None) -> None:
        super().__init__(parent)
        self.editor = AnnotationEditor(self)
        self.setCentralWidget(self.editor)
        self.items: list[AnnotationItem] = []
        self.index = -1
        self.answers: dict[str, str] | None = None
        self.autosave_timer = QTimer(self)
        self.autosave_timer.setSingleShot(True)
        self.autosave_timer.setInterval(autosave_ms)
        self.autosave_timer.timeout.connect(self.autosave)
        self.editor.session.changed.connect(lambda _ch: self._edited())
        self.editor.dirtyChanged.connect(lambda _d: self._update_title())
        self.progress = QLabel("")
        self.statusBar().addPermanentWidget(self.progress)
        self._build_menus()
        self.resize(1280, 980)
        if items:
            self.set_items(items)

    # ----------------------------------------------------------------- menus
    def _menu_action(self, menu, text, action, slot) -> QAction:
        """A window action with the keys of ``action`` in the keymap (shortcuts.py)."""
        a = QAction(text, self)
        if action:
            a.setShortcuts(keymap_keys(action, "annotate"))
        a.triggered.connect(slot)
        menu.addAction(a)
        return a

    def _build_menus(self) -> None:
        mb = self.menuBar()
        f = mb.addMenu("&File")
        self._menu_action(f, "Open folder…", "open_folder", self.open_folder_dialog)
        self.save_action = self._menu_action(f, "Save", "save_annotation", self.save)
        self._menu_action(f, "Next image", "next_frame", self.next_image)
        self._menu_action(f, "Previous image", "previous_frame", self.previous_image)
        self.done_action = self._menu_action(f, "Done", "done", self.toggle_done)
        self.done_action.setCheckable(True)
        f.addSeparator()
        self._menu_action(f, "Quit", "quit", self.close)
        e = mb.addMenu("&Edit")
        for name in ("undo", "redo", "new", "class", "group", "ungroup", "activate", "delete", "delete_hovered",
                     "escape", "filter"):
            e.addAction(self.editor.actions_by_name[name])
        t = mb.addMenu("&Tools")
        for name, a in self.editor.actions_by_name.items():
            if name.startswith("tool_") or name in ("split", "similar", "smaller", "larger"):
                t.addAction(a)
        v = mb.addMenu("&View")
        for name in ("layer_labels", "layer_superpixels", "layer_lights"):
            v.addAction(self.editor.actions_by_name[name])
        h = mb.addMenu("&Help")
        h.addAction(self.editor.actions_by_name["help"])

    # ----------------------------------------------------------------- dialogs
    def ask(self, key: str, title: str, text: str, buttons: list[str], default: str) -> str:
        """Ask the user; ``self.answers[key]`` answers instead when set (tests)."""
        if self.answers is not None:
            return self.answers.get(key, default)
        box = QMessageBox(self)
        box.setWindowTitle(title)
        box.setText(text)
        btns = {b: box.addButton(b, QMessageBox.ButtonRole.AcceptRole) for b in buttons}
        box.setDefaultButton(btns[default])
        box.exec()
        for b, w in btns.items():
            if box.clickedButton() is w:
                return b
        return default

    # ----------------------------------------------------------------- items
    @property
    def item(self) -> AnnotationItem | None:
        return self.items[self.index] if 0 <= self.index < len(self.items) else None

    def set_items(self, items: list[AnnotationItem], index: int = 0) -> None:
        self.items = list(items)
        self.index = -1
        if self.items:
            self.open_index(index)

    def open_folder_dialog(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Open a scene folder or a folder of images")
        if path:
            self.open_path(path)

    def open_path(self, path: str | Path) -> None:
        if not self.maybe_save("open another folder"):
            return
        try:
            self.set_items(discover_items(path))
        except NpsimInputError as exc:
            QMessageBox.warning(self, "Cannot open", str(exc))

    def open_index(self, index: int) -> bool:
        """Load item ``index`` (its saved annotation, or a recovery file when the user restores it)."""
        if not (0 <= index < len(self.items)):
            return False
        it = self.items[index]
        image = it.load_image()
        labels = it.load_labels()
        ann = None
        readonly = None
        dirty = False
        folder, stem = it.folder, it.stem
        if Path(it.image_path).parent == Path(it.folder):  # an image (not a scene folder): where the CLI reads
            folder, stem = frame_annotation_files(it.image_path)  # beside it, or a read-only dataset's folder
        rec = find_recovery(folder, stem)
        if rec is not None:
            choice = self.ask("restore", "Recover unsaved edits",
                              f"{it.name}: the last session ended without saving. Restore its unsaved edits?",
                              ["Restore", "Discard"], "Restore")
            if choice == "Restore":
                try:
                    ann = load_recovery(rec)
                    dirty = True
                except NpsimInputError as exc:
                    self.statusBar().showMessage(str(exc))
            else:
                rec.unlink(missing_ok=True)
        if ann is None and annotation_paths(folder, stem)["json"].exists():
            try:
                ann = load_annotation(folder, stem)
            except NpsimInputError as exc:
                # Never overwrite a file we could not read: edit a blank annotation read-only.
                readonly = str(exc)
                QMessageBox.warning(self, "Cannot open annotation", str(exc)) if self.answers is None else None
        if ann is not None and ann.shape != image.shape[:2]:
            readonly = f"annotation size {ann.shape} differs from the image {image.shape[:2]}"
            ann = None
        try:
            instances = it.load_instances(image.shape[:2])
        except NpsimInputError as exc:  # the annotation works without them: say why a car is not grouped
            instances = None
            self.statusBar().showMessage(f"{exc}; vehicle lights are not grouped as drawn")
        self.index = index
        self.editor.load(image, labels, ann, folder, stem, dirty=dirty, instances=instances)
        self.editor.session.readonly_reason = readonly
        if readonly:
            self.statusBar().showMessage(f"read-only: {readonly}")
        self._update_title()
        return True

    def step(self, delta: int) -> bool:
        """Save (when edited) and move ``delta`` images on."""
        j = self.index + delta
        if not (0 <= j < len(self.items)):
            return False
        s = self.editor.session
        if s.is_dirty and not s.readonly_reason:
            if not self.save():
                return False  # stay: the edits are not on disk (the recovery file still is)
        elif s.is_dirty and not self.maybe_save("leave this image"):
            return False
        return self.open_index(j)

    def next_image(self) -> bool:
        return self.step(1)

    def previous_image(self) -> bool:
        return self.step(-1)

    # ----------------------------------------------------------------- saving
    def save(self) -> bool:
        """Save the current image's annotation; False (and a message) when it could not be written."""
        s = self.editor.session
        if s.readonly_reason:
            QMessageBox.warning(self, "Not saved", f"Not saving: {s.readonly_reason}") if self.answers is None \
                else None
            return False
        try:
            paths = s.save()
        except (OSError, NpsimInputError) as exc:
            self.autosave()  # keep the edits in the recovery file at least
            self.statusBar().showMessage(f"save failed, previous files kept: {exc}")
            if self.answers is None:
                QMessageBox.critical(self, "Save failed", f"{exc}\n\nThe previous files are unchanged.")
            return False
        self.autosave_timer.stop()
        self.statusBar().showMessage(f"saved {paths['json']}")
        self._update_title()
        return True

    def autosave(self) -> None:
        if self.editor.session.readonly_reason:
            return  # the recovery file would shadow a file we could not read
        try:
            p = self.editor.session.autosave()
            if p is not None:
                self.statusBar().showMessage(f"autosaved to {p.name}", 3000)
        except OSError as exc:
            self.statusBar().showMessage(f"autosave failed: {exc}")

    def _edited(self) -> None:
        if self.editor.session.is_dirty:
            self.autosave_timer.start()
        self._update_title()

    def toggle_done(self) -> None:
        s = self.editor.session
        s.set_done(not bool(s.ann.meta.get("done", False)))
        self._update_title()

    def maybe_save(self, why: str) -> bool:
        """Before discarding edits: Save / Discard / Cancel. True = go ahead."""
        s = self.editor.session
        if not s.is_dirty:
            return True
        self.autosave()  # nothing is lost even if the dialog is answered wrongly or the app dies now
        if s.readonly_reason:
            choice = self.ask("discard", "Unsaved changes",
                              f"This annotation is read-only ({s.readonly_reason}). Discard your changes and "
                              f"{why}?", ["Discard", "Cancel"], "Cancel")
        else:
            choice = self.ask("discard", "Unsaved changes", f"Save your changes before you {why}?",
                              ["Save", "Discard", "Cancel"], "Save")
        if choice == "Save":
            return self.save()
        if choice == "Discard":
            s.discard_recovery()
            return True
        return False

    def closeEvent(self, event) -> None:  # noqa: N802
        if self.maybe_save("close"):
            self.autosave_timer.stop()
            self.editor.shutdown()  # a superpixel job still running stops quietly
            event.accept()
        else:
            event.ignore()

    def _update_title(self) -> None:
        s = self.editor.session
        it = self.item
        name = it.name if it else s.stem
        pos = f" [{self.index + 1}/{len(self.items)}]" if self.items else ""
        done = " ✓" if s.ann.meta.get("done") else ""
        done += " (read-only)" if s.readonly_reason else ""
        star = "*" if s.is_dirty else ""
        self.setWindowTitle(f"{star}{name}{pos}{done} — NPSim light annotation")
        self.done_action.setChecked(bool(s.ann.meta.get("done")))
        if self.items:
            n_done = sum(1 for k, i in enumerate(self.items)
                         if (s.ann.meta.get("done") if k == self.index else i.is_done()))
            self.progress.setText(f"{n_done}/{len(self.items)} done")


def main(path: str | Path, *, autosave_ms: int = 2000) -> int:
    """Run the editor on a scene folder, a folder of images or one image."""
    import sys

    from PySide6.QtWidgets import QApplication

    items = discover_items(path)
    app = QApplication.instance() or QApplication(sys.argv[:1])
    win = EditorWindow(items, autosave_ms=autosave_ms)
    win.show()
    return int(app.exec())
