"""``AnnotationEditor``: the canvas plus tool, layer, palette and instance panels.

A reusable widget (the main app embeds it); :class:`~npsim_gui.editor.window.EditorWindow`
adds menus, files, autosave and image stepping around it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (QAbstractItemView, QAbstractButton, QButtonGroup, QCheckBox, QComboBox, QDoubleSpinBox, QFormLayout,
                               QGridLayout, QGroupBox, QHBoxLayout, QLabel, QMainWindow, QPushButton, QScrollArea,
                               QSlider, QSpinBox, QTabWidget, QToolButton, QTreeWidget, QTreeWidgetItem,
                               QVBoxLayout, QWidget)

from npsim_core.annotation import class_of, is_group_class, is_light_class
from npsim_core.annotation_ops import Change, change_class, delete_instance, new_instance, ungroup
from npsim_core.errors import NpsimInputError
from npsim_core.labels import light_class
from npsim_core.superpixels import METHODS

from .canvas import EditorCanvas
from .overlays import boundary_rgba, class_color, labels_rgba, lights_region, lit_box
from .palette import ClassPalette, InstanceList
from .proposals import DEFAULT_ACCEPT_THRESHOLD, ProposalBook
from .session import EditorSession
from .shortcuts import GROUP_CLASS_KEYS, KEYMAP, LIGHT_CLASS_KEYS, PROPOSAL_KEYS, ShortcutSheet
from .shortcuts import keys as keymap_keys
from ..workers import JobChannel
from .tools import Tool, ToolController, ToolOptions

TOOL_KEYS = {Tool.SUPERPIXEL: "S", Tool.BRUSH: "B", Tool.ERASER: "E", Tool.FILL: "F", Tool.SELECT: "V",
             Tool.GROUP: "G"}
#: The night's choice of lights (``lights.source``) as the Proposals box offers it.
NIGHT_LIGHT_RULES = (("auto", "annotated lights, else proposals"), ("annotation", "annotated lights only"),
                     ("proposed", "all proposals"), ("none", "no lights"))
TOOL_TITLES = {Tool.SUPERPIXEL: "Superpixel", Tool.BRUSH: "Brush", Tool.ERASER: "Eraser", Tool.FILL: "Fill",
               Tool.SELECT: "Select", Tool.GROUP: "Group"}
TOOL_TIPS = {Tool.SUPERPIXEL: "click/drag adds superpixels to the current light; Shift removes; Alt: the other scale; "
                               "a right-drag from a light adds to that light (Shift: removes), a touch-up",
             Tool.BRUSH: "paints a disc along the path; Shift+drag erases; a right-drag from a light paints into "
                         "that light (Shift: erases from it)",
             Tool.ERASER: "clears the pixels of any light along the path",
             Tool.FILL: "click a light: it takes the superpixels it covers at least half of",
             Tool.SELECT: "click selects; Shift/Ctrl+click adds or removes; a drag selects every light in the box "
                          "(Shift+drag adds)",
             Tool.GROUP: "clicks add or remove lights; a box adds"}
#: Every tool's tooltip ends with the selection strokes, which work with any tool (docs/annotation.md).
STROKE_TIP = ("\nAny tool: Ctrl+drag adds every light the path passes over to the selection (a slanted floor of "
              "windows in one stroke); Ctrl+Shift+drag adds them and groups the selection (as Ctrl+G)")


class _ProposalLayer:
    """The editor's proposal layer as the tools' stroke accept sees it (``tools.ProposalStroke``): the pending
    proposals while the layer is shown, and their acceptance through the editor (list, status, message)."""

    def __init__(self, editor: "AnnotationEditor") -> None:
        self.editor = editor

    def pending_map(self) -> np.ndarray | None:
        ed = self.editor
        if ed.proposal_book is None or not ed.proposal_box.isChecked():
            return None  # a hidden layer is not there to stroke over
        return ed.proposal_book.pending_map(ed._existing_ids())

    def accept(self, lights: list[int]) -> list[int]:
        ed = self.editor
        new = ed._safe_result(lambda: ed.proposal_book.accept_lights(ed.session, lights)) or []
        ed.refresh_proposals()
        return new


class AnnotationEditor(QWidget):
    """Canvas + side panel editing one image's light annotation (see ``session``)."""

    #: Forwarded from the session: True when there are unsaved edits.
    dirtyChanged = Signal(bool)
    #: Esc pressed with nothing to clear (the main window then cancels its running job).
    escapeUnused = Signal()

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.session = EditorSession(self)
        self.options = ToolOptions()
        self.controller = ToolController(self.session, self.options)
        self.controller.proposals = _ProposalLayer(self)  # stroke accept (tools module doc)
        self.canvas = EditorCanvas(self)
        self.canvas.handler = self.controller
        self._lights_rgba = np.zeros((1, 1, 4), np.uint8)
        self._labels_layer_for: np.ndarray | None = None  # the labels the label layer was drawn from
        self._shown_highlight: set[int] = set()  # highlighted lights the light layer was drawn with
        self._stats: dict | None = None  # ann.stats() cache, dropped on every edit
        self._refresh_timer = QTimer(self)
        self._refresh_timer.setSingleShot(True)
        self._refresh_timer.setInterval(60)
        self._refresh_timer.timeout.connect(self._refresh_lists)
        #: The proposals of this image and what became of them (None before "Propose lights").
        self.proposal_book: ProposalBook | None = None
        #: ``proposal_source()`` -> a callable run in a worker that returns ``LightProposals``; the
        #: main window supplies the frame's depth and camera, the default proposes from image + labels.
        self.proposal_source = None
        self.proposal_jobs = JobChannel("proposals", parent=self)
        self._hover_xy = (-1, -1)
        self._proposal_timer = QTimer(self)
        self._proposal_timer.setSingleShot(True)
        self._proposal_timer.setInterval(80)
        self._proposal_timer.timeout.connect(self.refresh_proposals)
        self._build_ui()
        self._build_actions()
        # Buttons and check boxes never take the keyboard focus: Space (pan) and the
        # shortcuts must keep going to the canvas, not re-press the last clicked button.
        for w in self.findChildren(QAbstractButton):
            w.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        self.side_panel.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        s = self.session
        s.loaded.connect(self._on_loaded)
        s.changed.connect(self._on_changed)
        s.selectionChanged.connect(self._on_selection)
        s.currentChanged.connect(self._on_current)
        s.superpixelsReady.connect(self._on_superpixels)
        s.fineReady.connect(self._on_superpixels)
        s.dirtyChanged.connect(self.dirtyChanged)
        s.message.connect(self.show_message)
        s.loaded.connect(self.clear_proposals)
        s.changed.connect(lambda ch: self._proposal_timer.start()
                          if self.proposal_book is not None and ch.structure else None)
        self.proposal_jobs.finished.connect(self._on_proposals)
        self.proposal_jobs.failed.connect(lambda msg, _tb: self._proposal_failed(msg))
        self.proposal_jobs.busy.connect(self._on_proposal_busy)
        self.set_tool(Tool.SUPERPIXEL)

    # ----------------------------------------------------------------- UI
    def _build_ui(self) -> None:
        panel = QWidget()
        pl = QVBoxLayout(panel)
        pl.setContentsMargins(4, 4, 4, 4)
        pl.setSpacing(4)

        tools = QGroupBox("Tools")
        tl = QGridLayout(tools)
        tl.setSpacing(2)
        self.tool_group = QButtonGroup(self)
        self.tool_buttons: dict[Tool, QToolButton] = {}
        for k, t in enumerate(Tool):
            b = QToolButton()
            b.setText(f"{TOOL_TITLES[t]} ({TOOL_KEYS[t]})")
            b.setToolTip(TOOL_TIPS[t] + STROKE_TIP)
            b.setCheckable(True)
            b.setSizePolicy(b.sizePolicy().Policy.Expanding, b.sizePolicy().Policy.Fixed)
            b.clicked.connect(lambda _=False, t=t: self.set_tool(t))
            self.tool_group.addButton(b)
            self.tool_buttons[t] = b
            tl.addWidget(b, k // 3, k % 3)
        opts = QFormLayout()
        opts.setContentsMargins(0, 4, 0, 0)
        self.brush_spin = QSpinBox()
        self.brush_spin.setRange(0, 100)
        self.brush_spin.setValue(int(self.options.brush_radius))
        self.brush_spin.setSuffix(" px radius")
        self.brush_spin.valueChanged.connect(self._on_brush)
        opts.addRow("Brush", self.brush_spin)
        self.split_box = QCheckBox("One new light per region (R)")
        self.split_box.toggled.connect(lambda v: setattr(self.options, "split_regions", v))
        self.similar_box = QCheckBox("Similar colour only (T)")
        self.similar_box.toggled.connect(lambda v: setattr(self.options, "similar_only", v))
        self.tol_spin = QDoubleSpinBox()
        self.tol_spin.setRange(0, 200)
        self.tol_spin.setSpecialValueText("auto")
        self.tol_spin.setToolTip("colour tolerance (CIELab); auto = drop the wall (the densest colour the drag covered), keep the rest")
        self.tol_spin.setValue(self.options.tolerance)
        self.tol_spin.valueChanged.connect(lambda v: setattr(self.options, "tolerance", float(v)))
        self.overwrite_box = QCheckBox("Paint over other lights")
        self.overwrite_box.toggled.connect(lambda v: setattr(self.options, "overwrite", v))
        self.fine_box = QCheckBox("Fine superpixel scale (D; Alt inverts)")
        self.fine_box.toggled.connect(self._on_fine_toggled)
        self.vehicle_box = QCheckBox("Group by vehicle")
        self.vehicle_box.setChecked(True)
        self.vehicle_box.setToolTip("A window or lamp drawn on a car, truck or bus joins that vehicle's group (or "
                                    "makes it): needs the frame's instanceIds (X_instanceIds.png beside its labels)")
        self.vehicle_box.toggled.connect(lambda v: setattr(self.session, "group_by_vehicle", v))
        opts.addRow(self.split_box)
        sim = QHBoxLayout()
        sim.addWidget(self.similar_box)
        sim.addWidget(self.tol_spin)
        opts.addRow(sim)
        paint_row = QHBoxLayout()  # (one row: the side panel fits 1600x900 without scrolling)
        paint_row.addWidget(self.overwrite_box)
        paint_row.addWidget(self.vehicle_box)
        opts.addRow(paint_row)
        opts.addRow(self.fine_box)
        tl.addLayout(opts, 2, 0, 1, 3)
        pl.addWidget(tools)

        # Display adjustment of the base image (never of the data).
        view = QGroupBox("View (display only)")
        vl_outer = QVBoxLayout(view)
        vl_outer.setSpacing(2)
        vl = QHBoxLayout()
        vl.setSpacing(3)
        vl2 = QHBoxLayout()
        vl2.setSpacing(3)
        vl_outer.addLayout(vl)
        vl_outer.addLayout(vl2)
        self.view_brightness = QSpinBox()
        self.view_brightness.setRange(-100, 100)
        self.view_brightness.setSuffix(" %")
        self.view_brightness.setPrefix("b ")
        self.view_brightness.setToolTip("brightness: added to the shown image (% of full scale)")
        self.view_contrast = QDoubleSpinBox()
        self.view_contrast.setRange(0.1, 10.0)
        self.view_contrast.setSingleStep(0.1)
        self.view_contrast.setDecimals(2)
        self.view_contrast.setValue(1.0)
        self.view_contrast.setPrefix("c ")
        self.view_contrast.setToolTip("contrast: gain about mid-grey")
        self.view_gamma = QDoubleSpinBox()
        self.view_gamma.setRange(0.1, 5.0)
        self.view_gamma.setSingleStep(0.1)
        self.view_gamma.setDecimals(2)
        self.view_gamma.setValue(1.0)
        self.view_gamma.setPrefix("γ ")
        self.view_gamma.setToolTip("gamma: > 1 brightens dark parts (shown = value^(1/gamma))")
        for w in (self.view_brightness, self.view_contrast, self.view_gamma):
            w.valueChanged.connect(self._on_display)
            vl.addWidget(w)
        self.view_auto = QPushButton("Auto")
        self.view_auto.setToolTip("stretch the shown image's 1–99 % brightness range")
        self.view_auto.clicked.connect(self.auto_display)
        self.view_reset = QPushButton("Reset")
        self.view_reset.clicked.connect(lambda: self.set_display(0.0, 1.0, 1.0))
        vl2.addWidget(self.view_auto)
        vl2.addWidget(self.view_reset)
        vl_outer.addStretch(1)
        view.setTitle("")
        view.setFlat(True)

        # Top bar over the canvas: layer toggles with opacity, superpixel settings.
        # Two rows, so the canvas column stays narrow enough for 1600-px screens.
        bar = QWidget()
        bl = QGridLayout(bar)
        bl.setContentsMargins(4, 2, 4, 2)
        bl.setHorizontalSpacing(6)
        bl.setVerticalSpacing(0)
        self.layer_boxes: dict[str, QCheckBox] = {}
        self.layer_sliders: dict[str, QSlider] = {}
        for k, (name, title, key) in enumerate((("labels", "Labels", "L"), ("superpixels", "Superpixels", "P"),
                                                ("lights", "Lights", "M"))):
            cb = QCheckBox(f"{title} ({key})")
            cb.setChecked(name != "labels")
            cb.toggled.connect(lambda v, n=name: self._on_layer_toggled(n, v))
            self.canvas.set_layer_visible(name, cb.isChecked())
            sl_ = QSlider(Qt.Orientation.Horizontal)
            sl_.setRange(0, 100)
            sl_.setValue(int(round(self.canvas.layers[name].opacity() * 100)))
            sl_.setToolTip(f"{title} opacity")
            sl_.setFixedWidth(50)
            sl_.valueChanged.connect(lambda v, n=name: self.canvas.set_layer_opacity(n, v / 100))
            bl.addWidget(cb, k // 2, 2 * (k % 2))
            bl.addWidget(sl_, k // 2, 2 * (k % 2) + 1)
            self.layer_boxes[name] = cb
            self.layer_sliders[name] = sl_
        bl.setColumnStretch(4, 1)
        self.zoom_label = QLabel("")
        bl.addWidget(self.zoom_label, 0, 5)
        self.canvas.zoomChanged.connect(lambda z: self.zoom_label.setText(f"zoom {z:.2f}"))
        self.canvas.zoomChanged.connect(lambda _z: self._update_superpixel_layer())
        self.sp_method = QComboBox()
        self.sp_method.addItems(list(METHODS))
        self.sp_method.setToolTip("superpixel method")
        self.sp_size = QSpinBox()
        self.sp_size.setRange(3, 200)
        self.sp_size.setPrefix("size ")
        self.sp_size.setToolTip("superpixel size (px); the fine scale (Alt) is half of it")
        self.sp_compact = QDoubleSpinBox()
        self.sp_compact.setRange(0.5, 100)
        self.sp_compact.setDecimals(1)
        self.sp_compact.setPrefix("c ")
        self.sp_compact.setToolTip("compactness (SLIC/MSLIC ruler; LSC ratio x100; SEEDS ignores it)")
        p = self.session.sp_params
        self.sp_method.setCurrentText(p.method)
        self.sp_size.setValue(p.region_size)
        self.sp_compact.setValue(p.compactness)
        apply_sp = QPushButton("Segment")
        apply_sp.clicked.connect(self._apply_superpixel_settings)
        self.sp_status = QLabel("…")
        sp_row = QHBoxLayout()
        sp_row.setSpacing(3)
        for w in (self.sp_method, self.sp_size, self.sp_compact, apply_sp):
            sp_row.addWidget(w)
        sp_row.insertWidget(3, apply_sp)  # (placed below: the row is narrower in two lines)
        sp_row.removeWidget(apply_sp)
        opts.addRow("Superpixels", sp_row)
        sp_row2 = QHBoxLayout()
        sp_row2.addStretch(1)
        sp_row2.addWidget(apply_sp)
        opts.addRow(sp_row2)
        bl.addWidget(self.sp_status, 1, 2, 1, 4)  # under the zoom read-out

        pal = QGroupBox("Classes")
        pal_l = QVBoxLayout(pal)
        self.palette = ClassPalette()
        self.palette.lightClassChosen.connect(self.session.set_current_class)
        self.palette.groupClassChosen.connect(self.session.set_current_class)
        self.palette.filterDone.connect(self.canvas.setFocus)
        pal_l.addWidget(self.palette)
        # Classes, instances and proposals share one tabbed area under the tools: each is on screen when
        # picked, none below the fold (the side panel at 1600x900 ran 1350 px tall)
        self.side_tabs = QTabWidget()
        self.side_tabs.setDocumentMode(True)
        self.side_tabs.addTab(pal, "Classes")

        proposals_box = self.proposals_box = self._build_proposals_box()

        inst = QGroupBox("Instances")
        il = QVBoxLayout(inst)
        self.instance_list = InstanceList()
        self.instance_list.setMinimumHeight(110)
        self.instance_list.selectionEdited.connect(self._on_list_selection)
        il.addWidget(self.instance_list)
        row = QGridLayout()
        row.setSpacing(2)
        for k, (text, slot) in enumerate((("New", self.new_light), ("Class", self.change_selected_class),
                                          ("Group", self.group_selected), ("Ungroup", self.ungroup_selected),
                                          ("Delete", self.delete_selected))):
            b = QPushButton(text)
            b.clicked.connect(slot)
            row.addWidget(b, k // 3, k % 3)
        il.addLayout(row)
        self.side_tabs.addTab(inst, "Instances")
        self.side_tabs.addTab(proposals_box, "Proposals")
        self.side_tabs.addTab(view, "View")
        self.side_tabs.setTabToolTip(3, "brightness, contrast and gamma of the shown image (display only)")
        for box in (pal, inst, proposals_box):
            box.setTitle("")  # the tab names them
            box.setFlat(True)
        pl.addWidget(self.side_tabs, 1)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        pl.addWidget(self.status)

        scroll = QScrollArea()
        scroll.setWidget(panel)
        scroll.setWidgetResizable(True)
        # As wide as the panel needs, plus room for the vertical scroll bar.
        scroll.setFixedWidth(panel.minimumSizeHint().width() + scroll.verticalScrollBar().sizeHint().width() + 6)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.side_panel = scroll
        left = QWidget()
        lv = QVBoxLayout(left)
        lv.setContentsMargins(0, 0, 0, 0)
        lv.setSpacing(0)
        lv.addWidget(bar)
        lv.addWidget(self.canvas, 1)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.setSpacing(2)
        lay.addWidget(left, 1)
        lay.addWidget(scroll, 0)
        self.canvas.hovered.connect(self._on_hover)

    def _action(self, text: str, keys, slot) -> QAction:
        """An editor action; ``keys``: an action id of the keymap (:data:`shortcuts.KEYMAP`) or literal keys."""
        a = QAction(text, self)
        if isinstance(keys, str) and any(sc.action == keys for sc in KEYMAP):
            a.setShortcuts(keymap_keys(keys))
        else:
            a.setShortcuts([QKeySequence(k) for k in ([keys] if isinstance(keys, str) else keys)])
        a.setShortcutContext(Qt.ShortcutContext.WidgetWithChildrenShortcut)
        a.triggered.connect(slot)
        self.addAction(a)
        return a

    def _build_actions(self) -> None:
        self.actions_by_name: dict[str, QAction] = {}
        A = self.actions_by_name
        A["undo"] = self._action("Undo", "undo", self.session.undo)
        A["redo"] = self._action("Redo", "redo", self.session.redo)
        for t in TOOL_KEYS:
            A[f"tool_{t.value}"] = self._action(TOOL_TITLES[t], f"tool_{t.value}", lambda _=False, t=t: self.set_tool(t))
        for cid, k in {**LIGHT_CLASS_KEYS, **GROUP_CLASS_KEYS}.items():
            A[f"class_{cid}"] = self._action(light_class(cid).name, [k],
                                             lambda _=False, c=cid: self.session.set_current_class(c))
        A["new"] = self._action("New light", "new", self.new_light)
        A["class"] = self._action("Change class of selection", "class", self.change_selected_class)
        A["group"] = self._action("Group selection", "group", self.group_selected)
        A["ungroup"] = self._action("Ungroup", "ungroup", self.ungroup_selected)
        A["delete"] = self._action("Delete selection", "delete", self.delete_selected)
        A["delete_hovered"] = self._action("Delete light under mouse", "delete_hovered", self.delete_hovered)
        A["activate"] = self._action("Activate group (new lights join it; or double-click a light of it)", "activate",
                                     self.toggle_active_group)
        A["activate"].setToolTip("The selected group becomes active: the lights drawn next join it (one undo step "
                                 "each). Faster: double-click a light of the group with the Select tool, or "
                                 "Ctrl+double-click with any tool; double-click the background or Esc ends it.")
        A["escape"] = self._action("Clear selection", "escape", self.clear_selection)
        A["filter"] = self._action("Filter classes", "filter", self.focus_class_filter)
        A["split"] = self._action("One light per region", "split", self.split_box.toggle)
        A["similar"] = self._action("Similar colour only", "similar", self.similar_box.toggle)
        A["fine"] = self._action("Fine superpixel scale", "fine", self.fine_box.toggle)
        A["smaller"] = self._action("Brush smaller", "smaller", lambda: self.brush_spin.setValue(self.brush_spin.value() - 1))
        A["larger"] = self._action("Brush larger", "larger", lambda: self.brush_spin.setValue(self.brush_spin.value() + 1))
        for name in ("labels", "superpixels", "lights"):
            A[f"layer_{name}"] = self._action(f"Toggle {name}", f"layer_{name}", self.layer_boxes[name].toggle)
        A["help"] = self._action("Shortcuts", "help", self.show_shortcuts)
        A["propose"] = self._action("Propose lights", "propose", self.propose_lights)
        # (lambdas: triggered(bool) must not reach the methods' optional arguments)
        A["accept"] = self._action("Accept proposals", "accept", lambda: self.accept_proposals())
        A["reject"] = self._action("Reject proposals", "reject", lambda: self.reject_proposals())
        A["accept_above"] = self._action("Accept proposals above the confidence", "accept_above",
                                         lambda: self.accept_proposals_above())

    # ----------------------------------------------------------------- public API
    def load(self, image, labels=None, ann=None, folder=None, stem="annotation", *, dirty=False,
             instances=None) -> None:
        """Edit ``image`` (HxWx3 uint8) with optional labelIds, annotation and Cityscapes instanceIds (HxW
        integers: a vehicle light drawn on a vehicle joins its group)."""
        self.session.load(image, labels, ann, folder, stem, dirty=dirty)
        self.session.set_vehicle_instances(instances)
        self.vehicle_box.setEnabled(instances is not None)

    def show_image(self, rgb: np.ndarray) -> None:
        """Show ``rgb`` fitted in the canvas before its annotation is loaded (e.g. while a question about
        it is asked), so the canvas and its zoom read-out never show the previous or an empty image."""
        self.canvas.set_base_image(rgb)
        self.canvas.fit()

    def set_base_image(self, rgb: np.ndarray | None) -> None:
        """Show another view (e.g. a depth visualisation) under the overlays; None = the image."""
        self.canvas.set_base_image(self.session.image if rgb is None else rgb)

    def set_display(self, brightness: float = 0.0, contrast: float = 1.0, gamma: float = 1.0) -> None:
        """Brightness (fraction of full scale, -1..1), contrast and gamma of the shown image (display only)."""
        for w, v in ((self.view_brightness, int(round(brightness * 100))), (self.view_contrast, contrast),
                     (self.view_gamma, gamma)):
            w.blockSignals(True)
            w.setValue(v)
            w.blockSignals(False)
        self._on_display()

    def auto_display(self) -> None:
        """Stretch the shown image's brightness range (e.g. for a dark real frame)."""
        self.set_display(*self.canvas.auto_display())

    def _on_display(self, *_):
        self.canvas.set_display(self.view_brightness.value() / 100.0, self.view_contrast.value(),
                                self.view_gamma.value())

    def shutdown(self) -> None:
        """Cancel background work (call when the editor is closed for good; deleting the editor or
        quitting the application does it too)."""
        self.session.shutdown()

    def set_tool(self, tool: Tool) -> None:
        self.controller.tool = Tool(tool)
        self.tool_buttons[Tool(tool)].setChecked(True)
        self.canvas.set_brush_radius(self.options.brush_radius if tool in (Tool.BRUSH, Tool.ERASER) else 0)

    def show_message(self, text: str) -> None:
        self.status.setText(text)

    #: Which window's keymap the F1 sheet shows ("annotate" stand-alone, "app" in the main window).
    keymap_window = "annotate"

    def show_shortcuts(self) -> ShortcutSheet:
        dlg = ShortcutSheet(self.keymap_window, self)
        dlg.show()
        self._shortcut_dialog = dlg
        return dlg

    # ----------------------------------------------------------------- commands on the selection
    def _safe(self, fn) -> None:
        try:
            fn()
        except NpsimInputError as exc:
            self.show_message(str(exc))

    def new_light(self) -> None:
        def go():
            s = self.session
            cmd, iid = new_instance(s.ann, s.current_class)
            s.begin_stroke("new light")
            try:
                s.apply(cmd)
                s.lights_created([iid])  # joins the active group in the same undo step
            finally:
                s.end_stroke()
            s.set_selection({iid}, current=iid)
        self._safe(go)

    def selected_lights(self) -> list[int]:
        return sorted(self.session.selected_lights())

    def group_selected(self) -> None:
        """Ctrl+G: group the selection (:meth:`EditorSession.group_selection`, one undo step): with exactly one
        group selected (and no other group class picked by hand) the other selected lights join that group;
        otherwise a new group of the group class picked by hand, or else of the lights' default group class."""
        def go():
            _gid, text = self.session.group_selection()
            self.show_message(text)
        self._safe(go)

    def toggle_active_group(self) -> None:
        """Key A: the group of the selection becomes active (new lights join it); again ends it."""
        s = self.session
        groups = s.selected_groups() | {g for i in s.selected_lights() if (g := s.ann.group_of(i)) is not None}
        if s.active_group is not None and (not groups or groups == {s.active_group}):
            s.set_active_group(None)
            self.show_message("no active group: new lights are ungrouped")
        elif len(groups) == 1:
            s.set_active_group(groups.pop())
            self.show_message(f"active group {light_class(class_of(s.active_group)).name} {s.active_group}: "
                              "new lights join it (A, Esc or a double-click on the background ends)")
        else:
            self.show_message("select one group (or one of its lights) to make it active")

    def clear_selection(self) -> None:
        """Esc: no selection, no current light, no active group (:attr:`escapeUnused` when there were none)."""
        s = self.session
        if s.active_group is None and not s.selection and s.current_id is None:
            self.escapeUnused.emit()
            return
        s.set_active_group(None)
        s.set_selection(set(), current=None)
        s.set_current(None)

    def focus_class_filter(self) -> None:
        self.palette.filter_edit.setFocus()
        self.palette.filter_edit.selectAll()

    def ungroup_selected(self) -> None:
        s = self.session
        gids = {i for i in s.selection if i in s.ann.groups}
        gids |= {g for i in s.selection if (g := s.ann.group_of(i)) is not None}
        if gids:
            s.begin_stroke("ungroup")
            for g in sorted(gids):
                s.apply(ungroup(s.ann, g))
            s.end_stroke()

    def delete_selected(self) -> None:
        s = self.session
        ids = sorted(s.selection) or ([s.current_id] if s.current_id else [])
        if not ids:
            return
        s.begin_stroke("delete")
        for i in ids:  # lights first (lower ids); a group they empty is already gone when its turn comes
            if i in s.ann.groups or i in s.ann.instance_ids():
                s.apply(delete_instance(s.ann, i))
        s.end_stroke()
        s.set_selection(set(), current=None)

    def delete_hovered(self) -> int:
        """Delete the light under the mouse (key X; its group loses it, a group it empties goes) as one undo
        step, whatever is selected; returns its id, 0 when the mouse is over no light. Reviewing what
        "Accept ≥" took, a false light then costs one key instead of a right-click and Delete."""
        s = self.session
        iid = s.instance_at(*self._hover_xy)
        if not iid:
            self.show_message("no light under the mouse")
            return 0
        s.begin_stroke("delete")
        s.apply(delete_instance(s.ann, iid))
        s.end_stroke()
        if iid in s.selection:
            s.set_selection(s.selection - {iid})
        if s.current_id == iid:
            s.set_current(None)
        return iid

    def change_selected_class(self) -> None:
        def go():
            s = self.session
            ids = sorted(s.selection) or ([s.current_id] if s.current_id else [])
            new_sel = set()
            s.begin_stroke("change class")
            try:
                for i in ids:
                    target = s.group_class if is_group_class(class_of(i)) else s.current_class
                    if target is None:  # a group, but no group class chosen: it keeps its class
                        new_sel.add(i)
                        continue
                    cmd, nid = change_class(s.ann, i, target)
                    s.apply(cmd)
                    new_sel.add(nid)
            finally:
                s.end_stroke()
            s.set_selection(new_sel, current=max(new_sel) if new_sel and len(new_sel) == 1 else None)
        self._safe(go)

    # ----------------------------------------------------------------- session -> view
    def _on_loaded(self) -> None:
        s = self.session
        self.canvas.set_base_image(s.image)
        H, W = s.ann.shape
        self._labels_layer_for = None  # drawn when first shown (hidden by default: 90 ms at 2048x1024)
        self._show_labels_layer()
        self.layer_boxes["labels"].setEnabled(s.labels is not None)
        # nothing to show until the superpixels arrive: an empty full-size layer still costs every repaint
        self.canvas.set_layer("superpixels", np.zeros((1, 1, 4), np.uint8))
        self._lights_rgba = np.zeros((H, W, 4), np.uint8)
        self._stats = None
        self._shown_highlight = s.highlighted()
        # only the box of the labelled pixels: the rest of a fresh layer is transparent (and not painted)
        box = lit_box(s.ann.instance_map)
        lights_region(s.ann.instance_map, self._lights_rgba, box, self._shown_highlight)
        self.canvas.layers["lights"].set_array(self._lights_rgba, content=box)
        self.sp_status.setText("computing…")
        self._sync_superpixel_widgets()
        self.canvas.fit()
        self._refresh_lists()
        self._on_current()

    #: Superpixel borders are drawn only when a superpixel is at least this many screen pixels wide: at
    #: fit zoom on a large frame they speckle the whole image and hide the proposals.
    MIN_SUPERPIXEL_SCREEN_PX = 8.0

    def superpixel_borders_shown(self) -> bool:
        """True when the borders are on (P) and large enough on screen to be read."""
        s = self.session
        size = s.sp_params.region_size * (0.5 if self.options.fine_scale else 1.0)
        return self.layer_boxes["superpixels"].isChecked() and \
            size * self.canvas.zoom() >= self.MIN_SUPERPIXEL_SCREEN_PX

    def _update_superpixel_layer(self) -> None:
        on = self.superpixel_borders_shown()
        self.canvas.set_layer_visible("superpixels", on)
        cb = self.layer_boxes["superpixels"]
        cb.setToolTip("" if on or not cb.isChecked() else
                      "superpixel borders appear when you zoom in (hidden while a superpixel is under "
                      f"{self.MIN_SUPERPIXEL_SCREEN_PX:g} screen pixels)")

    def _on_layer_toggled(self, name: str, visible: bool) -> None:
        self.canvas.set_layer_visible(name, visible)
        if name == "labels" and visible:
            self._show_labels_layer()
        if name == "superpixels":
            self._update_superpixel_layer()

    def _show_labels_layer(self) -> None:
        """Draw the semantic label layer when it is visible and not drawn for these labels yet."""
        s = self.session
        if not self.canvas.layers["labels"].isVisible() or s.labels is None:
            if self._labels_layer_for is not s.labels:
                self.canvas.set_layer("labels", np.zeros((1, 1, 4), np.uint8))
            return
        if self._labels_layer_for is not s.labels:
            self.canvas.set_layer("labels", labels_rgba(s.labels))
            self._labels_layer_for = s.labels

    def _sync_superpixel_widgets(self) -> None:
        p = self.session.sp_params
        for w in (self.sp_method, self.sp_size, self.sp_compact):
            w.blockSignals(True)
        self.sp_method.setCurrentText(p.method)
        self.sp_size.setValue(p.region_size)
        self.sp_compact.setValue(p.compactness)
        for w in (self.sp_method, self.sp_size, self.sp_compact):
            w.blockSignals(False)

    def _on_superpixels(self) -> None:
        self._show_superpixel_borders()
        self._update_superpixel_layer()

    def _on_fine_toggled(self, on: bool) -> None:
        self.options.fine_scale = on
        self._show_superpixel_borders()
        self._update_superpixel_layer()

    def _show_superpixel_borders(self) -> None:
        """Borders of the scale the tools use (the fine one when the toggle is on and it is ready)."""
        s = self.session
        labels = s.sp_fine if self.options.fine_scale and s.sp_fine is not None else s.sp_coarse
        if labels is None:
            return
        self.canvas.set_layer("superpixels", boundary_rgba(labels))
        self.sp_status.setText(f"{int(s.sp_coarse.max()) + 1} superpixels"
                               + (f", fine {int(s.sp_fine.max()) + 1}" if s.sp_fine is not None else ", fine: …"))

    def _apply_superpixel_settings(self) -> None:
        self.sp_status.setText("computing…")
        self.session.request_superpixels(replace(self.session.sp_params, method=self.sp_method.currentText(),
                                                 region_size=self.sp_size.value(),
                                                 compactness=self.sp_compact.value()))

    def _ann_stats(self) -> dict:
        if self._stats is None:
            self._stats = self.session.ann.stats()
        return self._stats

    def _on_changed(self, ch: Change) -> None:
        self._stats = None
        if ch.rect is not None:
            # One pixel more on each side: outlines of the unchanged neighbours may change too.
            x0, y0, x1, y1 = ch.rect
            rect = (x0 - 1, y0 - 1, x1 + 1, y1 + 1)
            hl = self.session.highlighted()
            if hl != self._shown_highlight:  # e.g. an undone group: its lights' highlight changes too
                rect = self._union_rect(rect, self._highlight_rect(hl ^ self._shown_highlight))
                self._shown_highlight = hl
            lights_region(self.session.ann.instance_map, self._lights_rgba, rect, hl)
            self.canvas.layers["lights"].update_rect(rect)
        elif ch.structure:
            self._on_selection()
        self._refresh_timer.start()

    @staticmethod
    def _union_rect(a, b):
        if a is None or b is None:
            return a or b
        return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))

    def _highlight_rect(self, ids) -> tuple[int, int, int, int] | None:
        """Box (half-open) of the lights ``ids`` plus the one-pixel outer outline around them."""
        st = self._ann_stats()
        boxes = [st[i]["bbox"] for i in ids if st.get(i, {}).get("bbox")]
        if not boxes:
            return None
        return (min(b[0] for b in boxes) - 1, min(b[1] for b in boxes) - 1, max(b[2] for b in boxes) + 2,
                max(b[3] for b in boxes) + 2)

    def _on_selection(self) -> None:
        # Redraw only the boxes of the lights whose highlighted state changed.
        s = self.session
        hl = s.highlighted()
        rect = self._highlight_rect(self._shown_highlight ^ hl)
        self._shown_highlight = hl
        if rect is not None:
            lights_region(s.ann.instance_map, self._lights_rgba, rect, hl)
            self.canvas.layers["lights"].update_rect(rect)
        self.instance_list.set_selection(s.selection)
        n_l, n_g = len(s.selected_lights()), len(s.selected_groups())
        if n_l + n_g > 1:
            self.show_message(f"selected: {n_l} lights, {n_g} groups — Ctrl+G groups them")
        self._refresh_timer.start()

    def _on_current(self) -> None:
        s = self.session
        self.palette.set_current(s.current_class, s.group_class)
        cur = f"current light {s.current_id}" if s.current_id else "next stroke starts a new light"
        group = light_class(s.group_class).name if s.group_class is not None else "none (not grouped by default)"
        active = (f"; new lights join {light_class(class_of(s.active_group)).name} {s.active_group}"
                  if s.active_group is not None else "")
        self.show_message(f"class {light_class(s.current_class).name}, group class {group}; {cur}{active}")

    def _refresh_lists(self) -> None:
        s = self.session
        self.instance_list.rebuild(s.ann, s.selection, s.current_id, s.active_group)
        st = self._ann_stats()
        boxes = []
        few = len(s.ann.groups) <= 6
        for gid in sorted(s.ann.groups):
            b = s.ann.group_bbox(gid, st)
            if b is not None:
                # Selected groups (or groups of selected lights) in white with a caption;
                # captions for all only when there are few, so busy scenes stay readable.
                # The active group (new lights join it): solid, thicker, captioned.
                sel = gid in s.selection or bool(set(s.ann.groups[gid].members) & s.selection)
                active = gid == s.active_group
                color = (255, 255, 255) if sel or active else class_color(class_of(gid))
                caption = f"{light_class(class_of(gid)).name} {gid}" if (sel or few or active) else ""
                if active:
                    caption += " (active: new lights join)"
                boxes.append((gid, b, color, caption, active))
        self.canvas.set_group_boxes(boxes)

    def refresh_now(self) -> None:
        """Flush the debounced list / group-box refresh (tests and screenshots)."""
        self._refresh_timer.stop()
        self._refresh_lists()

    def _on_list_selection(self, ids: set[int]) -> None:
        self.session.set_selection(ids)
        lights = [i for i in ids if is_light_class(class_of(i))]
        if len(lights) == 1:
            self.session.set_current(lights[0])

    # ----------------------------------------------------------------- proposals
    def _build_proposals_box(self) -> QGroupBox:
        box = QGroupBox("Proposals")
        lay = QVBoxLayout(box)
        row = QHBoxLayout()
        self.propose_btn = QPushButton(f"Propose lights ({PROPOSAL_KEYS['propose']})")
        self.propose_btn.setToolTip("Propose traffic-light and street lamps, vehicle lamps and windows, building "
                                    "windows and advertisements from the image and its labels (in the background)")
        self.propose_btn.clicked.connect(self.propose_lights)
        self.propose_cancel = QPushButton("Cancel")
        self.propose_cancel.setEnabled(False)
        self.propose_cancel.clicked.connect(self.proposal_jobs.cancel)
        self.proposal_box = QCheckBox("show")
        self.proposal_box.setChecked(True)
        self.proposal_box.toggled.connect(lambda v: self.canvas.set_layer_visible(
            "proposals", v and self.proposal_book is not None))
        row.addWidget(self.propose_btn, 1)
        row.addWidget(self.propose_cancel)
        row.addWidget(self.proposal_box)
        lay.addLayout(row)
        row = QHBoxLayout()
        self.confidence_slider = QSlider(Qt.Orientation.Horizontal)
        self.confidence_slider.setRange(0, 100)
        self.confidence_slider.setValue(int(round(DEFAULT_ACCEPT_THRESHOLD * 100)))
        self.confidence_slider.setToolTip("confidence threshold of 'Accept ≥'")
        self.accept_above_btn = QPushButton()
        self.accept_above_btn.setToolTip(f"Accept every pending proposal at or above this confidence "
                                         f"({PROPOSAL_KEYS['accept_above']})")
        self.accept_above_btn.clicked.connect(lambda: self.accept_proposals_above())
        self.confidence_slider.valueChanged.connect(
            lambda v: self.accept_above_btn.setText(f"Accept ≥ {v / 100:.2f}"))
        self.accept_above_btn.setText(f"Accept ≥ {self.confidence_slider.value() / 100:.2f}")
        row.addWidget(self.confidence_slider, 1)
        row.addWidget(self.accept_above_btn)
        lay.addLayout(row)
        self.proposal_tree = QTreeWidget()
        self.proposal_tree.setHeaderLabels(["proposal", "conf."])
        self.proposal_tree.setSelectionMode(QAbstractItemView.SelectionMode.ExtendedSelection)
        self.proposal_tree.setMinimumHeight(90)
        self.proposal_tree.setColumnWidth(0, 190)
        lay.addWidget(self.proposal_tree)
        row = QHBoxLayout()
        for text, slot, tip in (("Accept", self.accept_proposals, PROPOSAL_KEYS["accept"]),
                                ("Reject", self.reject_proposals, PROPOSAL_KEYS["reject"]),
                                ("Reject rest", self.reject_all_proposals, "")):
            b = QPushButton(text)
            b.clicked.connect(lambda _=False, f=slot: f())
            if tip:
                b.setToolTip(f"the selected rows, else the proposal under the mouse with its group ({tip})")
            row.addWidget(b)
        lay.addLayout(row)
        self.proposal_status = QLabel("no proposals yet")
        self.proposal_status.setWordWrap(True)
        lay.addWidget(self.proposal_status)
        # Which lights the night uses (the main window fills and shows this row; hidden in the stand-alone
        # editor): accepting a few proposals otherwise silently replaced all of them in the night.
        self.night_lights_row = QWidget()
        nl = QVBoxLayout(self.night_lights_row)
        nl.setContentsMargins(0, 2, 0, 0)
        nl.setSpacing(1)
        self.night_lights_combo = QComboBox()
        for key, text in NIGHT_LIGHT_RULES:
            self.night_lights_combo.addItem(text, key)
        self.night_lights_combo.setToolTip("which lights the night preview and the export switch on "
                                           "(parameter lights.source)")
        self.night_lights_label = QLabel("")
        self.night_lights_label.setWordWrap(True)
        row = QHBoxLayout()
        row.addWidget(QLabel("Night uses"))
        row.addWidget(self.night_lights_combo, 1)
        nl.addLayout(row)
        nl.addWidget(self.night_lights_label)
        self.night_lights_row.hide()
        lay.addWidget(self.night_lights_row)
        return box

    def propose_lights(self) -> None:
        """Compute light proposals in a worker (Cancel stops waiting for them)."""
        s = self.session
        if self.proposal_source is not None:
            try:
                fn = self.proposal_source()
            except NpsimInputError as exc:
                self.show_message(str(exc))
                return
        elif s.labels is None:
            self.show_message("proposals need the image's semantic labels")
            return
        else:
            from npsim_core.proposals import propose_lights

            image, labels = s.image, s.labels

            def fn():
                return propose_lights(image, labels)
        generation = id(s.ann)
        self.side_tabs.setCurrentWidget(self.proposals_box)  # where the proposals and their status appear
        self.proposal_status.setText("proposing…")
        # the book (pixel lists and the overlay: full-frame passes) is built in the worker too
        self.proposal_jobs.submit(lambda cancel, progress: (ProposalBook(fn()), generation))

    def _on_proposal_busy(self, busy: bool) -> None:
        self.propose_cancel.setEnabled(busy)
        self.propose_btn.setEnabled(not busy)
        if busy:
            self.proposal_status.setText("proposing…")  # also when a new request replaced a cancelled one
        elif self.proposal_status.text() == "proposing…":
            self.proposal_status.setText("cancelled" if self.proposal_book is None else self._proposal_summary())

    def _proposal_failed(self, message: str) -> None:
        self.proposal_status.setText(f"proposals failed: {message}")

    def _on_proposals(self, payload) -> None:
        book, _generation = payload
        if book.proposals.annotation.shape != self.session.ann.shape:
            return  # proposals of an image that is no longer open
        self.set_proposals(book)

    def set_proposals(self, proposals) -> None:
        """Show ``proposals`` (``npsim_core.proposals.LightProposals`` of this image, or a
        :class:`ProposalBook` of them) as the proposal layer."""
        self.proposal_book = proposals if isinstance(proposals, ProposalBook) else ProposalBook(proposals)
        self._proposal_layer_set = False
        self.refresh_proposals()

    def clear_proposals(self) -> None:
        self.proposal_jobs.cancel()
        self.proposal_book = None
        self.canvas.set_layer("proposals", np.zeros((1, 1, 4), np.uint8))
        self.canvas.set_layer_visible("proposals", False)  # an empty full-size layer still costs every repaint
        if hasattr(self, "proposal_tree"):
            self.proposal_tree.clear()
            self.proposal_status.setText("no proposals yet")

    def _existing_ids(self) -> set[int]:
        return self.session.existing_ids()

    def pending_proposals(self) -> list[int]:
        """Proposal light ids still to decide on."""
        book = self.proposal_book
        return book.pending(self._existing_ids()) if book is not None else []

    def _proposal_summary(self, existing: set[int] | None = None) -> str:
        book = self.proposal_book
        existing = self._existing_ids() if existing is None else existing
        n = len(book.light_ids)
        pend = len(book.pending(existing))
        acc = sum(1 for p in book.light_ids if book.accepted.get(p) in existing)
        return f"{pend} of {n} proposals pending · {acc} accepted · {len(book.rejected)} rejected"

    def refresh_proposals(self) -> None:
        """Redraw the proposal layer and list (after proposals, an accept/reject, or an undo): only the
        pixels of the proposals whose state changed are redrawn (:meth:`ProposalBook.sync_overlay`)."""
        book = self.proposal_book
        if book is None:
            return
        existing = self._existing_ids()
        pending = book.pending(existing)
        rect = book.sync_overlay(pending)
        layer = self.canvas.layers["proposals"]
        if not getattr(self, "_proposal_layer_set", False) or layer.array is not book.overlay:
            self.canvas.set_layer("proposals", book.overlay)
            self._proposal_layer_set = True
        elif rect is not None:
            layer.update_rect(rect)
        self.canvas.set_layer_visible("proposals", self.proposal_box.isChecked() and bool(pending))
        tree = self.proposal_tree
        tree.clear()
        pend = set(pending)
        ann = book.proposals.annotation
        role = Qt.ItemDataRole.UserRole
        for gid, g in sorted(ann.groups.items()):
            members = [m for m in g.members if m in pend]
            if not members:
                continue
            top = QTreeWidgetItem([f"{light_class(class_of(gid)).name} {gid} ({len(members)})",
                                   f"{book.confidence(gid):.2f}"])
            top.setData(0, role, ("group", gid))
            for m in members:
                it = QTreeWidgetItem([f"{light_class(class_of(m)).name} {m}", f"{book.confidence(m):.2f}"])
                it.setData(0, role, ("light", m))
                top.addChild(it)
            tree.addTopLevelItem(top)
        for m in pending:
            if m not in book.group_of:
                it = QTreeWidgetItem([f"{light_class(class_of(m)).name} {m}", f"{book.confidence(m):.2f}"])
                it.setData(0, role, ("light", m))
                tree.addTopLevelItem(it)
        self.proposal_status.setText(self._proposal_summary(existing))

    def _proposal_targets(self) -> tuple[list[int], list[int]]:
        """(lights, groups): the rows selected in the proposal list, else the proposal under the mouse
        with its whole group."""
        book = self.proposal_book
        if book is None:
            return [], []
        lights, groups = [], []
        for it in self.proposal_tree.selectedItems():
            kind, pid = it.data(0, Qt.ItemDataRole.UserRole)
            (groups if kind == "group" else lights).append(int(pid))
        if lights or groups:
            return lights, groups
        x, y = self._hover_xy
        H, W = self.session.ann.shape
        if 0 <= x < W and 0 <= y < H:
            pid = book.at(x, y, self._existing_ids())
            if pid:
                return book.expand(pid)
        return [], []

    def accept_proposals(self, lights=None, groups=None) -> list[int]:
        """Accept proposal ``lights`` / ``groups`` (default: :meth:`_proposal_targets`) as one undo step;
        returns the new light ids."""
        if self.proposal_book is None:
            return []
        if lights is None and groups is None:
            lights, groups = self._proposal_targets()
        new = self._safe_result(lambda: self.proposal_book.accept(self.session, lights or [], groups or []))
        self.show_message(f"accepted {len(new)} proposed lights" if new else
                          "no pending proposal selected or under the mouse")
        self.refresh_proposals()
        return new

    def accept_proposals_above(self, threshold: float | None = None) -> list[int]:
        """Accept every pending proposal with confidence >= ``threshold`` (default: the slider)."""
        if self.proposal_book is None:
            return []
        t = self.confidence_slider.value() / 100 if threshold is None else float(threshold)
        new = self._safe_result(lambda: self.proposal_book.accept_above(self.session, t))
        self.show_message(f"accepted {len(new)} proposed lights with confidence ≥ {t:.2f}")
        self.refresh_proposals()
        return new

    def reject_proposals(self, lights=None, groups=None) -> None:
        """Reject proposal ``lights`` / the lights of ``groups`` (default: :meth:`_proposal_targets`)."""
        book = self.proposal_book
        if book is None:
            return
        if lights is None and groups is None:
            lights, groups = self._proposal_targets()
        book.reject(list(lights or []) + [m for g in groups or [] for m in book.proposals.ids_in_group(g)])
        self.refresh_proposals()

    def reject_all_proposals(self) -> None:
        if self.proposal_book is not None:
            self.proposal_book.reject(self.pending_proposals())
            self.refresh_proposals()

    def _safe_result(self, fn):
        try:
            return fn()
        except NpsimInputError as exc:
            self.show_message(str(exc))
            return []

    def _on_hover(self, x: int, y: int) -> None:
        self._hover_xy = (x, y)
        if x < 0:
            return
        iid = self.session.instance_at(x, y)
        what = f"{light_class(class_of(iid)).name} {iid}" if iid else "no light"
        win = self.window()
        if isinstance(win, QMainWindow):
            win.statusBar().showMessage(f"({x}, {y}) {what}")

    def _on_brush(self, v: int) -> None:
        self.options.brush_radius = float(v)
        if self.controller.tool in (Tool.BRUSH, Tool.ERASER):
            self.canvas.set_brush_radius(v)
