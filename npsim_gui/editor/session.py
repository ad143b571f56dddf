"""Editor state for one image: annotation, undo history, superpixels, selection.

The session is the only thing that mutates the annotation; every edit goes
through :meth:`EditorSession.apply` (an :mod:`npsim_core.annotation_ops`
command on the undo stack) and is announced with ``changed(Change)``.
Superpixels are computed in a worker thread; ``superpixelsReady`` fires when
the result for the *current* image and settings arrives (stale results are
dropped by a generation counter).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from PySide6.QtCore import QObject, QRunnable, QThreadPool, Signal

from npsim_core.annotation import (DEFAULT_GROUP_FOR_LIGHT, LightAnnotation, annotation_paths, check_image,
                                   class_of, discard_recovery, image_checksum, is_light_class, save_annotation,
                                   write_recovery)
from npsim_core.annotation_ops import Change, MacroCommand, UndoStack
from npsim_core.superpixels import SuperpixelParams, cached_superpixels, default_region_size, superpixel_means


class _Bridge(QObject):
    done = Signal(int, object)


class _SuperpixelJob(QRunnable):
    def __init__(self, bridge: _Bridge, generation: int, image: np.ndarray, key: str, params: SuperpixelParams):
        super().__init__()
        self.bridge, self.generation, self.image, self.key, self.params = bridge, generation, image, key, params

    def run(self) -> None:
        try:
            # The coarse scale first: the tools can work while the fine one is computed.
            coarse = cached_superpixels(self.image, self.params, self.key)
            means = superpixel_means(self.image, coarse)
            self.bridge.done.emit(self.generation, ("coarse", coarse, means))
            fine = cached_superpixels(self.image, self.params.fine(), self.key)
            self.bridge.done.emit(self.generation, ("fine", fine, None))
        except Exception as exc:  # noqa: BLE001 -- reported in the GUI, never kills the worker pool
            self.bridge.done.emit(self.generation, exc)


class EditorSession(QObject):
    """State of the image being annotated."""

    changed = Signal(object)  # Change
    selectionChanged = Signal()
    currentChanged = Signal()
    dirtyChanged = Signal(bool)
    superpixelsReady = Signal()  # the coarse scale is ready (fineReady follows)
    fineReady = Signal()
    loaded = Signal()
    message = Signal(str)

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.image = np.zeros((1, 1, 3), np.uint8)
        self.labels: np.ndarray | None = None
        self.ann = LightAnnotation.empty(1, 1)
        self.stack = UndoStack(self.ann)
        self.folder: Path | None = None
        self.stem = "annotation"
        self.image_key = ""
        self.sp_params = SuperpixelParams()
        self.sp_coarse: np.ndarray | None = None
        self.sp_fine: np.ndarray | None = None
        self.sp_means: np.ndarray | None = None
        self._sp_fine_means: np.ndarray | None = None
        self.sp_auto_size = True  # region size follows the image width until the user sets one
        self._sp_generation = 0
        self._bridge = _Bridge()
        self._bridge.done.connect(self._on_superpixels)
        self.pool = QThreadPool.globalInstance()
        self.current_class = 1
        self.group_class = 13
        self.current_id: int | None = None
        self.selection: set[int] = set()
        self._meta_dirty = False
        self._was_dirty = False
        self._stroke: MacroCommand | None = None
        self.readonly_reason: str | None = None

    # ----------------------------------------------------------------- loading
    def load(self, image: np.ndarray, labels: np.ndarray | None = None, ann: LightAnnotation | None = None,
             folder: str | Path | None = None, stem: str = "annotation", *, dirty: bool = False) -> None:
        """Start editing ``image`` with ``ann`` (empty when None); annotation files go to ``folder``/``stem``."""
        image = np.ascontiguousarray(image, dtype=np.uint8)
        H, W = image.shape[:2]
        if ann is None:
            ann = LightAnnotation.empty(H, W)
        if ann.shape != (H, W):
            raise ValueError(f"annotation is {ann.shape}, image is {(H, W)}")
        self.image, self.labels, self.ann = image, labels, ann
        self.stack = UndoStack(ann)
        self.folder = Path(folder) if folder is not None else None
        self.stem = stem
        self.image_key = image_checksum(image)
        self.current_id = None
        self.selection = set()
        self._meta_dirty = dirty
        self._was_dirty = dirty
        self.readonly_reason = None
        self.sp_coarse = self.sp_fine = self.sp_means = self._sp_fine_means = None
        if self.sp_auto_size:
            self.sp_params = replace(self.sp_params, region_size=default_region_size(W))
        if not check_image(ann, image):
            self.message.emit("warning: this annotation was saved for a different image (checksum differs)")
        self.loaded.emit()
        self.dirtyChanged.emit(self.is_dirty)
        self.request_superpixels()

    # ----------------------------------------------------------------- superpixels
    def request_superpixels(self, params: SuperpixelParams | None = None) -> None:
        """Compute superpixels for the current image in the background."""
        if params is not None:
            self.sp_params = params
            self.sp_auto_size = False
        self._sp_generation += 1
        self.sp_coarse = self.sp_fine = self.sp_means = self._sp_fine_means = None
        self.pool.start(_SuperpixelJob(self._bridge, self._sp_generation, self.image, self.image_key, self.sp_params))

    def _on_superpixels(self, generation: int, result) -> None:
        if generation != self._sp_generation:
            return  # stale: the image or the settings changed meanwhile
        if isinstance(result, Exception):
            self.message.emit(f"superpixels failed: {result}")
            return
        scale, labels, means = result
        if scale == "coarse":
            self.sp_coarse, self.sp_means = labels, means
            self.superpixelsReady.emit()
        else:
            self.sp_fine = labels
            self.fineReady.emit()

    @property
    def superpixels_ready(self) -> bool:
        return self.sp_coarse is not None

    @property
    def fine_ready(self) -> bool:
        return self.sp_fine is not None

    def sp_fine_means(self) -> np.ndarray:
        if self._sp_fine_means is None:
            self._sp_fine_means = superpixel_means(self.image, self.sp_fine)
        return self._sp_fine_means

    def current_class_name(self) -> str:
        from npsim_core.labels import light_class

        return light_class(self.current_class).name

    # ----------------------------------------------------------------- edits
    def apply(self, cmd, *, applied: bool = False) -> Change:
        """Run and record an edit (``None`` = no-op); inside a stroke it joins the stroke."""
        if cmd is None:
            return Change()
        if self._stroke is not None:
            ch = cmd.redo(self.ann) if not applied else Change()
            self._stroke.commands.append(cmd)
        else:
            ch = self.stack.push(cmd, applied=applied)
        self._after_edit(ch)
        return ch

    def begin_stroke(self, text: str) -> None:
        self._stroke = MacroCommand(text)

    def end_stroke(self) -> None:
        stroke, self._stroke = self._stroke, None
        if stroke is not None and stroke.commands:
            self.stack.push(stroke, applied=True)
            self._after_edit(Change())

    @property
    def in_stroke(self) -> bool:
        return self._stroke is not None

    def undo(self) -> None:
        if self._stroke is not None:
            self.end_stroke()
        ch = self.stack.undo()
        if ch is not None:
            self._after_edit(ch)

    def redo(self) -> None:
        ch = self.stack.redo()
        if ch is not None:
            self._after_edit(ch)

    def _after_edit(self, ch: Change) -> None:
        existing = set(self.ann.instance_ids()) | set(self.ann.groups) if ch.structure else None
        if existing is not None:
            if self.current_id is not None and self.current_id not in existing:
                self.current_id = None
                self.currentChanged.emit()
            if self.selection - existing:
                self.selection &= existing
                self.selectionChanged.emit()
        self.changed.emit(ch)
        if self.is_dirty != self._was_dirty:
            self._was_dirty = self.is_dirty
            self.dirtyChanged.emit(self.is_dirty)

    # ----------------------------------------------------------------- selection / current
    def set_current_class(self, class_id: int) -> None:
        if is_light_class(class_id):
            self.current_class = class_id
            self.group_class = DEFAULT_GROUP_FOR_LIGHT.get(class_id, self.group_class)
            if self.current_id is not None and class_of(self.current_id) != class_id:
                self.current_id = None  # the next stroke starts a light of the new class
        else:
            self.group_class = class_id
        self.currentChanged.emit()

    def set_current(self, instance_id: int | None) -> None:
        self.current_id = instance_id
        if instance_id is not None and is_light_class(class_of(instance_id)):
            self.current_class = class_of(instance_id)
        self.currentChanged.emit()

    def set_selection(self, ids, *, current: int | None = None) -> None:
        ids = set(int(i) for i in ids)
        if ids != self.selection:
            self.selection = ids
            self.selectionChanged.emit()
        if current is not None:
            self.set_current(current)

    def instance_at(self, x: int, y: int) -> int:
        H, W = self.ann.shape
        if 0 <= x < W and 0 <= y < H:
            return int(self.ann.instance_map[y, x])
        return 0

    # ----------------------------------------------------------------- dirty / saving
    @property
    def is_dirty(self) -> bool:
        return self._meta_dirty or not self.stack.is_clean

    def set_done(self, done: bool) -> None:
        if bool(self.ann.meta.get("done", False)) != done:
            self.ann.meta["done"] = bool(done)
            self._meta_dirty = True
            self._after_edit(Change())

    def paths(self) -> dict[str, Path] | None:
        return annotation_paths(self.folder, self.stem) if self.folder is not None else None

    def save(self) -> dict[str, Path]:
        """Write the annotation files atomically; the recovery file is removed afterwards."""
        if self.folder is None:
            raise RuntimeError("no folder to save to")
        if self.readonly_reason:
            raise RuntimeError(f"not saving: {self.readonly_reason}")
        if self._stroke is not None:
            self.end_stroke()
        paths = save_annotation(self.ann, self.folder, self.stem, image=self.image)
        self.stack.mark_clean()
        self._meta_dirty = False
        discard_recovery(self.folder, self.stem)
        self._after_edit(Change())
        return paths

    def autosave(self) -> Path | None:
        """Write the recovery file when there are unsaved edits."""
        if self.folder is None or not self.is_dirty:
            return None
        return write_recovery(self.ann, self.folder, self.stem)

    def discard_recovery(self) -> None:
        if self.folder is not None:
            discard_recovery(self.folder, self.stem)
