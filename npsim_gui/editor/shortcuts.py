"""The editor's keyboard shortcuts: one table used by the actions, the F1 sheet and the docs."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QDialog, QDialogButtonBox, QTableWidget, QTableWidgetItem, QVBoxLayout

#: Light class shortcuts: 1-9 and 0 for classes 1-10, Ctrl+1 / Ctrl+2 for 11 and 12.
LIGHT_CLASS_KEYS = {**{c: str(c) for c in range(1, 10)}, 10: "0", 11: "Ctrl+1", 12: "Ctrl+2"}
#: Group class shortcuts: Alt+1..Alt+9 for classes 13-21.
GROUP_CLASS_KEYS = {13 + k: f"Alt+{k + 1}" for k in range(9)}

#: Proposal layer shortcuts (keys no other editor action uses).
PROPOSAL_KEYS = {"propose": "Ctrl+P", "accept": "Shift+A", "reject": "Shift+R", "accept_above": "Ctrl+Shift+A"}

#: (keys, what) in the order the sheet shows them.
SHORTCUTS: list[tuple[str, str]] = [
    ("S", "Superpixel tool: click/drag adds superpixels to the current light; Shift removes; Alt = fine scale"),
    ("B", "Brush tool (pixel); Shift+drag erases"),
    ("E", "Eraser tool (pixel, any light)"),
    ("F", "Fill-to-superpixel: click a light to snap it to the superpixels it mostly covers"),
    ("V", "Select tool: click selects a light, Shift/Ctrl+click adds/removes, drag a box selects every light "
          "it touches (Shift/Ctrl+drag adds)"),
    ("G", "Group tool: clicks add/remove lights to/from the selection, a box adds"),
    ("R", "Toggle 'one new light per region' for superpixel drags"),
    ("T", "Toggle 'similar colour only' for superpixel drags"),
    ("D", "Toggle the fine superpixel scale (Alt+click/drag uses the other scale)"),
    ("[ / ]", "Brush smaller / larger"),
    ("1-9, 0", "Light classes 1-10 (window_building ... advertisement); each preselects its default group "
               "class"),
    ("Ctrl+1, Ctrl+2", "Light classes 11 clock, 12 inferred"),
    ("Alt+1 ... Alt+9", "Group classes 13 windows_group ... 21 traffic_sign_group"),
    ("N", "New light of the current class (the next stroke paints into it)"),
    ("C", "Change the selected lights to the current class"),
    ("Ctrl+G", "Group the selection (lights and selected groups' lights) as one group; with one group "
               "selected, the other selected lights join it"),
    ("A", "Make the selected group (or the group of the selected light) active: new lights join it; A again "
          "or Esc ends"),
    ("Ctrl+Shift+G", "Ungroup the selected groups / the groups of the selected lights"),
    ("Delete", "Delete the selected lights or groups"),
    ("Esc", "Clear the selection, the current light and the active group"),
    ("Ctrl+F", "Filter the class buttons by name (Return picks the only match, Esc clears)"),
    ("Ctrl+P", "Propose lights automatically (shown as a dashed, translucent layer apart from the annotation)"),
    ("Shift+A", "Accept the proposals selected in the Proposals list, else the proposal under the mouse with "
                "its whole group: they become ordinary lights and groups (Ctrl+Z undoes)"),
    ("Shift+R", "Reject the selected proposals, else the proposal under the mouse with its whole group"),
    ("Ctrl+Shift+A", "Accept every pending proposal at or above the confidence slider"),
    ("Ctrl+Z", "Undo"),
    ("Ctrl+Shift+Z, Ctrl+Y", "Redo"),
    ("L / P / M", "Show/hide semantic labels / superpixel borders / light masks"),
    ("Wheel", "Zoom under the mouse"),
    ("Space+drag, middle drag", "Pan"),
    ("Home", "Fit the image in the view"),
    ("Right click", "Make the light under the mouse the current one"),
    ("Ctrl+S", "Save (instance PNG, class PNG, JSON, COCO JSON)"),
    ("Ctrl+D", "Toggle the 'done' flag of this image"),
    ("Page Down / Page Up", "Next / previous image (saves this one first)"),
    ("F1", "This sheet"),
]


class ShortcutDialog(QDialog):
    """A table of every shortcut (Help > Shortcuts, F1)."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setWindowTitle("Annotation editor shortcuts")
        table = QTableWidget(len(SHORTCUTS), 2, self)
        table.setHorizontalHeaderLabels(["Keys", "Action"])
        for r, (k, what) in enumerate(SHORTCUTS):
            table.setItem(r, 0, QTableWidgetItem(k))
            table.setItem(r, 1, QTableWidgetItem(what))
        table.verticalHeader().setVisible(False)
        table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        table.resizeColumnsToContents()
        table.horizontalHeader().setStretchLastSection(True)
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close, Qt.Orientation.Horizontal, self)
        buttons.rejected.connect(self.reject)
        lay = QVBoxLayout(self)
        lay.addWidget(table)
        lay.addWidget(buttons)
        self.table = table
        self.resize(720, 640)
