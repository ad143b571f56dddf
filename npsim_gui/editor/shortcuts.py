"""The one keymap of the app and the stand-alone editor: every action's keys, and the F1 sheet made
from it (docs/annotation.md "Shortcuts" is this table).

An entry names an action (the id the windows build their ``QAction`` under), its keys, what it does
and where it exists: ``"both"`` (the annotation editor, in either window, and the File commands both
windows share), ``"app"`` (only the main window, ``npsim gui``) or ``"annotate"`` (only the
stand-alone editor, ``npsim annotate``). Rows without an action id are mouse gestures, listed for
the sheet only.
"""

from __future__ import annotations

from dataclasses import dataclass

from PySide6.QtCore import Qt
from PySide6.QtGui import QKeySequence
from PySide6.QtWidgets import (QDialog, QDialogButtonBox, QHeaderView, QTableWidget, QTableWidgetItem,
                               QVBoxLayout)

#: Light class shortcuts: 1-9 and 0 for classes 1-10, Ctrl+1 / Ctrl+2 for 11 and 12.
LIGHT_CLASS_KEYS = {**{c: str(c) for c in range(1, 10)}, 10: "0", 11: "Ctrl+1", 12: "Ctrl+2"}
#: Group class shortcuts: Alt+1..Alt+9 for classes 13-21.
GROUP_CLASS_KEYS = {13 + k: f"Alt+{k + 1}" for k in range(9)}

#: Proposal layer shortcuts (keys no other editor action uses).
PROPOSAL_KEYS = {"propose": "Ctrl+P", "accept": "Shift+A", "reject": "Shift+R", "accept_above": "Ctrl+Shift+A"}


@dataclass(frozen=True)
class Shortcut:
    """One row of the keymap (module doc)."""

    action: str  # the QAction's id; "" for a mouse gesture (sheet only)
    keys: tuple[str, ...]
    text: str
    section: str
    where: str = "both"

    @property
    def key_text(self) -> str:
        return ", ".join(self.keys)


def _s(action: str, keys, text: str, section: str, where: str = "both") -> Shortcut:
    return Shortcut(action, (keys,) if isinstance(keys, str) else tuple(keys), text, section, where)


FILES, RUN, TOOLS, CLASSES, EDIT, PROPOSALS, VIEW, HELP = (
    "Frames and files", "Computation", "Tools", "Classes", "Lights and groups", "Proposals", "View", "Help")

#: Every shortcut, in the order the sheet shows them.
KEYMAP: tuple[Shortcut, ...] = (
    # ---- frames and files
    _s("save_annotation", "Ctrl+S", "Save the light annotation (beside the image: X_lights.json, its PNGs and "
       "COCO JSON; a read-only dataset's go to the annotations folder)", FILES),
    _s("done", "Ctrl+D", "Toggle this frame's 'done' flag (saved in its annotation)", FILES),
    _s("next_frame", ("PgDown", "Ctrl+Right"), "Next frame (asks to save unsaved edits)", FILES),
    _s("previous_frame", ("PgUp", "Ctrl+Left"), "Previous frame (asks to save unsaved edits)", FILES),
    _s("open_scene", "Ctrl+O", "Open a scene folder", FILES, "app"),
    _s("open_folder", "Ctrl+O", "Open a folder of images or scene folders", FILES, "annotate"),
    _s("open_image", "Ctrl+I", "Open one dataset image (its labels, camera and disparity are found by name)",
       FILES, "app"),
    _s("open_dataset", "Ctrl+Shift+D", "Open a dataset root: its frames in the Frames dock (✓ = annotated)",
       FILES, "app"),
    _s("open_project", "Ctrl+Shift+O", "Open a project folder", FILES, "app"),
    _s("reopen", "Ctrl+Shift+R", "Reopen the last scene", FILES, "app"),
    _s("save_project", "Ctrl+Shift+S", "Save a project: frame, annotation, parameters, cached results", FILES,
       "app"),
    _s("export", "Ctrl+E", "Export masks, depth, normals, meshes and nights (asks before overwriting)", FILES,
       "app"),
    _s("quit", "Ctrl+Q", "Quit (asks to save unsaved edits)", FILES),
    # ---- computation
    _s("recompute", "F5", "Recompute depth, refinement and mesh", RUN, "app"),
    _s("render", "F6", "Render the night preview (computes the mesh first when needed)", RUN, "app"),
    # (no QAction key: Esc is the editor's "clear selection" first; the main window cancels when the editor
    # has nothing to clear or does not have the focus)
    _s("", "Esc", "Cancel the running job (when the editor has no selection to clear)", RUN, "app"),
    # ---- tools
    _s("tool_superpixel", "S", "Superpixel tool: click/drag adds superpixels to the current light; Shift "
       "removes; Alt = the other scale", TOOLS),
    _s("tool_brush", "B", "Brush tool (pixels); Shift+drag erases", TOOLS),
    _s("tool_eraser", "E", "Eraser tool (pixels of any light)", TOOLS),
    _s("tool_fill", "F", "Fill-to-superpixel: click a light to snap it to the superpixels it mostly covers",
       TOOLS),
    _s("tool_select", "V", "Select tool: click selects, Shift/Ctrl+click adds/removes, a drag selects every "
       "light in the box", TOOLS),
    _s("tool_group", "G", "Group tool: clicks add/remove lights to/from the selection, a box adds", TOOLS),
    _s("split", "R", "Toggle 'one new light per region' for superpixel drags", TOOLS),
    _s("similar", "T", "Toggle 'similar colour only' for superpixel drags", TOOLS),
    _s("fine", "D", "Toggle the fine superpixel scale", TOOLS),
    _s("smaller", "[", "Brush smaller", TOOLS),
    _s("larger", "]", "Brush larger", TOOLS),
    # ---- classes
    _s("", "1-9, 0", "Light classes 1-10 (window_building … advertisement); each preselects its default "
       "group class", CLASSES),
    _s("", "Ctrl+1, Ctrl+2", "Light classes 11 clock, 12 inferred", CLASSES),
    _s("", "Alt+1 … Alt+9", "Group classes 13 windows_group … 21 traffic_sign_group", CLASSES),
    _s("filter", "Ctrl+F", "Filter the class buttons by name (Return picks the only match, Esc clears)",
       CLASSES),
    # ---- lights and groups
    _s("new", "N", "New light of the current class (the next stroke paints into it)", EDIT),
    _s("class", "C", "Change the selected lights (groups) to the current light (group) class", EDIT),
    _s("group", "Ctrl+G", "Group the selection; with one group selected, the other selected lights join it; "
       "several groups merge (keeping their class when they share one)", EDIT),
    _s("ungroup", "Ctrl+Shift+G", "Ungroup the selected groups / the groups of the selected lights", EDIT),
    _s("activate", "A", "Make the selected group active: new lights join it; A again or Esc ends", EDIT),
    _s("delete", ("Delete", "Backspace"), "Delete the selected lights or groups", EDIT),
    _s("delete_hovered", "X", "Delete the light under the mouse, nothing selected first (a false light "
       "'Accept ≥' took: one key each)", EDIT),
    _s("escape", "Esc", "Clear the selection, the current light and the active group", EDIT),
    _s("undo", "Ctrl+Z", "Undo", EDIT),
    _s("redo", ("Ctrl+Shift+Z", "Ctrl+Y"), "Redo", EDIT),
    _s("", "Right click", "Make the light under the mouse the current one", EDIT),
    _s("", "Right-drag", "Superpixel/brush tool, from a light: add what the stroke passes over to that light "
       "(Shift+right-drag: remove it; a touch-up, with 'one new light per region' on or off)", EDIT),
    _s("", "Ctrl+drag", "Any tool: add every light the mouse path passes over to the selection (stroke select: "
       "a floor of windows slanting across the image in one gesture); Ctrl+click adds/removes one", EDIT),
    _s("", "Ctrl+Shift+drag", "Any tool: the same, then group the selection as Ctrl+G (stroke group: a floor of "
       "accepted windows split over several proposed groups becomes one group in one gesture); "
       "Ctrl+Shift+click: add one light and group", EDIT),
    _s("", "Double-click", "Select/Group tool (Ctrl+double-click: any tool): the group of the light under the "
       "mouse becomes active, the lights drawn next join it; on the background: ends it", EDIT),
    # ---- proposals
    _s("propose", PROPOSAL_KEYS["propose"], "Propose lights automatically (a dashed layer apart from the "
       "annotation; computed in the background)", PROPOSALS),
    _s("accept", PROPOSAL_KEYS["accept"], "Accept the proposals selected in the list, else the one under the "
       "mouse with its group (one undo step)", PROPOSALS),
    _s("reject", PROPOSAL_KEYS["reject"], "Reject the selected proposals, else the one under the mouse with "
       "its group", PROPOSALS),
    _s("accept_above", PROPOSAL_KEYS["accept_above"], "Accept every pending proposal at or above the "
       "confidence slider", PROPOSALS),
    _s("", "Ctrl+drag from a proposal", "Accept every pending proposal the path passes over, with their "
       "proposed groups restricted to them, and select them (stroke accept: a row of proposals under the "
       "slider without their group's false mates); Ctrl+Shift: group them too", PROPOSALS),
    # ---- view
    _s("layer_labels", "L", "Show/hide the semantic labels", VIEW),
    _s("layer_superpixels", "P", "Show/hide the superpixel borders (drawn only where a superpixel is at least "
       "8 screen pixels wide)", VIEW),
    _s("layer_lights", "M", "Show/hide the light masks", VIEW),
    _s("", "Wheel", "Zoom under the mouse", VIEW),
    _s("", "Space+drag, middle drag", "Pan", VIEW),
    _s("", "Home", "Fit the image in the view", VIEW),
    _s("help", "F1", "This sheet", HELP),
)

_BY_ACTION: dict[tuple[str, str], Shortcut] = {}
for _sc in KEYMAP:
    if _sc.action:
        for _w in (("app", "annotate") if _sc.where == "both" else (_sc.where,)):
            _BY_ACTION[(_sc.action, _w)] = _sc


def keys(action: str, window: str = "app") -> list[QKeySequence]:
    """The key sequences of ``action`` in ``window`` ("app" or "annotate"); KeyError for an unknown action."""
    return [QKeySequence(k) for k in _BY_ACTION[(action, window)].keys]


def rows(window: str = "app") -> list[Shortcut]:
    """The sheet's rows for ``window``: every shortcut that exists there."""
    return [sc for sc in KEYMAP if sc.where in ("both", window)]


def class_keys() -> dict[int, str]:
    """Keys of the light (1-12) and group (13-21) classes."""
    return {**LIGHT_CLASS_KEYS, **GROUP_CLASS_KEYS}


class ShortcutSheet(QDialog):
    """Every shortcut of ``window`` (F1), generated from :data:`KEYMAP`, grouped by section, the text
    wrapped so no row is cut off."""

    def __init__(self, window: str = "app", parent=None) -> None:
        super().__init__(parent)
        self.setWindowTitle("NPSim shortcuts" if window == "app" else "Annotation editor shortcuts")
        shown = rows(window)
        items: list[tuple[str, str, bool]] = []
        section = None
        for sc in shown:
            if sc.section != section:
                section = sc.section
                items.append((section, "", True))
            items.append((sc.key_text, sc.text, False))
        table = QTableWidget(len(items), 2, self)
        table.setHorizontalHeaderLabels(["Keys", "Action"])
        bold = table.font()
        bold.setBold(True)
        for r, (k, what, head) in enumerate(items):
            a, b = QTableWidgetItem(k), QTableWidgetItem(what)
            if head:
                a.setFont(bold)
                table.setSpan(r, 0, 1, 2)
            table.setItem(r, 0, a)
            table.setItem(r, 1, b)
        table.verticalHeader().setVisible(False)
        table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        table.setWordWrap(True)
        table.setTextElideMode(Qt.TextElideMode.ElideNone)
        table.resizeColumnToContents(0)
        table.setColumnWidth(0, table.columnWidth(0) + 16)  # keys on one line, whatever the style's margins
        table.horizontalHeader().setSectionResizeMode(0, QHeaderView.ResizeMode.Fixed)
        table.horizontalHeader().setSectionResizeMode(1, QHeaderView.ResizeMode.Stretch)
        # rows grow to the wrapped text whenever the Action column's width changes
        table.horizontalHeader().sectionResized.connect(lambda *_: table.resizeRowsToContents())
        buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close, Qt.Orientation.Horizontal, self)
        buttons.rejected.connect(self.reject)
        lay = QVBoxLayout(self)
        lay.addWidget(table)
        lay.addWidget(buttons)
        self.table = table
        self.shortcuts = shown
        self.resize(860, 720)
        table.resizeRowsToContents()

    def showEvent(self, event) -> None:  # noqa: N802 (Qt API)
        super().showEvent(event)
        self.table.resizeRowsToContents()
