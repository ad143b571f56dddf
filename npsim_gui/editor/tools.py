"""Canvas tools: superpixel painting, brush/eraser, fill-to-superpixel, select, group.

The :class:`ToolController` receives mouse events in image coordinates from
the canvas and turns them into :mod:`npsim_core.annotation_ops` commands on the
session. One press-drag-release is one undo step.

Selection
---------
* Select tool: a click selects the light under the cursor (on no light: clears
  the selection); Shift+click or Ctrl+click adds/removes it; a drag draws a
  rubber band and selects every light it touches (Shift/Ctrl: adds them).
* Group tool: every click adds/removes the light under the cursor; a band adds.

Modifiers (every tool)
----------------------
* right click: make the light under the cursor the current one (select it);
* right-drag (superpixel and brush tools) starting on a light: add what the stroke passes over to that
  light, Shift+right-drag: remove it from that light (a *touch-up*, whatever *one light per region* says);
* Ctrl+click: add/remove the light under the cursor to/from the selection;
* Ctrl+drag: add every light the mouse path passes over to the selection (a *stroke select*: one
  gesture along a floor of windows that slants across the image, where an axis-aligned rubber band
  would also take the floor above or below; :func:`lights_on_path`);
* Ctrl+Shift+drag (or click): the same, then group the selection as Ctrl+G does (*stroke group*: a
  floor of accepted windows, split over several proposed groups, becomes one group in one gesture);
* Ctrl+drag (or click) *starting on a pending proposal* (the dashed layer, where no light is): accept
  every pending proposal the path passes over, with their proposed groups (one undo step), and select
  them with the lights it passes over (*stroke accept*: a row of proposals under the slider taken in
  one gesture, without their false group mates); with Shift the selection is then grouped as well;
* Shift: remove instead of add (superpixel tool), erase (brush), add/remove (select tool);
* Alt: use the other superpixel scale (fine instead of coarse, or back when the
  panel's *Fine scale* toggle, key D, is on -- for window managers that take Alt+drag).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Protocol

import numpy as np
from PySide6.QtCore import Qt

from npsim_core.annotation import class_of, is_light_class, light_class
from npsim_core.annotation_ops import erase, new_instance, paint, snap_to_superpixels, split_paint
from npsim_core.errors import NpsimInputError
from npsim_core.superpixels import disk_index, line_pixels, similar_superpixels, superpixel_index


class Tool(str, Enum):
    SUPERPIXEL = "superpixel"
    BRUSH = "brush"
    ERASER = "eraser"
    FILL = "fill"
    SELECT = "select"
    GROUP = "group"


@dataclass
class ToolOptions:
    """Tool settings shown in the side panel.

    brush_radius : px; overwrite : painting may take pixels from other lights;
    split_regions : a superpixel drag makes one new light per connected region
    (e.g. one per window); similar_only : a superpixel drag keeps only the
    superpixels that look like the one where the drag started -- within
    ``tolerance`` (CIELab, 8-bit units), or with 0 = auto everything but the wall
    (the densest colour dragged over; :func:`npsim_core.superpixels.similar_superpixels`).
    Both apply when the mouse is released.
    """

    brush_radius: float = 3.0
    overwrite: bool = False
    split_regions: bool = False
    similar_only: bool = False
    tolerance: float = 0.0  # 0 = auto (two-cluster split of the dragged superpixels)
    fine_scale: bool = False  # superpixel and fill tools use the fine scale (Alt inverts)


def _mods(event) -> Qt.KeyboardModifier:
    return event.modifiers() if event is not None else Qt.KeyboardModifier.NoModifier


def _view_pos(event):
    """The event's position in the view (screen pixels), or None for synthetic calls."""
    try:
        p = event.position()
        return float(p.x()), float(p.y())
    except AttributeError:
        return None


#: A select-tool press that moves less than this (screen px, Manhattan) is a click, not a band.
BAND_THRESHOLD = 4


def lights_on_path(instance_map: np.ndarray, points) -> set[int]:
    """Ids of the lights (non-zero ids of ``instance_map``) under a mouse path: the pixels of the straight
    segments joining ``points`` ((x, y) image coordinates, floored to pixels as the tools do), clipped to
    the image. What a Ctrl+drag (stroke select) adds to the selection; ``benchmarks.annotation_actions``
    asks the same function which lights a stroke through a group's lights would take."""
    pts = [(int(np.floor(x)), int(np.floor(y))) for x, y in points]
    if not pts:
        return set()
    xs, ys = [np.array([pts[0][0]])], [np.array([pts[0][1]])]
    for (x0, y0), (x1, y1) in zip(pts[:-1], pts[1:]):
        a, b = line_pixels(x0, y0, x1, y1)
        xs.append(np.asarray(a))
        ys.append(np.asarray(b))
    x, y = np.concatenate(xs).astype(np.int64), np.concatenate(ys).astype(np.int64)
    H, W = instance_map.shape
    ok = (x >= 0) & (x < W) & (y >= 0) & (y < H)
    return {int(i) for i in np.unique(instance_map[y[ok], x[ok]]) if i}


class ProposalStroke(Protocol):
    """What a stroke accept needs of the proposal layer (the editor provides it while it shows proposals)."""

    def pending_map(self) -> np.ndarray | None:
        """The pending proposals' ids per pixel (0 elsewhere), or None when there are none."""

    def accept(self, lights: list[int]) -> list[int]:
        """Accept proposal ``lights`` with their proposed groups (one undo step); the new light ids."""


class ToolController:
    """Dispatches canvas mouse events to the active tool."""

    def __init__(self, session, options: ToolOptions | None = None) -> None:
        self.session = session
        self.options = options or ToolOptions()
        self.tool = Tool.SUPERPIXEL
        self._active = None  # the press handler in use until release
        self._last: tuple[float, float] | None = None
        self._labels = None
        self._touched: set[int] = set()
        self._seed: int | None = None
        self._remove = False
        self._target: int | None = None
        self._band: tuple[float, float, float, float] | None = None  # select drag: image x0, y0, x1, y1
        self._band_mods = Qt.KeyboardModifier.NoModifier
        self._band_view: tuple[float, float] | None = None  # press position in the view
        self._band_moved = False
        self._band_press_pixel = (0, 0)
        self._stroke_last: tuple[float, float] | None = None  # Ctrl+drag: the path's last point
        self._stroke_ids: set[int] = set()  # Ctrl+drag: the lights passed over so far
        #: The proposal layer, when the editor shows one (:class:`ProposalStroke`); None: no stroke accept.
        self.proposals: ProposalStroke | None = None
        self._pending_map: np.ndarray | None = None  # stroke accept: the pending proposals' id map
        self._pending_ids: set[int] = set()  # stroke accept: the pending proposals passed over so far
        self._grow: tuple | None = None  # right press on a light: (light id, x, y, modifiers)
        self._growing = False  # a right-drag paints into (or, Shift, erases from) that light only

    # ----------------------------------------------------------------- dispatch
    def press(self, x: float, y: float, event=None) -> None:
        mods = _mods(event)
        button = event.button() if event is not None else Qt.MouseButton.LeftButton
        xi, yi = int(np.floor(x)), int(np.floor(y))
        s = self.session
        if button == Qt.MouseButton.RightButton:
            iid = s.instance_at(xi, yi)
            s.set_selection({iid} if iid else set(), current=iid or None)
            if not iid:
                s.set_current(None)
            elif self.tool in (Tool.SUPERPIXEL, Tool.BRUSH) and is_light_class(class_of(iid)):
                # A right-drag touches this light up (_grow_start), whatever *one light per region* says.
                self._active, self._grow = "grow", (iid, x, y, mods)
            return
        if self.tool in (Tool.SELECT, Tool.GROUP) or mods & Qt.KeyboardModifier.ControlModifier:
            # Click, rubber band or (Ctrl, any tool) stroke select: decided on release (a click acts then too).
            self._active = "stroke" if mods & Qt.KeyboardModifier.ControlModifier else "select"
            self._band = (x, y, x, y)
            self._band_mods = mods
            self._band_view = _view_pos(event)
            self._band_moved = False
            self._band_press_pixel = (xi, yi)
            self._stroke_last = (x, y)
            self._stroke_ids = lights_on_path(s.ann.instance_map, [(x, y)])
            self._pending_map, self._pending_ids = None, set()
            if self._active == "stroke" and not self._stroke_ids and self.proposals is not None:
                pmap = self.proposals.pending_map()
                if pmap is not None and 0 <= yi < pmap.shape[0] and 0 <= xi < pmap.shape[1] and pmap[yi, xi]:
                    self._pending_map, self._pending_ids = pmap, {int(pmap[yi, xi])}
            return
        self._last = (x, y)
        if self.tool == Tool.SUPERPIXEL:
            self._active = "superpixel"
            self._sp_press(xi, yi, mods)
        elif self.tool in (Tool.BRUSH, Tool.ERASER):
            self._active = "brush"
            self._brush_press(xi, yi, mods)
        elif self.tool == Tool.FILL:
            self._fill_click(xi, yi, mods)

    def move(self, x: float, y: float, event=None) -> None:
        if self._active == "grow":
            if (int(np.floor(x)), int(np.floor(y))) == tuple(int(np.floor(v)) for v in self._grow[1:3]):
                return  # not a drag yet: a right-click only makes the light current
            self._grow_start()
        if self._active == "stroke" and self._stroke_last is not None:
            self._stroke_ids |= lights_on_path(self.session.ann.instance_map, [self._stroke_last, (x, y)])
            if self._pending_map is not None:
                self._pending_ids |= lights_on_path(self._pending_map, [self._stroke_last, (x, y)])
            self._stroke_last = (x, y)
        if self._active in ("select", "stroke"):
            self._band = self._band[:2] + (x, y)
            vpos = _view_pos(event)
            if self._band_view is not None and vpos is not None:
                moved = abs(vpos[0] - self._band_view[0]) + abs(vpos[1] - self._band_view[1])
            else:
                moved = abs(x - self._band[0]) + abs(y - self._band[1])
            self._band_moved |= moved >= BAND_THRESHOLD
            return
        if self._active is None or self._last is None:
            return
        # Segments join the pixels the mouse was over (floor of the scene position).
        xs, ys = line_pixels(np.floor(self._last[0]), np.floor(self._last[1]), np.floor(x), np.floor(y))
        self._last = (x, y)
        if self._active == "superpixel":
            self._sp_points(xs, ys)
        elif self._active == "brush":
            self._brush_points(xs, ys)

    def release(self, x: float, y: float, event=None) -> None:
        if self._active is None:
            return
        self.move(x, y, event)
        if self._active == "select":
            band = self.band_rect()
            self._active = None
            self._select_release(band)
            return
        if self._active == "stroke":
            self._active = None
            self._stroke_release()
            return
        if self._active == "grow":  # a right-click: the light is current, nothing painted
            self._active = None
            return
        active, self._active = self._active, None
        if active == "superpixel":
            self._sp_release()
        self.session.end_stroke()
        self._last = None
        self._growing = False

    def double_click(self, x: float, y: float, event=None) -> bool:
        """A double-click (the canvas calls it for the second press): with the Select or Group tool, or
        Ctrl held with any tool (a Ctrl+click draws nothing), the group of the light under the mouse
        becomes the active group -- the lights drawn next join it (``EditorSession.lights_created``, in
        their own undo step) -- and on the background the active group ends. That completes a proposed
        group missing some lights in one gesture. False when it does nothing (a drawing tool without
        Ctrl: its first click was a stroke). The next stroke starts a new light of the clicked light's class."""
        button = event.button() if event is not None else Qt.MouseButton.LeftButton
        if button != Qt.MouseButton.LeftButton or not (
                self.tool in (Tool.SELECT, Tool.GROUP) or _mods(event) & Qt.KeyboardModifier.ControlModifier):
            return False
        s = self.session
        iid = s.instance_at(int(np.floor(x)), int(np.floor(y)))
        if not iid:
            if s.active_group is not None:
                s.set_active_group(None)
                s.message.emit("no active group: new lights are ungrouped")
            return True
        gid = s.ann.group_of(iid)
        if gid is None:
            s.message.emit(f"light {iid} is in no group: select lights and Ctrl+G, then double-click one of "
                           "them to add the lights drawn next")
            return True
        s.set_active_group(gid)
        s.set_selection({gid})
        # The next stroke starts a new light (which joins) of the clicked light's class (the pane or lamp
        # missing is mostly of its neighbour's class), not a stroke into the clicked light.
        s.set_current_class(class_of(iid))
        s.set_current(None)
        s.message.emit(f"active group {light_class(class_of(gid)).name} {gid}: new lights join it "
                       "(double-click the background or Esc ends)")
        return True

    def shows_path(self) -> bool:
        """True while a drag whose effect comes on release is under way (the canvas draws its path)."""
        return self._active == "stroke" or (self._active == "superpixel" and self._sp_deferred())

    def band_rect(self) -> tuple[int, int, int, int] | None:
        """The rubber band as an inclusive pixel box (x0, y0, x1, y1), clipped to the image, while one is
        dragged; None otherwise."""
        if self._active != "select" or not self._band_moved:
            return None
        H, W = self.session.ann.shape
        ax, ay, bx, by = self._band
        x0, x1 = sorted((int(np.floor(ax)), int(np.floor(bx))))
        y0, y1 = sorted((int(np.floor(ay)), int(np.floor(by))))
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(W - 1, x1), min(H - 1, y1)
        return (x0, y0, x1, y1) if x0 <= x1 and y0 <= y1 else None

    # ----------------------------------------------------------------- helpers
    def _fine(self, mods) -> bool:
        """Fine scale: the panel toggle, inverted while Alt is held."""
        return self.options.fine_scale != bool(mods & Qt.KeyboardModifier.AltModifier)

    def _ensure_current(self) -> int:
        """The light strokes paint into; a new one of the current class when there is none."""
        s = self.session
        cur = s.current_id
        if cur is None or class_of(cur) != s.current_class or not is_light_class(class_of(cur)):
            cmd, cur = new_instance(s.ann, s.current_class)
            s.apply(cmd)
            s.lights_created([cur])  # joins the active group (same undo step: we are inside the stroke)
            s.set_current(cur)
            s.set_selection({cur})
        return cur

    def _select_release(self, band: tuple[int, int, int, int] | None) -> None:
        """A select/group-tool press ended: a click when ``band`` is None, else a rubber band."""
        s = self.session
        mods = self._band_mods
        add = bool(mods & (Qt.KeyboardModifier.ControlModifier | Qt.KeyboardModifier.ShiftModifier)) \
            or self.tool == Tool.GROUP
        self._band, self._band_moved = None, False
        if band is None:  # a click
            x, y = self._band_press_pixel
            self._select_click(x, y, toggle=add)
            return
        x0, y0, x1, y1 = band
        ids = {int(i) for i in np.unique(s.ann.instance_map[y0:y1 + 1, x0:x1 + 1]) if i}
        sel = (s.selection | ids) if add else ids
        lights = [i for i in ids if is_light_class(class_of(i))]
        s.set_selection(sel, current=lights[0] if len(lights) == 1 and not add else None)
        s.message.emit(f"{len(ids)} lights in the box; {len(sel)} selected")

    def _stroke_release(self) -> None:
        """A Ctrl+press ended: a click toggles the light under it; a drag adds every light it passed over.
        With Shift as well (a click too adds) the selection is then grouped, as Ctrl+G does."""
        s = self.session
        group = bool(self._band_mods & Qt.KeyboardModifier.ShiftModifier)
        moved, self._band, self._band_moved, self._stroke_last = self._band_moved, None, False, None
        ids, self._stroke_ids = self._stroke_ids, set()
        pending, self._pending_ids, self._pending_map = self._pending_ids, set(), None
        if pending:  # a stroke accept: the proposals it passed over become lights, selected with the rest
            new = self.proposals.accept(sorted(pending))
            ids |= set(new)
            if not group:
                sel = s.selection | {i for i in ids if is_light_class(class_of(i))}
                s.set_selection(sel)
                s.message.emit(f"accepted {len(new)} proposals under the stroke; {len(sel)} lights selected "
                               "(Ctrl+Shift+drag groups them too)")
                return
        elif not moved and not group:
            x, y = self._band_press_pixel
            self._select_click(x, y, toggle=True)
            return
        lights = {i for i in ids if is_light_class(class_of(i))}
        if group and not lights:  # a slip on the background groups nothing (Ctrl+G is there for that)
            s.message.emit("no light under the stroke: nothing grouped")
            return
        sel = s.selection | lights
        s.set_selection(sel)
        if not group:
            s.message.emit(f"{len(lights)} lights under the stroke; {len(sel)} selected — Ctrl+G groups them "
                           "(Ctrl+Shift+drag groups at once)")
            return
        try:
            _gid, text = s.group_selection()
        except NpsimInputError as exc:
            text = str(exc)
        s.message.emit(text)

    def _select_click(self, x: int, y: int, toggle: bool) -> None:
        s = self.session
        iid = s.instance_at(x, y)
        if toggle:
            if not iid:
                return
            sel = set(s.selection)
            sel.symmetric_difference_update({iid})
            s.set_selection(sel, current=iid if iid in sel else None)
        else:
            s.set_selection({iid} if iid else set())
            s.set_current(iid or None)

    # ----------------------------------------------------------------- superpixel tool
    def _sp_press(self, x: int, y: int, mods) -> None:
        s = self.session
        labels = s.sp_fine if self._fine(mods) else s.sp_coarse
        if labels is None:
            s.message.emit("superpixels (this scale) are still being computed; use the brush meanwhile")
            self._active = None
            return
        H, W = labels.shape
        if not (0 <= x < W and 0 <= y < H):
            self._active = None
            return
        self._labels = labels
        self._touched = set()
        self._seed = int(labels[y, x])
        self._remove = bool(mods & Qt.KeyboardModifier.ShiftModifier)
        s.begin_stroke("remove superpixels" if self._remove else "add superpixels")
        if self._remove:
            self._target = s.current_id
        elif not self.options.split_regions:
            self._target = self._ensure_current()
        else:
            self._target = None
        self._sp_points(np.array([x]), np.array([y]))

    def _sp_deferred(self) -> bool:
        """Splitting into regions and colour filtering need the whole drag: apply on release."""
        return not self._remove and not self._growing and (self.options.split_regions or self.options.similar_only)

    def _grow_start(self) -> None:
        """A right-drag began on a light (the press made it current): the stroke adds the superpixels (the
        brush's disc) it passes over to that light, Shift removes them from it -- one undo step. A touch-up of
        an accepted proposal in one gesture, with *one light per region* on or off (a left stroke there makes
        new lights)."""
        s = self.session
        iid, x, y, mods = self._grow
        xi, yi = int(np.floor(x)), int(np.floor(y))
        self._remove = bool(mods & Qt.KeyboardModifier.ShiftModifier)
        self._target, self._growing, self._last = iid, True, (x, y)
        if self.tool == Tool.SUPERPIXEL:
            labels = s.sp_fine if self._fine(mods) else s.sp_coarse
            if labels is None:
                s.message.emit("superpixels (this scale) are still being computed; use the brush meanwhile")
                self._active, self._growing = None, False
                return
            self._labels, self._touched, self._seed = labels, set(), int(labels[yi, xi])
            self._active = "superpixel"
            s.begin_stroke(f"{'shrink' if self._remove else 'grow'} light {iid}")
            self._sp_points(np.array([xi]), np.array([yi]))
        else:
            self._active = "brush"
            s.begin_stroke(f"{'shrink' if self._remove else 'grow'} light {iid}")
            self._brush_points(np.array([xi]), np.array([yi]))

    def _sp_points(self, xs: np.ndarray, ys: np.ndarray) -> None:
        labels = self._labels
        H, W = labels.shape
        ok = (xs >= 0) & (xs < W) & (ys >= 0) & (ys < H)
        ids = set(np.unique(labels[ys[ok], xs[ok]]).tolist()) - self._touched
        if not ids:
            return
        self._touched |= ids
        if self._sp_deferred():
            return
        idx = superpixel_index(labels, sorted(ids))
        s = self.session
        if self._remove:
            s.apply(erase(s.ann, idx, self._target))
        else:
            s.apply(paint(s.ann, idx, self._target, overwrite=self.options.overwrite))

    def _sp_release(self) -> None:
        if not self._sp_deferred() or not self._touched:
            return
        s = self.session
        ids = sorted(self._touched)
        if self.options.similar_only:
            means = s.sp_means if self._labels is s.sp_coarse else s.sp_fine_means()
            tol = self.options.tolerance if self.options.tolerance > 0 else None
            ids = similar_superpixels(means, ids, self._seed, tol).tolist()
        idx = superpixel_index(self._labels, ids)
        if self.options.split_regions:
            cmd, new_ids = split_paint(s.ann, idx, s.current_class, overwrite=self.options.overwrite)
            s.apply(cmd)
            if new_ids:
                s.lights_created(new_ids)
                s.select_created(new_ids, current=new_ids[-1])
                s.message.emit(f"{len(new_ids)} new {s.current_class_name()} lights, {len(s.selection)} "
                               "selected; Ctrl+G groups them")
        else:
            s.apply(paint(s.ann, idx, self._target, overwrite=self.options.overwrite))

    # ----------------------------------------------------------------- brush / eraser
    def _brush_press(self, x: int, y: int, mods) -> None:
        s = self.session
        self._remove = self.tool == Tool.ERASER or bool(mods & Qt.KeyboardModifier.ShiftModifier)
        s.begin_stroke("erase" if self._remove else "brush")
        if not self._remove:
            self._target = self._ensure_current()
        self._brush_points(np.array([x]), np.array([y]))

    def _brush_points(self, xs: np.ndarray, ys: np.ndarray) -> None:
        s = self.session
        idx = disk_index(s.ann.shape, xs, ys, self.options.brush_radius)
        if idx.size == 0:
            return
        if self._remove:
            s.apply(erase(s.ann, idx, self._target) if self._growing else erase(s.ann, idx))
        else:
            s.apply(paint(s.ann, idx, self._target, overwrite=self.options.overwrite))

    # ----------------------------------------------------------------- fill to superpixel
    def _fill_click(self, x: int, y: int, mods) -> None:
        s = self.session
        labels = s.sp_fine if self._fine(mods) else s.sp_coarse
        iid = s.instance_at(x, y) or s.current_id
        if labels is None or not iid:
            s.message.emit("fill: click a light (superpixels must be ready)")
            return
        s.apply(snap_to_superpixels(s.ann, iid, labels, overwrite=self.options.overwrite))
        s.set_selection({iid}, current=iid)
