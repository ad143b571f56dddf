"""The NPSim main window: annotation canvas with view modes, parameter panel,
3D mesh viewer, night render preview, loss curve and a log strip.

Everything computed comes from :class:`npsim_core.chain.Chain` in worker
threads (:mod:`npsim_gui.workers`); this module only presents and edits.
"""

from __future__ import annotations

import threading
import time
from dataclasses import replace
from pathlib import Path

import cv2

from PySide6.QtCore import QEvent, QEventLoop, QObject, QSettings, Qt, QTimer, Signal
from PySide6.QtGui import QAction, QKeySequence
from PySide6.QtWidgets import (QAbstractSpinBox, QApplication, QComboBox, QDockWidget, QFileDialog, QHBoxLayout,
                               QLabel, QLineEdit, QListWidget, QMainWindow, QMessageBox, QProgressDialog,
                               QToolButton, QVBoxLayout, QWidget)

from npsim_core.annotation import annotation_paths, find_recovery, load_recovery
from npsim_core.errors import NpsimCancelled, NpsimInputError
from npsim_core.scene import Scene
from npsim_core.chain import Chain, ChainParams
from npsim_core.chain.session import frame_annotation_files, scene_annotation_files
from npsim_core.memory import release_free_memory
from npsim_core.views import VIEW_MODES, view_image

from .editor.editor import AnnotationEditor
from .editor.shortcuts import keys as keymap_keys
from .param_values import gui_values, with_gui_value
from .params_panel import ParameterPanel
from .render_panel import RenderPanel
from .viewer3d import MeshViewer, build_display
from .warmup import warm_up
from .widgets import LogStrip, LossPlot
from .workers import JobChannel

ORG, APP = "NPSim", "NPSim"


class _Done(QObject):
    """Tells the GUI thread that a background load ended (queued: emitted from the loader thread)."""

    done = Signal()


def _display_mesh(chain: Chain, res, budget: int, params: ChainParams):
    """``chain.display_mesh`` held to ``budget`` faces (+10 %): the reduction may land up to 1.5 times
    over its target (81-108 k faces for 60 k on real frames), so the target is lowered until it fits."""
    target, shown = budget, chain.display_mesh(res, max_faces=budget, params=params)
    for _ in range(3):
        if shown is None or shown.n_faces <= 1.1 * budget:
            break
        target = max(1000, int(target * budget / shown.n_faces * 0.95))
        shown = chain.display_mesh(res, max_faces=target, params=params)
    return shown


def _copy_export(files: list[Path], folder: Path, cancel: threading.Event, progress) -> list[Path]:
    """Copy an earlier export's ``files`` into ``folder`` (manifest last, as the writer does)."""
    import shutil

    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k, src in enumerate(files):
        if cancel.is_set():
            raise NpsimCancelled("export cancelled")
        progress((k / max(len(files), 1), f"copying {src.name}"))
        dst = folder / src.name
        if src.resolve() != dst.resolve():
            shutil.copy2(src, dst)
        out.append(dst)
    return out


class MainWindow(QMainWindow):
    """Main application window for one scene at a time."""

    def __init__(self, scene: Scene | None = None, *, with_3d: bool = True):
        super().__init__()
        warm_up()  # the workers' first imports would hold the GIL (freeze the window) after the first open
        self.setWindowTitle("NPSim")
        self.resize(1680, 1020)
        self.chain: Chain | None = None
        self.proxy_chain: Chain | None = None
        self.params = ChainParams()
        self.results = None
        self.light_override: dict[int, bool] | None = None
        self._t_change = 0.0
        self.last_latency: dict[str, float] = {}
        self.pipeline_jobs = JobChannel("pipeline", debounce_ms=60, parent=self)
        self.render_jobs = JobChannel("render", debounce_ms=100, parent=self, one_at_a_time=True)
        self.export_jobs = JobChannel("export", parent=self)
        self.view_jobs = JobChannel("view", parent=self)
        self._loading = False  # a frame is being read in the background (see _in_background)
        self._closed = False
        self._build_ui(with_3d)
        self._build_menus()
        self._connect()
        self._fit_screen()
        self._restore_layout()
        self._show_params()  # the defaults, never the sliders' minimums, before a frame is open
        if scene is not None:
            self.set_scene(scene)

    # ----------------------------------------------------------------- layout
    def _build_ui(self, with_3d: bool) -> None:
        central = QWidget()
        lay = QVBoxLayout(central)
        lay.setContentsMargins(2, 2, 2, 2)
        bar = QHBoxLayout()
        bar.addWidget(QLabel("View:"))
        self.view_mode = QComboBox()
        self.view_mode.addItems(VIEW_MODES)
        bar.addWidget(self.view_mode)
        # what runs (or why nothing does) sits in the status bar beside Cancel, where its whole text fits
        self.busy_label = QLabel("")
        bar.addStretch(1)
        lay.addLayout(bar)
        self.editor = AnnotationEditor(self)
        lay.addWidget(self.editor, 1)
        self.setCentralWidget(central)

        self.params_panel = ParameterPanel()
        self.params_panel.setMinimumWidth(250)
        self.params_dock = self._dock("Parameters", self.params_panel, Qt.DockWidgetArea.LeftDockWidgetArea)
        self.viewer = MeshViewer() if with_3d else None
        if self.viewer is not None:
            self.viewer_dock = self._dock("3D mesh", self.viewer, Qt.DockWidgetArea.RightDockWidgetArea)
        self.render_panel = RenderPanel()
        self.render_dock = self._dock("Night preview", self.render_panel, Qt.DockWidgetArea.RightDockWidgetArea)
        bottom = QWidget()
        bl = QHBoxLayout(bottom)
        bl.setContentsMargins(0, 0, 0, 0)
        self.loss_plot = LossPlot()
        self.log = LogStrip()
        bl.addWidget(self.loss_plot, 1)
        bl.addWidget(self.log, 1)
        self.log_dock = self._dock("Loss and log", bottom, Qt.DockWidgetArea.BottomDockWidgetArea)
        self.frame_list = QListWidget()
        self.frame_list.currentRowChanged.connect(self.open_frame)
        self.frames_dock = self._dock("Frames", self.frame_list, Qt.DockWidgetArea.LeftDockWidgetArea)
        self.tabifyDockWidget(self.params_dock, self.frames_dock)
        self.params_dock.raise_()
        self.frames_dock.hide()  # shown when a dataset is opened; fit_to arranges the docks for the screen

    def _dock(self, title: str, widget: QWidget, area) -> QDockWidget:
        d = QDockWidget(title, self)
        d.setObjectName(title.replace(" ", "_"))
        d.setWidget(widget)
        self.addDockWidget(area, d)
        return d

    def _build_menus(self) -> None:
        m = self.menuBar().addMenu("&File")
        self.act_open_scene = self._action(m, "Open scene folder…", "open_scene", self.open_scene_dialog)
        self.act_open_image = self._action(m, "Open dataset image…", "open_image", self.open_image_dialog)
        self.act_open_dataset = self._action(m, "Open dataset…", "open_dataset", self.open_dataset_dialog)
        self.act_next = self._action(m, "Next frame", "next_frame", lambda: self.step_frame(+1))
        self.act_prev = self._action(m, "Previous frame", "previous_frame", lambda: self.step_frame(-1))
        self.act_open_project = self._action(m, "Open project…", "open_project", self.open_project_dialog)
        self.act_reopen = self._action(m, "Reopen last scene", "reopen", self.reopen_last)
        m.addSeparator()
        self.act_save_ann = self._action(m, "Save annotation", "save_annotation", self.save_annotation)
        self.act_done = self._action(m, "Frame done", "done", self.toggle_done)
        self.act_done.setCheckable(True)
        self.act_save_project = self._action(m, "Save project…", "save_project", self.save_project_dialog)
        m.addSeparator()
        self.act_export = self._action(m, "Export…", "export", self.export_dialog)
        m.addSeparator()
        self._action(m, "Quit", "quit", self.close)
        r = self.menuBar().addMenu("&Run")
        self._action(r, "Recompute", "recompute", self.recompute)
        self._action(r, "Render night preview", "render", self.render_now)
        # Esc is the editor's "clear selection" too: it cancels when there is nothing to clear
        # (AnnotationEditor.escapeUnused) or when the focus is outside the editor (keyPressEvent)
        self.act_cancel = self._action(r, "Cancel running job (Esc)", "", self.cancel_jobs)
        self.act_cancel.setToolTip("Stop the running computation, night render or export (Esc)")
        self.act_cancel.setEnabled(False)
        self.cancel_btn = QToolButton()
        self.cancel_btn.setDefaultAction(self.act_cancel)
        self.cancel_btn.setText("Cancel")
        self.cancel_btn.setToolButtonStyle(Qt.ToolButtonStyle.ToolButtonTextOnly)
        self.statusBar().addPermanentWidget(self.busy_label)
        self.statusBar().addPermanentWidget(self.cancel_btn)
        v = self.menuBar().addMenu("&View")
        for d in (self.params_dock, self.frames_dock, self.render_dock, self.log_dock) + \
                ((self.viewer_dock,) if self.viewer else ()):
            v.addAction(d.toggleViewAction())
        h = self.menuBar().addMenu("&Help")
        self.editor.keymap_window = "app"
        h.addAction(self.editor.actions_by_name["help"])  # F1: the sheet of this window's keymap
        self.editor.actions_by_name["help"].setShortcutContext(Qt.ShortcutContext.WindowShortcut)
        # frame navigation works wherever the focus is (spin boxes and line edits keep Ctrl+Left/Right)
        self._nav_keys = {QKeySequence(k).toString() for a in (self.act_next, self.act_prev)
                          for k in a.shortcuts()}
        QApplication.instance().installEventFilter(self)

    def _action(self, menu, text: str, action: str, fn) -> QAction:
        """A window action with the keys of ``action`` in the keymap (editor/shortcuts.py)."""
        a = QAction(text, self)
        if action:
            a.setShortcuts(keymap_keys(action, "app"))
        a.triggered.connect(fn)
        menu.addAction(a)
        return a

    def eventFilter(self, obj, event) -> bool:  # noqa: N802 (Qt API)
        # A focused spin box or line edit claims Ctrl+Left/Right (move by word) before the window's
        # shortcuts see them: frame navigation is application-wide, so its keys are not left to them.
        if event.type() == QEvent.Type.ShortcutOverride and self.isActiveWindow() and not self._closed:
            seq = QKeySequence(event.keyCombination()).toString()
            if seq in self._nav_keys and isinstance(obj, (QAbstractSpinBox, QLineEdit)):
                event.ignore()
                return True
        # An application-wide filter also sees a few watched objects that are no QObject to
        # PySide (the 3D view's QSurface with a timer event): the base class would raise there.
        return super().eventFilter(obj, event) if isinstance(obj, QObject) else False

    def toggle_done(self) -> None:
        """Ctrl+D: this frame's 'done' flag (saved in its annotation's JSON)."""
        s = self.editor.session
        s.set_done(not bool(s.ann.meta.get("done", False)))
        self._update_title()

    def _connect(self) -> None:
        self.params_panel.changed.connect(self.on_param_changed)
        self.params_panel.presetChosen.connect(self.on_preset)
        self.params_panel.resetRequested.connect(self.on_reset)
        self.view_mode.currentTextChanged.connect(lambda _t: self.refresh_view())
        self.pipeline_jobs.finished.connect(self.on_pipeline_done)
        self.pipeline_jobs.failed.connect(self.on_error)
        self.pipeline_jobs.progress.connect(self.on_pipeline_progress)
        self.pipeline_jobs.busy.connect(lambda b: self._set_busy("computing…" if b else ""))
        self.view_jobs.finished.connect(self._on_view)
        self.view_jobs.failed.connect(self.on_error)
        self.export_jobs.progress.connect(self._on_export_progress)
        self.export_jobs.finished.connect(self._on_export_done)
        self.export_jobs.failed.connect(self.on_error)
        self.render_jobs.finished.connect(self.on_render_done)
        self.render_jobs.failed.connect(self.on_error)
        self.render_jobs.progress.connect(self.on_render_progress)
        self.render_panel.seedChanged.connect(lambda s: self.on_param_changed("night", "seed", int(s)))
        self.render_panel.denoiserChanged.connect(lambda d: self.on_param_changed("night", "denoiser", str(d)))
        self.render_panel.lightsToggled.connect(self.on_lights_toggled)
        self.render_panel.renderRequested.connect(self.render_now)
        self.render_dock.visibilityChanged.connect(self._on_render_dock_visible)
        self.editor.escapeUnused.connect(self.cancel_jobs)
        self.editor.night_lights_row.show()
        self.editor.night_lights_combo.activated.connect(
            lambda _i: self.on_param_changed("lights", "source", self.editor.night_lights_combo.currentData()))
        self.editor.proposal_source = self._proposal_job
        for ch in (self.pipeline_jobs, self.render_jobs, self.export_jobs, self.view_jobs):
            ch.busy.connect(self._update_cancel)
        self.editor.dirtyChanged.connect(self._update_title)
        self.editor.session.changed.connect(lambda *_: self._annotation_edited())
        self._ann_timer = QTimer(self)  # one night request per pause in the edits, not one per brush dab
        self._ann_timer.setSingleShot(True)
        self._ann_timer.setInterval(150)
        self._ann_timer.timeout.connect(self.request_render)
        # The recovery file is written at most AUTOSAVE_MS after the first unsaved edit, also while edits
        # keep coming (not restarted by each edit: a long session of strokes is never left unsaved).
        self.autosave_timer = QTimer(self)
        self.autosave_timer.setSingleShot(True)
        self.autosave_timer.setInterval(self.AUTOSAVE_MS)
        self.autosave_timer.timeout.connect(self._autosave)
        self.editor.session.changed.connect(
            lambda *_: None if self.autosave_timer.isActive() else self.autosave_timer.start())
        self.editor.session.saved.connect(self._on_saved)
        self.editor.session.autosaved.connect(lambda p: self.log.log(f"unsaved edits kept in {p}"))

    def _set_busy(self, text: str) -> None:
        self.busy_label.setText(text)

    @property
    def jobs_busy(self) -> bool:
        """True while a pipeline, render, export or view job is pending or running."""
        return any(ch.is_busy for ch in (self.pipeline_jobs, self.render_jobs, self.export_jobs, self.view_jobs))

    def _update_cancel(self, *_a) -> None:
        busy = self.jobs_busy
        self.act_cancel.setEnabled(busy)
        if not busy and getattr(self, "_cancelling", False):
            self._cancelling = False
            self._set_busy("cancelled — F5 recomputes, F6 renders")
            if self.render_panel.status.text() == "rendering…":
                self.render_panel.status.setText("render cancelled — F6 renders")
        dlg = getattr(self, "_export_dialog", None)
        if dlg is not None and not self.export_jobs.is_busy:
            dlg.reset()  # a cancelled or failed export never leaves its dialog up

    def cancel_jobs(self) -> None:
        """Stop every running job (Cancel button, Esc); the views keep what they show."""
        if not self.jobs_busy:
            return
        self._set_busy("cancelling…")
        self._cancelling = True
        for ch in (self.pipeline_jobs, self.render_jobs, self.export_jobs, self.view_jobs):
            ch.cancel()
        self.log.log("cancelled by the user")
        self._update_cancel()

    def keyPressEvent(self, event) -> None:  # noqa: N802 (Qt API)
        if event.key() == Qt.Key.Key_Escape and self.jobs_busy:
            self.cancel_jobs()
            return
        super().keyPressEvent(event)

    # ----------------------------------------------------------------- scene
    @classmethod
    def chains_for(cls, scene: Scene) -> tuple[Chain, Chain | None]:
        """The chain of ``scene`` and, for a frame wider than :attr:`PROXY_WIDTH`, the proxy chain of
        its quick views. Pure data work (hashing the frame, resampling the proxy): a background
        load builds them in its thread."""
        # a full-resolution result set of a large frame is hundreds of MB per stage: keep fewer
        chain = Chain(scene, cache_size=2 if scene.width * scene.height > cls.LARGE_FRAME_PX else 4)
        proxy = None
        if scene.width > cls.PROXY_WIDTH * 1.25:
            from npsim_core.chain import scaled_frame

            proxy = Chain(scaled_frame(scene, cls.PROXY_WIDTH / scene.width))
        return chain, proxy

    def set_scene(self, scene: Scene, params: ChainParams | None = None, *,
                  chains: tuple[Chain, Chain | None] | None = None) -> None:
        """Show ``scene`` and start computing its pipeline (``chains``: from :meth:`chains_for`,
        when a background load built them already)."""
        self.pipeline_jobs.cancel()
        self.render_jobs.cancel()
        self.chain = None  # the previous frame's results go before the next frame's are computed
        self.results = None
        self.chain, self.proxy_chain = chains if chains is not None else self.chains_for(scene)
        if params is not None:
            self.params = params
        self.results = None
        self.light_override = None
        self.render_panel.clear_night()
        if self.viewer is not None:
            self.viewer.clear()  # the last frame's display meshes and image go with its results
        self._export_cache = None  # (it names the last frame's files)
        where = scene_annotation_files(scene)
        folder, stem = where if where is not None else (None, scene.name)
        ann, dirty = scene.lights, False
        # the frame and its parameters are on screen before any question is asked about them
        self._show_params()
        self.editor.show_image(scene.image)
        rec = find_recovery(folder, stem) if folder else None
        if rec is not None:
            choice = self.ask("Recover unsaved edits", f"{scene.name}: the last session ended without saving its "
                              "light annotation. Restore the unsaved edits?", ["Restore", "Discard"])
            if choice == "Restore":
                try:
                    ann, dirty = load_recovery(rec), True
                except NpsimInputError as exc:
                    self.on_error(str(exc), "")
            else:
                rec.unlink(missing_ok=True)
        if ann is not None and ann.shape != (scene.height, scene.width):
            self.on_error(f"{rec}: the recovered annotation is {ann.shape[1]}x{ann.shape[0]}, the frame "
                          f"{scene.width}x{scene.height}; not used", "")
            ann, dirty = scene.lights, False
        self.editor.load(scene.image, scene.labels, ann, folder=folder, stem=stem, dirty=dirty,
                         instances=scene.instances)
        self._rule_had_lights = bool(self.editor.session.existing_ids())
        self._show_night_rule()
        if ann is not scene.lights:
            self.chain.set_annotation(ann)
        self._ann_version = self._ann_applied = 0
        self.render_panel.set_day(scene.image)
        self.render_panel.seed.blockSignals(True)
        self.render_panel.seed.setValue(self.params.night.seed)
        self.render_panel.seed.blockSignals(False)
        self._update_title()
        self.log.log(f"scene {scene.name}: {scene.width}x{scene.height}"
                     + (" (with ground truth)" if scene.depth_gt is not None else ""))
        src = scene.provenance.get("folder") or scene.provenance.get("image")
        if src:
            QSettings(ORG, APP).setValue("last_scene", str(src))
        self.recompute()

    def _show_params(self) -> None:
        values = gui_values(self.params)
        if self.chain is not None and not values.get(("camera", "hfov_deg")):
            # 0 means "the scene's own intrinsics": show the field of view they imply
            values[("camera", "hfov_deg")] = self.chain.scene.intrinsics.hfov_deg
        self.params_panel.set_values(values)
        self.render_panel.set_denoiser(self.params.night.denoiser)
        self._show_night_rule()

    def _show_night_rule(self) -> None:
        """The Proposals box says which lights the night uses now, by the rule chosen (lights.source)."""
        lp = self.params.lights
        combo = self.editor.night_lights_combo
        k = combo.findData(lp.source)
        if k >= 0 and combo.currentIndex() != k:
            combo.setCurrentIndex(k)
        n = len(self.editor.session.existing_ids())
        thr = f"≥ {lp.min_confidence:.2f}"
        text = {"auto": (f"now: the {n} annotated lights (proposals are used only while no light is annotated)"
                         if n else f"now: every proposal {thr} (until a light is annotated or accepted)"),
                "annotation": f"now: the {n} annotated lights" + ("" if n else " — no light sources"),
                "proposed": f"now: every proposal {thr}, the annotation ignored",
                "none": "now: no light sources (ego headlights and sky only)",
                "file": f"now: the annotation in {lp.file}"}.get(lp.source, lp.source)
        self.editor.night_lights_label.setText(text)
        if lp.source == "auto" and n and not getattr(self, "_rule_had_lights", False):
            self.statusBar().showMessage(f"the night now uses only the {n} annotated lights, not every proposal: "
                                         "'Night uses' in the Proposals box chooses", 8000)
        self._rule_had_lights = bool(n)

    def _update_title(self, *_a) -> None:
        name = self.chain.scene.name if self.chain else "no scene"
        done = bool(self.editor.session.ann.meta.get("done"))
        self.act_done.setChecked(done)
        dirty = " *" if self.editor.session.is_dirty else ""
        self.setWindowTitle(f"NPSim — {name}{' (done)' if done else ''}{dirty}")

    # ----------------------------------------------------------------- parameters
    def on_param_changed(self, section: str, field: str, value) -> None:
        try:
            self.params = with_gui_value(self.params, section, field, value)
        except NpsimInputError as exc:
            self.on_error(str(exc), "")
            return
        self._t_change = time.perf_counter()
        if section == "lights":
            self._show_params()  # the panel's and the Proposals box's choices agree
        self.recompute()

    def on_preset(self, name: str) -> None:
        self.params = self.params.with_preset(name)
        self._show_params()
        self._t_change = time.perf_counter()
        self.recompute()

    def on_reset(self) -> None:
        seed = self.params.night.seed
        self.params = ChainParams().with_value("night", "seed", seed)
        self._show_params()
        self._t_change = time.perf_counter()
        self.recompute()

    def _annotation_edited(self) -> None:
        """An edit only changes the lights: the depth, normal and 3D views stay as they are (the mesh is
        never rebuilt for it); the night scene updates the shapes of the lights it touched when the
        night preview is shown (else when it is shown next)."""
        self._show_night_rule()
        if self.chain is not None:
            # never chain.set_annotation here: it waits for the chain's lock, which a running job holds
            # (seconds on a large frame); the next job applies a snapshot (_annotation_for_job)
            self._ann_version = getattr(self, "_ann_version", 0) + 1
            self._ann_timer.start()

    def _annotation_for_job(self):
        """A function for a worker that hands the chain the editor's annotation as it is now (a copy: the
        editor keeps editing its own), or does nothing when the chain already has it."""
        version = getattr(self, "_ann_version", 0)
        if version == getattr(self, "_ann_applied", 0):
            return lambda chain: None
        snapshot = self.editor.session.ann.copy()

        def apply(chain) -> None:
            if version > getattr(self, "_ann_applied", 0):
                chain.set_annotation(snapshot)
                self._ann_applied = version
        return apply

    def _proposal_job(self):
        """The editor's "Propose lights" on this frame: with its camera and the best depth at hand
        (ground truth, stereo, else the chain's refined depth)."""
        from npsim_core.proposals import propose_for_scene

        if self.chain is None:
            raise NpsimInputError("open a frame first (File > Open…)")
        scene = self.chain.scene
        depth = self.results.depth if self.results is not None else None
        return lambda: propose_for_scene(scene, depth=depth)

    def night_preview_shown(self) -> bool:
        """True when the night preview is on screen (its dock open and, if tabbed, the current tab)."""
        # a dock behind another tab stays "visible" (moved off-screen): its visible region is empty
        return self.render_dock.isVisible() and not self.render_dock.visibleRegion().isEmpty()

    def _on_render_dock_visible(self, visible: bool) -> None:
        if visible and getattr(self, "_night_stale", False):
            QTimer.singleShot(0, self.request_render)  # after the dock is laid out

    #: Wall-clock budget of the quick refinement shown first after a change (s); the full
    #: refinement follows in the same worker and replaces it when done.
    LIVE_REFINE_BUDGET_S = 0.15
    #: Frames with more pixels than this keep 2 cached results per stage instead of 4 (memory).
    LARGE_FRAME_PX = 1_000_000
    #: Frames wider than this get a proxy chain at this width for the quick views.
    PROXY_WIDTH = 512
    #: The full-resolution chain starts this long after the last change on a proxied frame.
    FULL_RES_SETTLE_S = 0.8
    #: Face budget of the 3D view's mesh (``Chain.display_mesh``): llvmpipe draws every face on each
    #: repaint (~0.45 us a face on 2 loaded cores). At 2048x1024 this gives 71 k faces on a third-
    #: resolution grid (683 columns: more than the ~530-px-wide 3D dock shows) instead of 155 k at
    #: half resolution, whose repaint took 87-170 ms while the night rendered.
    DISPLAY_FACES = 60_000

    def recompute(self) -> None:
        """Run the pipeline up to the mesh in a worker (stale runs are cancelled).

        Two phases: a quick refinement with a time budget (shown at once), then the full
        refinement (shown when done), so a slider answers in well under a second.
        """
        if self.chain is None:
            return
        chain, params, proxy = self.chain, self.params, self.proxy_chain
        apply_ann = self._annotation_for_job()
        t0 = self._t_change or time.perf_counter()
        live = None
        if params.refine.optimizer == "fast" and params.refine.max_time_s is None:
            live = replace(params, refine=replace(params.refine, max_time_s=self.LIVE_REFINE_BUDGET_S))
        settle = self.FULL_RES_SETTLE_S if proxy is not None and self.results is not None else 0.0

        mode = self.view_mode.currentText()
        with_3d = self.viewer is not None
        display_faces = self.DISPLAY_FACES

        def job(cancel: threading.Event, progress):
            # everything heavy happens here, off the GUI thread: stages, view images, 3D geometry
            apply_ann(chain)
            if live is not None:
                # large frames answer from a proxy resolution at once; the full resolution follows
                # once the sliders have settled (a newer change cancels this job first)
                src = proxy if proxy is not None else chain
                quick = src.compute(live, until="refine", cancel=cancel, progress=progress)
                if "refine" in quick.recomputed or proxy is not None:
                    view = view_image(src.scene, quick, mode)
                    if proxy is not None:
                        view = cv2.resize(view, (chain.scene.width, chain.scene.height),
                                          interpolation=cv2.INTER_LINEAR)
                    progress({"live_results": quick, "t0": t0, "view": view, "mode": mode,
                              "proxy": proxy is not None})
                if settle and cancel.wait(settle):
                    raise NpsimCancelled("superseded by a newer change")
            res = chain.compute(params, until="mesh", cancel=cancel, progress=progress)
            display = None
            if with_3d and res.mesh is not None:
                fields = {k: v for k, v in (("uncertainty", res.uncertain), ("error", res.depth_error()))
                          if v is not None}
                display = build_display(_display_mesh(chain, res, display_faces, params), chain.scene.image,
                                        removed=res.removed, fields=fields, fy=res.intrinsics.fy)
            return res, t0, display, view_image(chain.scene, res, mode), mode
        self.pipeline_jobs.submit(job)

    def on_pipeline_progress(self, info) -> None:
        if isinstance(info, dict) and "live_results" in info:
            self._show_results(info["live_results"], info["t0"], final=False, view=(info["mode"], info["view"]),
                               proxy=info.get("proxy", False))
        elif isinstance(info, dict) and "history" in info:
            self.loss_plot.set_history(info["history"])
        elif isinstance(info, dict) and "stage" in info:
            self._set_busy(f"computing {info['stage']}…")

    def on_pipeline_done(self, payload) -> None:
        res, t0, display, view, mode = payload
        self._show_results(res, t0, final=True, display=display, view=(mode, view))

    def _show_results(self, res, t0: float, *, final: bool, display=None, view=None, proxy: bool = False) -> None:
        if not proxy:  # proxy results are shown, never kept: they are not at the frame's resolution
            self.results = res
        self.results_final = final
        lat = time.perf_counter() - t0
        self.last_latency["pipeline" if final else "pipeline_live"] = lat
        what = "recomputed" if final else f"quick preview ({self.LIVE_REFINE_BUDGET_S:g} s refinement budget" + \
            (f", {res.intrinsics.width}x{res.intrinsics.height} proxy)" if proxy else ")")
        self.log.log(f"{what}: " + ", ".join(f"{k} {v * 1000:.0f} ms" for k, v in res.timings.items()
                                             if k in res.recomputed) + f" — change→view {lat:.2f} s")
        if "geometry" in res.recomputed:
            self.log.log(f"depth from {res.depth_source}")
        if res.refine is not None:
            self.loss_plot.set_history(res.refine_history())
            if final and res.refine.diverged:
                self.log.log(f"warning: the refinement diverged: {res.refine.message}")
        if view is not None and view[0] == self.view_mode.currentText():
            self.editor.set_base_image(view[1])
        else:
            self.refresh_view()
        if not final:
            return  # the quick result updates the 2D views; the mesh and the night follow the full one
        if self.viewer is not None and display is not None:
            self.viewer.set_display(display)
            if display.mesh is not res.mesh:
                self.log.log(f"3D view shows a {display.mesh.n_faces:,}-face reduction of the "
                             f"{res.mesh.n_faces:,}-face mesh")
        force, self._render_after_compute = getattr(self, "_render_after_compute", False), False
        self.request_render(force=force)

    def refresh_view(self) -> None:
        """Recompute the canvas image for the current view mode (in a worker)."""
        if self.chain is None:
            return
        scene, res, mode = self.chain.scene, self.results, self.view_mode.currentText()
        self.view_jobs.submit(lambda cancel, progress: (mode, view_image(scene, res, mode)))

    def _on_view(self, payload) -> None:
        mode, img = payload
        if mode == self.view_mode.currentText():
            self.editor.set_base_image(img)

    # ----------------------------------------------------------------- night
    def on_lights_toggled(self, state: dict) -> None:
        self.light_override = dict(state)
        self.request_render()

    def render_now(self) -> None:
        """F6 / the Render button: the night preview now, computing the mesh first when there is none
        yet (e.g. after the computation was cancelled)."""
        if self.chain is None:
            return
        if self.results is None or self.results.mesh is None or not getattr(self, "results_final", True):
            self._render_after_compute = True
            if not self.pipeline_jobs.is_busy:
                self.recompute()
            self._set_busy("computing the mesh, then the night…")
            return
        self.request_render(force=True)

    def request_render(self, force: bool = False) -> None:
        """Render the night preview in a worker; skipped (and remembered) while the preview is hidden,
        unless ``force`` (F6, the Render button)."""
        if self.chain is None or self.results is None or self.results.mesh is None \
                or not getattr(self, "results_final", True):
            return
        if not force and not self.night_preview_shown():
            self._night_stale = True
            return
        self._night_stale = False
        chain, params, res, override = self.chain, self.params, self.results, self.light_override
        apply_ann = self._annotation_for_job()
        t0 = self._t_change or time.perf_counter()

        def job(cancel: threading.Event, progress):
            apply_ann(chain)
            last = None
            for frame in chain.night_preview(res, params, light_override=override, cancel=cancel):
                progress(frame)
                last = frame
                release_free_memory()  # the scene build's temporaries, before the next (longer) pass
            return last, t0
        self.render_panel.status.setText("rendering…")
        self.render_jobs.submit(job)

    def on_render_progress(self, frame) -> None:
        if frame is None:
            return
        self.render_panel.set_night(frame.image, f"{frame.spp} spp · {frame.elapsed:.2f} s · {frame.variant}",
                                    realism=getattr(frame, "realism", None))
        if frame.active is not None and self.light_override is None:
            self._fill_lights(frame)

    def on_render_done(self, payload) -> None:
        frame, t0 = payload
        if frame is None:
            return
        self.last_latency["render"] = time.perf_counter() - t0
        self._t_change = 0.0
        self.on_render_progress(frame)
        self.log.log(f"night preview {frame.spp} spp in {frame.elapsed:.2f} s ({frame.variant}); "
                     f"{len(frame.active.on_ids) if frame.active else 0} lights on")

    def _fill_lights(self, frame) -> None:
        """The night panel's light list: the lights this night used (annotated or proposed)."""
        ann, active = frame.annotation, frame.active
        if ann is None:
            return
        grouped = {m for g in ann.groups.values() for m in g.members}
        groups = {gid: list(g.members) for gid, g in ann.groups.items()}
        singles = [i for i in ann.instance_ids() if i not in grouped]
        state = {i: st.on for i, st in active.lights.items()}
        if state == getattr(self, '_filled_state', None):
            return
        self._filled_state = state
        self.render_panel.set_lights(groups, singles, state)

    # ----------------------------------------------------------------- files
    def open_scene_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open scene folder")
        if folder:
            self.open_scene(folder)

    def open_image_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Open a dataset image (its labels are found by name)", "",
                                              "Images (*.png *.jpg *.jpeg)")
        if path:
            self.open_scene(path)

    def open_dataset_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open a dataset root (Cityscapes, ACDC, a folder of frames)")
        if folder:
            self.open_dataset(folder)

    def open_dataset(self, root: str | Path) -> None:
        """List the frames of a dataset root in the Frames dock and open the first."""
        from npsim_core.chain import iter_frames

        try:
            frames = iter_frames(root)
        except (NpsimInputError, OSError) as exc:
            self.on_error(str(exc), "")
            return
        if not self.leave_frame("open the dataset"):
            return
        self.frames = frames
        self.frame_list.blockSignals(True)
        self.frame_list.clear()
        for f in frames:
            p = Path(f.path)
            # a frame's annotation: inside its scene folder, else where frame_annotation_files puts it
            if p.is_dir():
                done = any(p.glob("*_lights.json"))
            else:
                done = annotation_paths(*frame_annotation_files(p))["json"].exists()
            self.frame_list.addItem(("✓ " if done else "   ") + f.name)
        self.frame_list.blockSignals(False)
        if self.frames_dock.isHidden():
            self.frames_dock.show()
            if not getattr(self, "_narrow", True):
                self.resizeDocks([self.params_dock, self.frames_dock], [600, 160], Qt.Orientation.Vertical)
        self.log.log(f"dataset {root}: {len(frames)} frames (✓ = annotated); Ctrl+Right / Ctrl+Left step through them")
        self.open_frame(0, asked=True)

    def open_frame(self, index: int, *, asked: bool = False) -> None:
        """Open frame ``index`` of the dataset (after asking about unsaved edits unless ``asked``)."""
        frames = getattr(self, "frames", [])
        if not 0 <= index < len(frames):
            return
        if self._loading:
            return
        if not asked and not self.leave_frame():
            self.frame_list.blockSignals(True)  # stay: the list keeps showing the frame that is open
            self.frame_list.setCurrentRow(getattr(self, "frame_index", -1))
            self.frame_list.blockSignals(False)
            return
        try:
            scene, chains = self._load(frames[index].load, frames[index].name)
        except (NpsimInputError, OSError) as exc:
            self.on_error(f"{frames[index].name}: {exc}", "")
            return
        if self._closed:
            return
        self.frame_index = index
        self.frame_list.blockSignals(True)
        self.frame_list.setCurrentRow(index)
        self.frame_list.blockSignals(False)
        self.set_scene(scene, chains=chains)

    def step_frame(self, delta: int) -> None:
        if getattr(self, "frames", None):
            self.open_frame(min(max(getattr(self, "frame_index", 0) + delta, 0), len(self.frames) - 1))

    def open_scene(self, path: str | Path) -> None:
        """Open a scene folder, project folder or dataset image (read in the background; returns
        when the frame is shown)."""
        from npsim_core.chain import load_frame

        if self._loading or not self.leave_frame():
            return
        try:
            scene, chains = self._load(lambda: load_frame(path), Path(path).name)
        except (NpsimInputError, OSError) as exc:
            self.on_error(str(exc), "")
            return
        if not self._closed:
            self.set_scene(scene, chains=chains)

    def _load(self, read, name: str, scene_of=lambda value: value):
        """``(read(), chains)``: what ``read`` returns and the chains of its scene (``scene_of(value)``),
        computed in a thread while the window stays live."""
        def job():
            value = read()
            chains = self.chains_for(scene_of(value))
            release_free_memory()  # the decoders' temporaries
            return value, chains
        self._set_busy(f"opening {name}…")
        try:
            return self._in_background(job)
        finally:
            self._set_busy("")

    def _in_background(self, fn):
        """Run ``fn()`` in a thread and return its result (or raise its exception); meanwhile the
        event loop keeps running, so a large frame's decoding and hashing (0.2-0.4 s at 2048x1024)
        never freezes the window. Opening again meanwhile is ignored (:attr:`_loading`)."""
        box: dict = {}
        sig = _Done()
        loop = QEventLoop()
        sig.done.connect(loop.quit, Qt.ConnectionType.QueuedConnection)

        def run() -> None:
            try:
                box["value"] = fn()
            except BaseException as exc:  # handed to the caller on the GUI thread
                box["error"] = exc
            finally:
                sig.done.emit()
        self._loading = True
        for a in (self.act_open_scene, self.act_open_image, self.act_open_dataset, self.act_next, self.act_prev,
                  self.act_open_project, self.act_reopen):
            a.setEnabled(False)
        try:
            t = threading.Thread(target=run, name="npsim-open", daemon=True)
            t.start()
            loop.exec()
            t.join()
        finally:
            self._loading = False
            for a in (self.act_open_scene, self.act_open_image, self.act_open_dataset, self.act_next, self.act_prev,
                      self.act_open_project, self.act_reopen):
                a.setEnabled(True)
        if "error" in box:
            raise box["error"]
        return box["value"]

    def reopen_last(self) -> None:
        """Open the scene (or project) folder opened last time, remembered across runs."""
        last = QSettings(ORG, APP).value("last_scene")
        if not last:
            self.on_error("no scene folder was opened before", "")
            return
        self.open_scene(last)

    def open_project_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open project folder")
        if folder:
            self.open_project(folder)

    def open_project(self, folder: str | Path) -> None:
        from npsim_core.chain.project import load_project

        if self._loading or not self.leave_frame("open the project"):
            return
        try:
            (scene, params), chains = self._load(lambda: load_project(folder), Path(folder).name,
                                                 scene_of=lambda v: v[0])
        except (NpsimInputError, OSError) as exc:
            self.on_error(str(exc), "")
            return
        if not self._closed:
            self.set_scene(scene, params, chains=chains)

    def save_project_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Save project into folder")
        if folder:
            self.save_project(folder)

    def save_project(self, folder: str | Path) -> None:
        from npsim_core.chain.project import save_project

        if self.chain is None:
            return
        s = self.editor.session
        try:
            save_project(folder, self.chain.scene.with_(lights=s.ann), self.params, self.results)
            self.log.log(f"project saved to {folder}")
        except (NpsimInputError, OSError) as exc:
            self.on_error(str(exc), "")
            return
        if s.is_dirty:
            if s.folder is None:
                # a frame that exists only in memory: from now on its annotation lives in the project
                s.folder, s.stem = Path(folder) / "scene", self.chain.scene.name
                s.save_in_background()
            else:  # the project holds a copy; the frame's own annotation file is saved too
                self.save_annotation()

    def save_annotation(self) -> None:
        """Save the frame's light annotation where the command line reads it (``X_lights.json`` beside a
        dataset image, or the annotations folder of a read-only dataset; in the background)."""
        try:
            self.editor.session.save_in_background()
            self._set_busy("saving the annotation…")
        except NpsimInputError as exc:
            self._save_failed(str(exc))

    def save_annotation_now(self) -> bool:
        """Save on this thread (before leaving a frame or closing); False, with a message, when it failed."""
        s = self.editor.session
        try:
            s.wait_for_writes()
            paths = s.save()
        except NpsimInputError as exc:
            self._save_failed(str(exc))
            return False
        self._on_saved(paths, "")
        return True

    def _save_failed(self, message: str) -> None:
        self._autosave()  # the edits stay in the recovery file at least
        self.on_error(f"annotation not saved: {message}", "")
        self.ask("Annotation not saved", f"{message}\n\nYour edits are kept in the recovery file; nothing "
                 "was overwritten.", ["OK"])

    def _on_saved(self, paths, error: str) -> None:
        if self.busy_label.text() == "saving the annotation…":
            self._set_busy("")
        if error:
            self._save_failed(error)
            return
        self.log.log(f"annotation saved: {paths['json']}")
        self.statusBar().showMessage(f"saved {paths['json']}", 5000)
        self._mark_frame_done()
        self._update_title()

    def _mark_frame_done(self) -> None:
        """✓ in the Frames dock for the frame shown (its annotation is on disk)."""
        frames = getattr(self, "frames", None)
        k = getattr(self, "frame_index", -1)
        if frames and 0 <= k < self.frame_list.count() and self.chain is not None \
                and frames[k].name == self.chain.scene.name:
            self.frame_list.item(k).setText("✓ " + frames[k].name)

    def leave_frame(self, what: str = "open another frame") -> bool:
        """Before another frame replaces this one: Save / Discard / Cancel when the annotation has unsaved
        edits. True = go ahead."""
        s = self.editor.session
        if self.chain is None or not s.is_dirty:
            return True
        self._autosave()
        choice = self.ask("Unsaved annotation", f"{self.chain.scene.name}: save the light annotation before you "
                          f"{what}?", ["Save", "Discard", "Cancel"])
        if choice == "Save":
            return self.save_annotation_now()
        if choice == "Discard":
            s.wait_for_writes()
            s.discard_recovery()
            return True
        return False

    def export_dialog(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Export into folder")
        if folder:
            self.export(folder)

    def export(self, folder: str | Path, *, nights: int = 1, show_progress: bool = True) -> None:
        """Write masks, depth, normals, meshes and nights to ``folder`` in a worker, with progress."""
        from npsim_core.chain import export_frame

        if self.chain is None:
            return
        chain, params = self.chain, self.params
        folder = Path(folder)
        name = chain.scene.name
        if (folder / f"{name}_export.json").exists() and \
                self.ask("Overwrite the export?", f"{folder} already holds an export of {name}. Overwrite its "
                         "files?", ["Overwrite", "Cancel"]) != "Overwrite":
            return
        # An unchanged frame (same parameters, annotation and nights) is not computed again: its last
        # export's files are copied (a full-resolution export renders for minutes).
        key = (id(chain), params, getattr(self, "_ann_version", 0), nights)
        last = getattr(self, "_export_cache", None)
        reuse = last[1] if last is not None and last[0] == key and all(p.exists() for p in last[1]) else None
        apply_ann = self._annotation_for_job()
        dlg = None
        if show_progress:
            dlg = QProgressDialog("Exporting…", "Cancel", 0, 100, self)
            dlg.setWindowModality(Qt.WindowModality.WindowModal)
            dlg.setMinimumDuration(0)
            dlg.canceled.connect(self.export_jobs.cancel)
        self._export_dialog = dlg

        def job(cancel, progress):
            if reuse is not None:
                return _copy_export(reuse, folder, cancel, progress), key
            apply_ann(chain)
            return export_frame(chain, params, folder, nights=nights, cancel=cancel,
                                progress=lambda f, text: progress((f, text))), key

        self._export_folder = folder  # what the (once-connected) handlers report
        self._export_reused = reuse is not None
        self.export_jobs.submit(job)

    def _on_export_progress(self, info) -> None:
        dlg = getattr(self, "_export_dialog", None)
        if dlg is not None:
            dlg.setValue(int(info[0] * 100))
            dlg.setLabelText(info[1])

    def _on_export_done(self, payload) -> None:
        written, key = payload
        dlg = getattr(self, "_export_dialog", None)
        if dlg is not None:
            dlg.setValue(100)
        self._export_cache = (key, list(written))
        how = " (unchanged frame: the last export's files copied, nothing recomputed)" if self._export_reused else ""
        self.log.log(f"exported {len(written)} files to {self._export_folder}{how}")
        self.last_export = written
        self.export_reports = getattr(self, "export_reports", 0) + 1

    # ----------------------------------------------------------------- errors & lifetime
    def on_error(self, message: str, tb: str) -> None:
        self._set_busy("")
        self.log.log(f"error: {message}")
        self.statusBar().showMessage(message, 10000)
        self.last_error = message

    #: The recovery file is written this long (ms) after the first edit not yet in it.
    AUTOSAVE_MS = 1000

    #: Screens narrower than this get one right-hand column: parameters over the night preview (tabbed
    #: with the 3D view), so the annotation canvas, the annotator's workspace, is the largest panel.
    #: (With parameters on the left and the 3D view over the night on the right, the canvas was 401 px
    #: wide at 1600x900.) Only very wide screens get the three-column arrangement.
    NARROW_SCREEN = 2500
    #: Width of the right-hand column as a fraction of the screen (at least RIGHT_MIN px).
    RIGHT_FRACTION, RIGHT_MIN = 0.25, 330

    def _fit_screen(self) -> None:
        """Start within the screen (a saved layout that fits overrides this)."""
        from PySide6.QtGui import QGuiApplication

        screen = self.screen() or QGuiApplication.primaryScreen()
        if screen is not None:
            self.fit_to(screen.availableGeometry())

    def fit_to(self, avail) -> None:
        """Size the window for the available screen rectangle ``avail`` (QRect) and choose the dock
        arrangement: on screens narrower than :attr:`NARROW_SCREEN` px the parameters (tabbed with
        the frame list) go over the night preview (tabbed with the 3D view) in one right-hand column;
        wider, the parameters are on the left and the 3D view sits over the night preview."""
        self._avail = avail
        self._narrow = avail.width() < self.NARROW_SCREEN
        self._arrange_pending = True
        self.resize(min(1680, avail.width()), min(1020, avail.height()))
        if self.isVisible():
            self._arrange()

    def _arrange(self) -> None:
        self._arrange_pending = False
        right, left = Qt.DockWidgetArea.RightDockWidgetArea, Qt.DockWidgetArea.LeftDockWidgetArea
        vertical = Qt.Orientation.Vertical
        frames_open = not self.frames_dock.isHidden()
        docks = [self.params_dock, self.frames_dock, self.render_dock] + ([self.viewer_dock] if self.viewer else [])
        for d in docks:
            self.removeDockWidget(d)
        self.addDockWidget(right if self._narrow else left, self.params_dock, vertical)
        if self._narrow or self.viewer is None:
            self.addDockWidget(right, self.render_dock, vertical)
            if self.viewer is not None:
                self.tabifyDockWidget(self.render_dock, self.viewer_dock)
        else:
            self.addDockWidget(right, self.viewer_dock, vertical)
            self.addDockWidget(right, self.render_dock, vertical)
        if self._narrow:
            self.tabifyDockWidget(self.params_dock, self.frames_dock)
        else:  # the frame list under the parameters
            self.splitDockWidget(self.params_dock, self.frames_dock, vertical)
        for d in docks:
            d.show()
        self.frames_dock.setVisible(frames_open)
        self.params_dock.raise_()
        self.render_dock.raise_()
        if self._narrow:
            self.resizeDocks([self.params_dock, self.render_dock], [300, 400], vertical)
            right_w = max(self.RIGHT_MIN, int(self._avail.width() * self.RIGHT_FRACTION))
            self.resizeDocks([self.render_dock], [right_w], Qt.Orientation.Horizontal)
        elif self.viewer is not None:
            self.resizeDocks([self.viewer_dock, self.render_dock], [400, 500], vertical)
            self.resizeDocks([self.viewer_dock], [self._avail.width() // 3], Qt.Orientation.Horizontal)
        self.resizeDocks([self.log_dock], [90], vertical)
        if frames_open and not self._narrow:
            self.resizeDocks([self.params_dock, self.frames_dock], [600, 160], vertical)

    def showEvent(self, event) -> None:  # noqa: N802 (Qt API)
        super().showEvent(event)
        if getattr(self, "_arrange_pending", False):  # on a laid-out window (earlier leaves a stray tab bar)
            self._arrange()

    def _restore_layout(self) -> None:
        """Window geometry and dock state of the last session (QSettings), when they fit this screen."""
        s = QSettings(ORG, APP)
        geo, state = s.value("geometry"), s.value("state")
        if geo is None or state is None:
            return
        self.restoreGeometry(geo)
        self.restoreState(state)
        avail = getattr(self, "_avail", None)
        hint = self.minimumSizeHint()
        if avail is not None and (hint.width() > avail.width() or hint.height() > avail.height()
                                  or not avail.contains(self.geometry())):
            self.fit_to(avail)  # saved on a larger screen: the default arrangement for this one
        else:
            self._arrange_pending = False

    def save_layout(self) -> None:
        """Remember the window geometry and dock state for the next session (also done on close)."""
        s = QSettings(ORG, APP)
        s.setValue("geometry", self.saveGeometry())
        s.setValue("state", self.saveState())

    def ask(self, title: str, text: str, buttons: list[str]) -> str:
        """Modal question; returns the chosen button's text (tests replace this method)."""
        box = QMessageBox(QMessageBox.Icon.Question, title, text, parent=self)
        for b in buttons:
            box.addButton(b, QMessageBox.ButtonRole.AcceptRole)
        box.exec()
        clicked = box.clickedButton()
        return clicked.text() if clicked is not None else buttons[-1]

    def confirm_close(self) -> bool:
        """Save / Discard / Cancel when the annotation has unsaved edits. True = go ahead."""
        return self.leave_frame("close")

    def _autosave(self) -> None:
        """Write the recovery file of unsaved edits (in the background)."""
        self.autosave_timer.stop()
        s = self.editor.session
        if s.is_dirty and s.folder is not None and not s.readonly_reason:
            s.autosave_in_background()

    def closeEvent(self, event) -> None:  # noqa: N802
        if self.editor.session.is_dirty:
            if not self.confirm_close():  # autosaves first: nothing is lost even if answered wrongly
                event.ignore()
                return
        self.editor.session.wait_for_writes()
        self._closed = True  # a frame still being read is not shown
        self.save_layout()
        for ch in (self.pipeline_jobs, self.render_jobs, self.export_jobs, self.view_jobs):
            ch.cancel()
        self.pipeline_jobs.shutdown()  # workers stop at their next cancellation check
        if self.viewer is not None:
            self.viewer.close_viewer()
        # let go of the frame's results: signal connections to lambdas keep a closed window's Python
        # object alive (PySide cannot collect those cycles), which must not keep gigabytes with it
        self.chain = self.proxy_chain = self.results = None
        self._export_cache = None
        self.editor.clear_proposals()
        self.render_panel.clear_night()
        release_free_memory()
        super().closeEvent(event)
