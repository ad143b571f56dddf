"""Class palette (21 light/group classes by category) and the instance list."""

from __future__ import annotations

from PySide6.QtCore import QEvent, Qt, Signal
from PySide6.QtGui import QColor, QIcon, QPixmap
from PySide6.QtWidgets import (QAbstractItemView, QButtonGroup, QGridLayout, QLabel, QLineEdit, QSizePolicy,
                               QToolButton, QTreeWidget, QTreeWidgetItem, QVBoxLayout, QWidget)

from npsim_core.annotation import LightAnnotation, class_of, is_group_class
from npsim_core.labels import light_class, light_classes

from .shortcuts import GROUP_CLASS_KEYS, LIGHT_CLASS_KEYS


def swatch(color, size: int = 12) -> QIcon:
    pm = QPixmap(size, size)
    pm.fill(QColor(*color))
    return QIcon(pm)


class _FilterEdit(QLineEdit):
    """The class filter: Esc clears it (instead of the editor's Esc), Return picks the only match."""

    done = Signal()

    def event(self, ev) -> bool:
        if ev.type() == QEvent.Type.ShortcutOverride and ev.key() in (Qt.Key.Key_Escape, Qt.Key.Key_Return,
                                                                       Qt.Key.Key_Enter):
            ev.accept()  # handled in keyPressEvent, not by the editor's shortcuts
            return True
        return super().event(ev)

    def keyPressEvent(self, ev) -> None:  # noqa: N802
        if ev.key() == Qt.Key.Key_Escape:
            self.clear()
            self.done.emit()
            return
        super().keyPressEvent(ev)


class ClassPalette(QWidget):
    """A filter box, then buttons for the 12 light classes (by category) and the 9 group classes.

    ``lightClassChosen`` / ``groupClassChosen`` fire on clicks (and on Return in the
    filter box when one class is left); :meth:`set_current` reflects the session
    without emitting. ``filterDone`` asks the editor to give the keyboard back to the canvas.
    """

    lightClassChosen = Signal(int)
    groupClassChosen = Signal(int)
    filterDone = Signal()

    CATEGORY_TITLES = {"building": "Building", "vehicle": "Vehicle", "object": "Object", "group": "Groups"}

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.setSpacing(1)
        self.setStyleSheet("QToolButton { padding: 1px 3px; } QToolButton:checked { font-weight: bold; }")
        self.filter_edit = _FilterEdit()
        self.filter_edit.setPlaceholderText("filter classes… (Ctrl+F)")
        self.filter_edit.setClearButtonEnabled(True)
        self.filter_edit.setToolTip("type part of a class name; Return picks the only match, Esc clears")
        self.filter_edit.textChanged.connect(self.set_filter)
        self.filter_edit.returnPressed.connect(self._pick_single)
        self.filter_edit.done.connect(self.filterDone)
        lay.addWidget(self.filter_edit)
        self.light_buttons = QButtonGroup(self)
        self.group_buttons = QButtonGroup(self)
        self.buttons: dict[int, QToolButton] = {}
        self._sections: list[tuple[QLabel, QGridLayout, list[int]]] = []
        self._names = {c.id: c.name for c in light_classes()}
        for cat in ("building", "vehicle", "object", "group"):
            title = QLabel(f"<b>{self.CATEGORY_TITLES[cat]}</b>")
            title.setContentsMargins(0, 2, 0, 0)
            lay.addWidget(title)
            grid = QGridLayout()
            grid.setSpacing(1)
            classes = [c for c in light_classes() if c.category == cat]
            self._sections.append((title, grid, [c.id for c in classes]))
            for k, c in enumerate(classes):
                key = GROUP_CLASS_KEYS.get(c.id) if c.is_group else LIGHT_CLASS_KEYS.get(c.id)
                b = QToolButton(self)
                label = c.name[:-len("_group")] if c.is_group and c.name.endswith("_group") else c.name
                b.setText(f"{key}  {label}")
                b.setAutoRaise(False)
                b.setToolTip(f"{c.name} (class {c.id}) — shortcut {key}")
                b.setIcon(swatch(c.color))
                b.setCheckable(True)
                b.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextBesideIcon)
                b.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Fixed)
                (self.group_buttons if c.is_group else self.light_buttons).addButton(b, c.id)
                self.buttons[c.id] = b
                grid.addWidget(b, k // 2, k % 2)
            lay.addLayout(grid)
        self.light_buttons.idClicked.connect(self.lightClassChosen)
        self.group_buttons.idClicked.connect(self.groupClassChosen)

    def set_current(self, light_class_id: int, group_class_id: int | None) -> None:
        """Check the current light class and group class (None: no group class button checked)."""
        for cid in (light_class_id, group_class_id):
            b = self.buttons.get(cid) if cid is not None else None
            if b is not None and not b.isChecked():
                b.setChecked(True)
        if group_class_id is None and self.group_buttons.checkedButton() is not None:
            self.group_buttons.setExclusive(False)  # an exclusive group cannot be left with none checked
            self.group_buttons.checkedButton().setChecked(False)
            self.group_buttons.setExclusive(True)

    def set_filter(self, text: str) -> None:
        """Show only the classes whose name contains ``text`` (case-insensitive); '' shows all."""
        text = text.strip().lower()
        for title, grid, ids in self._sections:
            shown = [cid for cid in ids if text in self._names[cid].lower()]
            for cid in ids:
                grid.removeWidget(self.buttons[cid])
                self.buttons[cid].setVisible(cid in shown)
            for k, cid in enumerate(shown):  # re-flow the visible buttons, two per row
                grid.addWidget(self.buttons[cid], k // 2, k % 2)
            title.setVisible(bool(shown))

    def visible_classes(self) -> list[int]:
        return [cid for cid, b in self.buttons.items() if not b.isHidden()]

    def _pick_single(self) -> None:
        shown = self.visible_classes()
        if len(shown) == 1:
            cid = shown[0]
            self.buttons[cid].setChecked(True)
            (self.groupClassChosen if is_group_class(cid) else self.lightClassChosen).emit(cid)
            self.filterDone.emit()


class InstanceList(QTreeWidget):
    """Groups (with their member lights as children) and ungrouped lights.

    Columns: instance id, class, area (px), group. Multi-selection; emits
    ``selectionEdited(set_of_ids)`` when the user changes the selection.
    """

    selectionEdited = Signal(object)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setColumnCount(4)
        self.setHeaderLabels(["Instance", "Class", "Area", "Group"])
        self.setSelectionMode(QAbstractItemView.SelectionMode.ExtendedSelection)
        self.setRootIsDecorated(True)
        self.setUniformRowHeights(True)
        self._items: dict[int, QTreeWidgetItem] = {}
        self._updating = False
        self.itemSelectionChanged.connect(self._on_selection)

    def rebuild(self, ann: LightAnnotation, selection: set[int], current: int | None,
                active_group: int | None = None) -> None:
        """Refill from the annotation (cheap: a few hundred rows at most); the active group is bold."""
        self._updating = True
        try:
            self.clear()
            self._items = {}
            areas = ann.areas()
            grouped = {}
            for gid in sorted(ann.groups):
                g = ann.groups[gid]
                gi = QTreeWidgetItem(self, [str(gid), light_class(class_of(gid)).name,
                                            str(sum(areas.get(m, 0) for m in g.members)), f"{len(g.members)} lights"])
                gi.setIcon(0, swatch(light_class(class_of(gid)).color))
                gi.setData(0, Qt.ItemDataRole.UserRole, gid)
                if gid == active_group:
                    gi.setText(3, f"{len(g.members)} lights, active")
                    for c in range(4):
                        f = gi.font(c)
                        f.setBold(True)
                        gi.setFont(c, f)
                self._items[gid] = gi
                for m in g.members:
                    grouped[m] = gi
                gi.setExpanded(True)
            for iid in ann.instance_ids():
                parent = grouped.get(iid)
                cols = [str(iid), light_class(class_of(iid)).name, str(areas.get(iid, 0)),
                        str(parent.data(0, Qt.ItemDataRole.UserRole)) if parent is not None else ""]
                it = QTreeWidgetItem(parent, cols) if parent is not None else QTreeWidgetItem(self, cols)
                it.setIcon(0, swatch(light_class(class_of(iid)).color))
                it.setData(0, Qt.ItemDataRole.UserRole, iid)
                if iid == current:
                    f = it.font(0)
                    f.setBold(True)
                    it.setFont(0, f)
                self._items[iid] = it
            for c in range(4):
                self.resizeColumnToContents(c)
            self._apply_selection(selection)
        finally:
            self._updating = False

    def set_selection(self, selection: set[int]) -> None:
        self._updating = True
        try:
            self._apply_selection(selection)
        finally:
            self._updating = False

    def _apply_selection(self, selection: set[int]) -> None:
        self.clearSelection()
        last = None
        for i in selection:
            it = self._items.get(i)
            if it is not None:
                it.setSelected(True)
                last = it
        if last is not None:
            self.scrollToItem(last)

    def selected_ids(self) -> set[int]:
        return {int(it.data(0, Qt.ItemDataRole.UserRole)) for it in self.selectedItems()}

    def _on_selection(self) -> None:
        if not self._updating:
            self.selectionEdited.emit(self.selected_ids())
