"""Editor state for one image: annotation, undo history, superpixels, selection.

The session is the only thing that mutates the annotation; every edit goes
through :meth:`EditorSession.apply` (an :mod:`npsim_core.annotation_ops`
command on the undo stack) and is announced with ``changed(Change)``.
Superpixels are computed in a worker thread; ``superpixelsReady`` fires when
the result for the *current* image and settings arrives (stale results are
dropped by a generation counter). A job whose session goes away (the editor
is deleted, or the application quits while it computes) is cancelled: it
stops before its next step and never emits into a deleted object.
"""

from __future__ import annotations

import threading
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
from PySide6.QtCore import QCoreApplication, QObject, QRunnable, QThreadPool, Signal

from npsim_core.annotation import (DEFAULT_GROUP_FOR_LIGHT, GroupInstance, LightAnnotation, annotation_paths,
                                   check_image, class_of, discard_recovery, image_checksum, is_group_class,
                                   is_light_class, save_annotation, write_recovery)
from npsim_core.annotation_ops import (Change, EditCommand, MacroCommand, Structure, UndoStack, group_lights,
                                      vehicle_grouping)
from npsim_core.errors import NpsimInputError
from npsim_core.labels import light_class
from npsim_core.superpixels import SuperpixelParams, cached_superpixels, default_region_size, superpixel_means

#: Default group class per light class (docs/annotation.md "Default groups"). resources/light_classes.json
#: only gives each light class a category, and the vehicle category holds both car and public-transport
#: lights, so the table is written here: building windows -> windows_group (13); windows and lamps of
#: parked and moving vehicles -> car_group (14); window_transport (windows of buses, trams, trains) ->
#: bus_group (16, the common case in street scenes; train_group is Alt+7). Street lights,
#: advertisements, clocks and inferred lights stand alone: no default group (Ctrl+G then asks for one).
DEFAULT_GROUP_CLASS = DEFAULT_GROUP_FOR_LIGHT  # one table, in the core


def default_group_class(light_class_id: int) -> int | None:
    """The group class preselected for a light class (None: the class is not grouped by default)."""
    return DEFAULT_GROUP_CLASS.get(int(light_class_id))


def join_group(ann: LightAnnotation, group_id: int, lights) -> EditCommand | None:
    """Command adding existing ``lights`` to group ``group_id`` (they leave any other group; groups
    emptied by that are removed). None when nothing changes."""
    g = ann.groups[group_id]
    add = set(int(i) for i in lights) - set(g.members)
    if not add:
        return None
    before = Structure.of(ann)
    groups = {}
    for gid, other in ann.groups.items():
        members = tuple(m for m in other.members if gid == group_id or m not in add)
        if gid == group_id:
            members = tuple(sorted(set(members) | add))
        if members:
            groups[gid] = GroupInstance(gid, members)
    after = Structure(tuple(groups[k] for k in sorted(groups)), before.extra_ids)
    return EditCommand(f"join {group_id}", None, before, after)


class _Bridge(QObject):
    done = Signal(int, object)
    #: (kind "save" | "autosave", serial of the edits saved, paths or Exception), from the writer thread
    written = Signal(str, int, object)


class _SuperpixelJob(QRunnable):
    """Coarse then fine superpixels in a pool thread. ``cancelled`` (job) and ``closed`` (session gone)
    are checked before every step; an emit into a bridge deleted meanwhile is dropped silently."""

    def __init__(self, bridge: _Bridge, generation: int, image: np.ndarray, key: str, params: SuperpixelParams,
                 cancelled: threading.Event, closed: threading.Event):
        super().__init__()
        self.bridge, self.generation, self.image, self.key, self.params = bridge, generation, image, key, params
        self.cancelled, self.closed = cancelled, closed

    def _stopped(self) -> bool:
        return self.cancelled.is_set() or self.closed.is_set()

    def _emit(self, payload) -> bool:
        if self._stopped():
            return False
        try:
            self.bridge.done.emit(self.generation, payload)
        except RuntimeError:  # "Signal source has been deleted": the editor went away meanwhile
            self.closed.set()
            return False
        return True

    def run(self) -> None:
        try:
            # The coarse scale first: the tools can work while the fine one is computed.
            coarse = cached_superpixels(self.image, self.params, self.key)
            if self._stopped():
                return
            means = superpixel_means(self.image, coarse)
            if not self._emit(("coarse", coarse, means)):
                return
            fine = cached_superpixels(self.image, self.params.fine(), self.key)
            self._emit(("fine", fine, None))
        except Exception as exc:  # noqa: BLE001 -- reported in the GUI, never kills the worker pool
            self._emit(exc)


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
    #: A background save ended: (paths written, or None) and an error text ("" when it worked).
    saved = Signal(object, str)
    #: A background autosave wrote the recovery file (its path).
    autosaved = Signal(object)

    def __init__(self, parent=None, *, superpixels: bool = True) -> None:
        """``superpixels=False``: never compute superpixels (a session replayed by a script, e.g. the action
        benchmark, draws with masks it is given; no pool thread then runs native code behind it)."""
        super().__init__(parent)
        self.compute_superpixels = superpixels
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
        self.vehicle_instances: np.ndarray | None = None
        #: a vehicle light drawn on a vehicle joins that vehicle's group (needs :attr:`vehicle_instances`)
        self.group_by_vehicle = True
        self._sp_generation = 0
        self._bridge = _Bridge()
        self._bridge.done.connect(self._on_superpixels)
        self._bridge.written.connect(self._on_written)
        #: One writer thread: saves and recovery files are written in order, off the GUI thread
        #: (a 2048x1024 save encodes two PNGs and the RLE JSON: 0.3 s).
        self._writer = ThreadPoolExecutor(1, thread_name_prefix="npsim-annotation-writer")
        #: Counts every edit, undo and redo: a background save marks the session clean only when
        #: nothing changed while it wrote.
        self.edit_serial = 0
        self._ids: set[int] = set()
        self._ids_at: tuple[int, int] | None = None
        self.pool = QThreadPool.globalInstance()
        # Jobs stop (and never emit) once the session is destroyed or the application quits.
        self._closed = threading.Event()
        self._job_cancel = threading.Event()
        self.destroyed.connect(self._closed.set)
        app = QCoreApplication.instance()
        if app is not None:
            app.aboutToQuit.connect(self._closed.set)
        self.current_class = 1
        #: Group class Ctrl+G uses; None = none chosen (the selected lights' default group is used).
        self.group_class: int | None = 13
        #: True when the group class was picked by hand (palette / Alt+1..9) after the last light class.
        self.group_explicit = False
        self.current_id: int | None = None
        self.selection: set[int] = set()
        #: Group new lights join while it is set (key A; docs/annotation.md "Groups").
        self.active_group: int | None = None
        self._created_run: set[int] = set()  # lights made by consecutive split strokes, kept selected
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
        self.edit_serial += 1  # a save of the previous image that ends later never marks this one clean
        self.folder = Path(folder) if folder is not None else None
        self.stem = stem
        self.image_key = image_checksum(image)
        self.current_id = None
        self.selection = set()
        self.active_group = None
        self.vehicle_instances = None
        self._created_run = set()
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
        self._job_cancel.set()  # a previous job skips what it has not started (its result is stale)
        self._job_cancel = threading.Event()
        if not self.compute_superpixels:
            return
        self.pool.start(_SuperpixelJob(self._bridge, self._sp_generation, self.image, self.image_key, self.sp_params,
                                       self._job_cancel, self._closed))

    def shutdown(self) -> None:
        """Cancel the background work under way (the editor is closing): the job stops before its next
        step and emits nothing. A later :meth:`load` or :meth:`request_superpixels` starts afresh.
        Deleting the session or quitting the application does the same on its own."""
        self._job_cancel.set()
        self._sp_generation += 1

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

    def existing_ids(self) -> set[int]:
        """Ids of the lights that exist (with pixels or registered), computed once per edit (a pass over
        the map: 3-10 ms at 2048x1024). Do not modify the returned set."""
        if self._ids_at != (self.edit_serial, id(self.ann)):
            self._ids = set(self.ann.instance_ids())
            self._ids_at = (self.edit_serial, id(self.ann))
        return self._ids

    def _after_edit(self, ch: Change) -> None:
        self.edit_serial += 1
        existing = self.existing_ids() | set(self.ann.groups) if ch.structure else None
        if existing is not None:
            if self.current_id is not None and self.current_id not in existing:
                self.current_id = None
                self.currentChanged.emit()
            if self.active_group is not None and self.active_group not in self.ann.groups:
                self.active_group = None
                self.currentChanged.emit()
            if self.selection - existing:
                self.selection &= existing
                self.selectionChanged.emit()
        self.changed.emit(ch)
        self._emit_dirty()

    def _emit_dirty(self) -> None:
        if self.is_dirty != self._was_dirty:
            self._was_dirty = self.is_dirty
            self.dirtyChanged.emit(self.is_dirty)

    # ----------------------------------------------------------------- selection / current
    def set_current_class(self, class_id: int) -> None:
        """A light class (also preselects its default group class) or a group class (chosen by hand)."""
        if is_light_class(class_id):
            self.current_class = class_id
            self.group_class = default_group_class(class_id)
            self.group_explicit = False
            if self.current_id is not None and class_of(self.current_id) != class_id:
                self.current_id = None  # the next stroke starts a light of the new class
        else:
            self.group_class = class_id
            self.group_explicit = True
        self.currentChanged.emit()

    def set_current(self, instance_id: int | None) -> None:
        self.current_id = instance_id
        if instance_id is not None and is_light_class(class_of(instance_id)):
            self.current_class = class_of(instance_id)
            if not self.group_explicit:
                self.group_class = default_group_class(self.current_class)
        self.currentChanged.emit()

    def set_selection(self, ids, *, current: int | None = None) -> None:
        ids = set(int(i) for i in ids)
        if ids != self.selection:
            self.selection = ids
            self.selectionChanged.emit()
        if current is not None:
            self.set_current(current)

    def selected_lights(self) -> set[int]:
        return {i for i in self.selection if is_light_class(class_of(i))}

    def selected_groups(self) -> set[int]:
        return {i for i in self.selection if i in self.ann.groups}

    def highlighted(self) -> set[int]:
        """Lights drawn as selected: the selected lights and the members of the selected groups."""
        out = self.selected_lights()
        for g in self.selected_groups():
            out.update(self.ann.groups[g].members)
        return out

    def group_class_for(self, lights) -> int | None:
        """Group class for grouping ``lights``: the one picked by hand, else the most common default
        group of their classes (None when none of them has one)."""
        if self.group_explicit and self.group_class is not None:
            return self.group_class
        votes = Counter(g for i in lights if (g := default_group_class(class_of(i))) is not None)
        if not votes:
            return None
        best = max(votes.values())
        return min(g for g, n in votes.items() if n == best)

    def group_selection(self) -> tuple[int | None, str]:
        """Group the selection (Ctrl+G, and the end of a Ctrl+Shift+drag): the selected lights and the lights of
        the selected groups become one group, one undo step. With exactly one group selected (and no other
        group class picked by hand) the other selected lights join that group; otherwise a new group of the
        group class picked by hand, else of the selected groups' class when they all have one, else of the
        lights' default group class, is made (lights leave their old groups: merging groups). Returns (the
        group's id, the status text); (None, why) when nothing was grouped. Raises :class:`NpsimInputError`
        from the edit command (e.g. a class's 999 ids used up)."""
        groups = sorted(self.selected_groups())
        lights = self.highlighted()
        if not lights:
            return None, ("select lights to group: Shift/Ctrl+click, a box with the Select tool (V), a Ctrl+drag "
                          "over them, or the list")
        if len(groups) == 1 and not (self.group_explicit and self.group_class not in (None, class_of(groups[0]))):
            gid = groups[0]
            cmd = join_group(self.ann, gid, lights)
            if cmd is None:
                return None, f"the selection already is {light_class(class_of(gid)).name} {gid}"
        else:
            # Several whole groups of one class merge into one of that class (two train_groups stay a
            # train_group, not the bus_group their windows' class preselects), unless one is picked by hand.
            kept = {class_of(g) for g in groups}
            gclass = kept.pop() if len(groups) > 1 and len(kept) == 1 and not self.group_explicit \
                else self.group_class_for(lights)
            if gclass is None:
                names = sorted({light_class(class_of(i)).name for i in lights})
                return None, (f"{', '.join(names)} has no default group class: choose a group class "
                              "(Alt+1…Alt+9 or the Groups buttons), then Ctrl+G")
            cmd, gid = group_lights(self.ann, lights, gclass)
        self.apply(cmd)
        self.set_selection({gid})
        return gid, f"grouped {len(lights)} lights as {light_class(class_of(gid)).name} {gid}"

    def set_active_group(self, group_id: int | None) -> None:
        """New lights join ``group_id`` while it is active (None ends it)."""
        if group_id is not None and (group_id not in self.ann.groups or not is_group_class(class_of(group_id))):
            raise ValueError(f"{group_id} is not a group")
        if group_id != self.active_group:
            self.active_group = group_id
            self.currentChanged.emit()
            self.selectionChanged.emit()  # the group boxes show which group is active

    def set_vehicle_instances(self, instances: np.ndarray | None) -> None:
        """The image's Cityscapes instanceIds (HxW integers; None: none): a vehicle light drawn on a vehicle
        joins that vehicle's group (:meth:`lights_created`). :meth:`load` clears them."""
        if instances is not None:
            instances = np.asarray(instances)
            if instances.shape != self.ann.shape or not np.issubdtype(instances.dtype, np.integer):
                raise NpsimInputError(f"instance ids must be an integer map of the image's size {self.ann.shape}, "
                                      f"got {instances.dtype} {instances.shape}")
        self.vehicle_instances = instances

    def lights_created(self, ids) -> None:
        """Call after creating lights (inside the same stroke): they join the active group, if any; else,
        with :attr:`group_by_vehicle` on and the image's instance ids known, a vehicle light joins its
        vehicle's group (or makes it: ``annotation_ops.vehicle_grouping``)."""
        if self.active_group is not None and self.active_group in self.ann.groups and ids:
            self.apply(join_group(self.ann, self.active_group, ids))
        elif self.group_by_vehicle and self.vehicle_instances is not None:
            for i in ids:
                plan = vehicle_grouping(self.ann, self.vehicle_instances, int(i))
                if plan is None:
                    continue
                gid, members, cls = plan
                if gid is not None:
                    self.apply(join_group(self.ann, gid, members))
                else:
                    self.apply(group_lights(self.ann, members, cls)[0])

    def select_created(self, ids, current: int | None = None) -> None:
        """Select lights made by a split stroke; consecutive such strokes add up while the selection is
        left alone (click each window with *one light per region*, then Ctrl+G)."""
        ids = set(int(i) for i in ids)
        if self._created_run and self.selection == self._created_run:
            ids |= self._created_run
        self._created_run = set(ids)
        self.set_selection(ids, current=current)

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
        """Write the annotation files atomically (on this thread); the recovery file is removed afterwards.
        Raises :class:`NpsimInputError` naming what is missing or the file that failed."""
        self._check_savable()
        if self._stroke is not None:
            self.end_stroke()
        try:
            paths = save_annotation(self.ann, self.folder, self.stem, image=self.image)
        except OSError as exc:
            raise NpsimInputError(f"{self.folder}: could not write the annotation ({exc.strerror or exc})") from None
        self._mark_saved()
        return paths

    def _check_savable(self) -> None:
        if self.folder is None:
            raise NpsimInputError("this frame has no folder to save its annotation in (it exists only in memory): "
                                  "use File > Save project…")
        if self.readonly_reason:
            raise NpsimInputError(f"not saving: {self.readonly_reason}")

    def _mark_saved(self) -> None:
        self.stack.mark_clean()
        self._meta_dirty = False
        discard_recovery(self.folder, self.stem)
        self._after_edit(Change())

    def save_in_background(self) -> None:
        """Save a snapshot of the annotation in the writer thread; :attr:`saved` tells the outcome.
        The session turns clean only if no edit came in meanwhile (else the newer edits stay unsaved)."""
        self._check_savable()
        if self._stroke is not None:
            self.end_stroke()
        snap, folder, stem, image, serial = self.ann.copy(), self.folder, self.stem, self.image, self.edit_serial

        def job():
            try:
                self._bridge.written.emit("save", serial, (folder, stem, save_annotation(snap, folder, stem,
                                                                                         image=image)))
            except Exception as exc:  # noqa: BLE001 -- reported in the window, never lost in a thread
                self._bridge.written.emit("save", serial, exc)
        self._writer.submit(job)

    def autosave_in_background(self) -> None:
        """Write the recovery file from a snapshot in the writer thread (:attr:`autosaved` when written)."""
        if self.folder is None or not self.is_dirty:
            return
        snap, folder, stem, serial = self.ann.copy(), self.folder, self.stem, self.edit_serial

        def job():
            try:
                self._bridge.written.emit("autosave", serial, (folder, stem, write_recovery(snap, folder, stem)))
            except Exception as exc:  # noqa: BLE001
                self._bridge.written.emit("autosave", serial, exc)
        self._writer.submit(job)

    def wait_for_writes(self) -> None:
        """Block until every queued save and autosave has been written."""
        self._writer.submit(lambda: None).result()

    def _on_written(self, kind: str, serial: int, result) -> None:
        if isinstance(result, Exception):
            if kind == "autosave":
                self.message.emit(f"autosave failed: {result}")
            else:
                err = result.strerror if isinstance(result, OSError) and result.strerror else str(result)
                self.saved.emit(None, f"{self.folder}: could not write the annotation ({err})")
            return
        folder, stem, result = result
        current = (folder, stem) == (self.folder, self.stem)  # else written for an image no longer open
        if kind == "autosave":
            if current and not self.is_dirty:  # saved meanwhile: the recovery file is stale
                self._writer.submit(lambda f=folder, s=stem: discard_recovery(f, s))
            elif current:
                self.autosaved.emit(result)
            return
        if current and serial == self.edit_serial:
            self.stack.mark_clean()
            self._meta_dirty = False
            self._writer.submit(lambda f=self.folder, s=self.stem: discard_recovery(f, s))
            self._emit_dirty()  # the clean marker itself is no edit (edit_serial stays)
        self.saved.emit(result, "")

    def autosave(self) -> Path | None:
        """Write the recovery file when there are unsaved edits (on this thread)."""
        if self.folder is None or not self.is_dirty:
            return None
        return write_recovery(self.ann, self.folder, self.stem)

    def discard_recovery(self) -> None:
        if self.folder is not None:
            discard_recovery(self.folder, self.stem)
