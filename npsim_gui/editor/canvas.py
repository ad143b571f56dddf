"""The annotation canvas: a QGraphicsView showing the image and its overlay layers.

Scene coordinates are image pixels: pixel (u, v) covers the square
[u, u+1) x [v, v+1). Layers (bottom to top): base image, semantic labels,
superpixel borders, light masks, group boxes, brush cursor. Each array layer
wraps a numpy RGBA buffer in a QImage without copying; an edit updates the
buffer's changed rectangle and repaints only that.

Navigation: wheel zooms anchored under the mouse; middle button or Space+left
drag pans; Home fits the image. Mouse events in image coordinates go to
``self.handler`` (any object with ``press/move/release(x, y, event)``) so tools
stay outside the view; a handler may offer ``shows_path()`` (draw the drag path)
and ``band_rect()`` (draw a selection rectangle).

Display adjustment (brightness, contrast, gamma; :meth:`EditorCanvas.set_display`)
changes only the pixels shown for the base image, never the image data.
"""

from __future__ import annotations

import cv2
import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QBrush, QColor, QFont, QImage, QPainter, QPainterPath, QPen
from PySide6.QtWidgets import (QGraphicsEllipseItem, QGraphicsItem, QGraphicsPathItem, QGraphicsRectItem,
                               QGraphicsScene,
                               QGraphicsSimpleTextItem, QGraphicsView, QStyleOptionGraphicsItem)


class ArrayLayerItem(QGraphicsItem):
    """A graphics item painting an (H, W, 4) uint8 RGBA numpy buffer (no copy)."""

    def __init__(self, rgba: np.ndarray | None = None, parent=None) -> None:
        super().__init__(parent)
        self.setFlag(QGraphicsItem.GraphicsItemFlag.ItemUsesExtendedStyleOption, True)
        # Repaints (any change in the window, a brush dab) blit a screen-sized copy of the layer
        # instead of scaling and blending the whole 2048x1024 RGBA buffer again (30-80 ms a
        # window repaint at 2048x1024 with three layers); update(rect) redraws only that part of it.
        self.setCacheMode(QGraphicsItem.CacheMode.DeviceCoordinateCache)
        self._arr = np.zeros((1, 1, 4), np.uint8)
        self._img = QImage()
        self._content: QRectF | None = None  # where the buffer may be non-transparent (None: anywhere)
        if rgba is not None:
            self.set_array(rgba)

    @property
    def array(self) -> np.ndarray:
        return self._arr

    @property
    def content_rect(self) -> QRectF | None:
        """The box painted (pixels): the rest of the buffer is known to be transparent. None: all."""
        return self._content

    def set_array(self, rgba: np.ndarray, content: tuple[int, int, int, int] | None | str = "all") -> None:
        """Show ``rgba`` (HxWx4, wrapped without a copy). ``content``: the (x0, y0, x1, y1) box
        outside which it is transparent, None when it is all transparent, "all" (default) when unknown:
        a 2048x1024 layer costs every repaint 20-40 ms of blending, also where it is empty."""
        arr = np.ascontiguousarray(rgba, dtype=np.uint8)
        if arr.ndim != 3 or arr.shape[2] != 4:
            raise ValueError(f"layer arrays must be HxWx4 RGBA, got {arr.shape}")
        self.prepareGeometryChange()
        self._arr = arr
        h, w = arr.shape[:2]
        self._img = QImage(arr.data, w, h, 4 * w, QImage.Format.Format_RGBA8888)
        if isinstance(content, str):
            self._content = None if content == "all" else QRectF()
        else:
            self._content = QRectF() if content is None else self._box(content)
        self.update()

    @staticmethod
    def _box(rect: tuple[int, int, int, int]) -> QRectF:
        x0, y0, x1, y1 = rect
        return QRectF(x0, y0, x1 - x0, y1 - y0)

    def update_rect(self, rect: tuple[int, int, int, int] | None) -> None:
        """Repaint the (x0, y0, x1, y1) pixel box after its buffer region changed (None: anywhere)."""
        if rect is None:
            self._content = None
            self.update()
        else:
            box = self._box(rect)
            if self._content is not None:
                self._content = box if self._content.isEmpty() else self._content.united(box)
            self.update(box)

    def boundingRect(self) -> QRectF:  # noqa: N802 (Qt API)
        return QRectF(0, 0, self._arr.shape[1], self._arr.shape[0])

    def paint(self, painter: QPainter, option: QStyleOptionGraphicsItem, widget=None) -> None:
        if self._img.isNull():
            return
        r = option.exposedRect.intersected(self.boundingRect())
        if self._content is not None:
            r = r.intersected(self._content)
        if r.isEmpty():
            return
        # Whole pixels only, so the source and target rectangles match exactly.
        x0, y0 = int(np.floor(r.left())), int(np.floor(r.top()))
        x1, y1 = int(np.ceil(r.right())), int(np.ceil(r.bottom()))
        target = QRectF(x0, y0, x1 - x0, y1 - y0)
        painter.setRenderHint(QPainter.RenderHint.SmoothPixmapTransform, False)
        painter.drawImage(target, self._img, target)


def display_lut(brightness: float = 0.0, contrast: float = 1.0, gamma: float = 1.0) -> np.ndarray | None:
    """uint8 LUT for ``v' = (v**(1/gamma) + brightness - 0.5) * contrast + 0.5`` on v in [0, 1]
    (brightness as a fraction of full scale, added before the contrast gain about mid-grey);
    None for the identity."""
    if brightness == 0 and contrast == 1 and gamma == 1:
        return None
    v = np.arange(256, dtype=np.float64) / 255.0
    v = (v ** (1.0 / max(gamma, 1e-3)) + brightness - 0.5) * contrast + 0.5
    return np.clip(np.round(v * 255.0), 0, 255).astype(np.uint8)


def auto_display(rgb: np.ndarray, low: float = 1.0, high: float = 99.0) -> tuple[float, float, float]:
    """(brightness, contrast, gamma) mapping the ``low``..``high`` luminance percentiles to 0..1:
    brightness centres the range on mid-grey (always within +-0.5), contrast stretches it."""
    lum = np.asarray(rgb, np.float32)[::2, ::2] @ np.array([0.299, 0.587, 0.114], np.float32)
    lo, hi = (float(v) / 255.0 for v in np.percentile(lum, [low, high]))
    if hi - lo < 1e-3:
        return 0.0, 1.0, 1.0
    contrast = float(np.clip(1.0 / (hi - lo), 0.1, 10.0))
    return 0.5 - (lo + hi) / 2, contrast, 1.0


class EditorCanvas(QGraphicsView):
    """Zoomable, pannable view of an image with toggleable overlay layers."""

    #: Emitted with the image pixel under the mouse (x, y) or (-1, -1) outside.
    hovered = Signal(int, int)
    #: Emitted after the zoom factor changed.
    zoomChanged = Signal(float)

    LAYERS = ("labels", "superpixels", "lights", "proposals")

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.setScene(QGraphicsScene(self))
        self.setBackgroundBrush(QBrush(QColor(38, 40, 44)))
        self.setTransformationAnchor(QGraphicsView.ViewportAnchor.AnchorUnderMouse)
        self.setResizeAnchor(QGraphicsView.ViewportAnchor.AnchorViewCenter)
        self.setViewportUpdateMode(QGraphicsView.ViewportUpdateMode.MinimalViewportUpdate)
        self.setDragMode(QGraphicsView.DragMode.NoDrag)
        self.setMouseTracking(True)
        self.setFocusPolicy(Qt.FocusPolicy.StrongFocus)
        self.handler = None
        self.base = ArrayLayerItem()
        self.layers = {name: ArrayLayerItem() for name in self.LAYERS}
        self.scene().addItem(self.base)
        for z, name in enumerate(self.LAYERS, start=1):
            self.layers[name].setZValue(z)
            self.scene().addItem(self.layers[name])
        self.layers["labels"].setOpacity(0.35)
        self.layers["superpixels"].setOpacity(0.35)
        self.layers["lights"].setOpacity(0.85)
        self.layers["proposals"].setOpacity(1.0)  # its RGBA carries the translucency (editor.proposals)
        self._group_items: list[QGraphicsItem] = []
        self.cursor_item = QGraphicsEllipseItem()
        self.cursor_item.setPen(QPen(QColor(255, 255, 255), 0))
        self.cursor_item.setZValue(50)
        self.cursor_item.setVisible(False)
        self.scene().addItem(self.cursor_item)
        self.path_item = QGraphicsPathItem()  # the drag path, for tools that act on release
        pen = QPen(QColor(255, 80, 200), 0)
        pen.setCosmetic(True)
        pen.setWidthF(2.0)
        self.path_item.setPen(pen)
        self.path_item.setZValue(49)
        self.scene().addItem(self.path_item)
        self._path = QPainterPath()
        # Rubber band of the select tool: a black line under a white dashed one (visible on any image).
        self.band_item = QGraphicsRectItem()
        self._band_dash = QGraphicsRectItem(self.band_item)
        for it, color, style in ((self.band_item, QColor(0, 0, 0), Qt.PenStyle.SolidLine),
                                 (self._band_dash, QColor(255, 255, 255), Qt.PenStyle.DashLine)):
            bpen = QPen(color, 0)
            bpen.setCosmetic(True)
            bpen.setStyle(style)
            it.setPen(bpen)
        self.band_item.setBrush(QBrush(QColor(255, 255, 255, 40)))
        self.band_item.setZValue(48)
        self.band_item.setVisible(False)
        self.scene().addItem(self.band_item)
        self._base_source = np.zeros((1, 1, 3), np.uint8)  # the base image as given, before display adjustment
        self.display = (0.0, 1.0, 1.0)  # brightness, contrast, gamma
        self.brush_radius = 0.0
        self._pan_last: QPointF | None = None
        self._space = False
        self._pressed = False
        self._auto_fit = True  # keep fitting on resize until the user zooms

    # ----------------------------------------------------------------- content
    def set_base_image(self, rgb: np.ndarray) -> None:
        """Show ``rgb`` (HxWx3 uint8) under the overlays (the image, or e.g. a depth view)."""
        rgb = np.asarray(rgb)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"base image must be HxWx3 uint8 RGB, got {rgb.shape} {rgb.dtype}")
        self._base_source = rgb
        self._show_base()

    def set_display(self, brightness: float = 0.0, contrast: float = 1.0, gamma: float = 1.0) -> None:
        """Adjust how the base image is shown (display only: the arrays given are never changed)."""
        self.display = (float(brightness), float(contrast), float(gamma))
        self._show_base()

    def auto_display(self) -> tuple[float, float, float]:
        """Settings that stretch the shown base image's 1-99 % luminance range (not applied)."""
        return auto_display(self._base_source)

    def _show_base(self) -> None:
        rgb = np.ascontiguousarray(self._base_source)
        lut = display_lut(*self.display)
        # OpenCV passes (LUT, RGB -> RGBA): 5 ms instead of 40 ms for a 2048x1024 view
        arr = cv2.cvtColor(rgb if lut is None else cv2.LUT(rgb, lut), cv2.COLOR_RGB2RGBA)
        first = self.base.array.shape[:2] != arr.shape[:2]
        self.base.set_array(arr)
        self.scene().setSceneRect(QRectF(0, 0, arr.shape[1], arr.shape[0]))
        if first:
            self.fit()

    def set_layer(self, name: str, rgba: np.ndarray) -> None:
        self.layers[name].set_array(rgba)

    def set_layer_visible(self, name: str, visible: bool) -> None:
        self.layers[name].setVisible(visible)

    def set_layer_opacity(self, name: str, opacity: float) -> None:
        self.layers[name].setOpacity(float(opacity))

    def set_group_boxes(self, boxes: list[tuple]) -> None:
        """Draw dashed boxes: (group id, [x0, y0, x1, y1] inclusive, colour, caption[, active]); empty
        caption = none; an active group (new lights join it) gets a thicker solid line."""
        for it in self._group_items:
            self.scene().removeItem(it)
        self._group_items = []
        for gid, b, color, caption, *rest in boxes:
            active = bool(rest and rest[0])
            pen = QPen(QColor(*color), 0)
            pen.setStyle(Qt.PenStyle.SolidLine if active else Qt.PenStyle.DashLine)
            pen.setCosmetic(True)
            pen.setWidthF(2.5 if active else 1.5)
            r = QGraphicsRectItem(QRectF(b[0] - 0.5, b[1] - 0.5, b[2] - b[0] + 2, b[3] - b[1] + 2))
            r.setPen(pen)
            r.setZValue(10)
            self.scene().addItem(r)
            self._group_items.append(r)
            if not caption:
                continue
            t = QGraphicsSimpleTextItem(caption)
            t.setBrush(QBrush(QColor(*color)))
            f = QFont()
            f.setPointSizeF(8)
            t.setFont(f)
            t.setFlag(QGraphicsItem.GraphicsItemFlag.ItemIgnoresTransformations, True)
            t.setPos(b[0] - 0.5, b[1] - 0.5)
            t.setZValue(11)
            self.scene().addItem(t)
            self._group_items.append(t)
            t.moveBy(0, -t.boundingRect().height() / max(self.zoom(), 1e-6))

    # ----------------------------------------------------------------- navigation
    def zoom(self) -> float:
        return float(self.transform().m11())

    def set_zoom(self, factor: float) -> None:
        self._auto_fit = False
        factor = float(np.clip(factor, 0.05, 64.0))
        self.scale(factor / self.zoom(), factor / self.zoom())
        self.zoomChanged.emit(self.zoom())

    def resizeEvent(self, event) -> None:  # noqa: N802
        super().resizeEvent(event)
        if self._auto_fit:
            self.fit()

    def fit(self) -> None:
        self._auto_fit = True
        r = self.scene().sceneRect()
        if r.width() > 0:
            self.fitInView(r, Qt.AspectRatioMode.KeepAspectRatio)
            self.zoomChanged.emit(self.zoom())

    def wheelEvent(self, event) -> None:  # noqa: N802
        delta = event.angleDelta().y() or event.angleDelta().x()
        if not delta:
            return
        self._auto_fit = False
        factor = 1.0015 ** delta  # 120 per notch -> ~20 % per notch, smooth on touchpads
        new = float(np.clip(self.zoom() * factor, 0.05, 64.0))
        f = new / self.zoom()
        # Keep the image point under the wheel event's position fixed (explicitly: Qt's
        # AnchorUnderMouse uses the last mouse *move*, which may be stale).
        pos = event.position().toPoint()
        anchor = self.mapToScene(pos)
        self.setTransformationAnchor(QGraphicsView.ViewportAnchor.NoAnchor)
        self.scale(f, f)
        self.setTransformationAnchor(QGraphicsView.ViewportAnchor.AnchorUnderMouse)
        moved = self.mapFromScene(anchor) - pos
        self.horizontalScrollBar().setValue(self.horizontalScrollBar().value() + moved.x())
        self.verticalScrollBar().setValue(self.verticalScrollBar().value() + moved.y())
        self.zoomChanged.emit(self.zoom())
        event.accept()

    def image_pos(self, view_pos) -> tuple[float, float]:
        p = self.mapToScene(view_pos.toPoint() if hasattr(view_pos, "toPoint") else view_pos)
        return p.x(), p.y()

    def _image_size(self) -> tuple[int, int]:
        return self.base.array.shape[1], self.base.array.shape[0]

    def keyPressEvent(self, event) -> None:  # noqa: N802
        if event.key() == Qt.Key.Key_Space and not event.isAutoRepeat():
            self._space = True
            self.viewport().setCursor(Qt.CursorShape.OpenHandCursor)
            event.accept()
            return
        if event.key() == Qt.Key.Key_Home:
            self.fit()
            return
        super().keyPressEvent(event)

    def keyReleaseEvent(self, event) -> None:  # noqa: N802
        if event.key() == Qt.Key.Key_Space and not event.isAutoRepeat():
            self._space = False
            self.viewport().unsetCursor()
            event.accept()
            return
        super().keyReleaseEvent(event)

    def mousePressEvent(self, event) -> None:  # noqa: N802
        self.setFocus()
        if event.button() == Qt.MouseButton.MiddleButton or (
                event.button() == Qt.MouseButton.LeftButton and self._space):
            self._pan_last = event.position()
            self.viewport().setCursor(Qt.CursorShape.ClosedHandCursor)
            event.accept()
            return
        if self.handler is not None and event.button() in (Qt.MouseButton.LeftButton, Qt.MouseButton.RightButton):
            self._pressed = True
            x, y = self.image_pos(event.position())
            self._path = QPainterPath(QPointF(x, y))
            self.handler.press(x, y, event)
            self.path_item.setVisible(bool(getattr(self.handler, "shows_path", lambda: False)()))
            self.path_item.setPath(self._path)
            event.accept()
            return
        super().mousePressEvent(event)

    def mouseMoveEvent(self, event) -> None:  # noqa: N802
        if self._pan_last is not None:
            d = event.position() - self._pan_last
            self._pan_last = event.position()
            self.horizontalScrollBar().setValue(self.horizontalScrollBar().value() - int(round(d.x())))
            self.verticalScrollBar().setValue(self.verticalScrollBar().value() - int(round(d.y())))
            event.accept()
            return
        x, y = self.image_pos(event.position())
        self._move_cursor(x, y)
        W, H = self._image_size()
        inside = 0 <= x < W and 0 <= y < H
        self.hovered.emit(int(np.floor(x)) if inside else -1, int(np.floor(y)) if inside else -1)
        if self._pressed and self.handler is not None:
            self.handler.move(x, y, event)
            if self.path_item.isVisible():
                self._path.lineTo(QPointF(x, y))
                self.path_item.setPath(self._path)
            self._update_band()
            event.accept()
            return
        super().mouseMoveEvent(event)

    def mouseReleaseEvent(self, event) -> None:  # noqa: N802
        if self._pan_last is not None and event.button() in (Qt.MouseButton.MiddleButton, Qt.MouseButton.LeftButton):
            self._pan_last = None
            self.viewport().setCursor(Qt.CursorShape.OpenHandCursor if self._space else Qt.CursorShape.ArrowCursor)
            event.accept()
            return
        if self._pressed and self.handler is not None:
            self._pressed = False
            x, y = self.image_pos(event.position())
            self.handler.release(x, y, event)
            self.path_item.setVisible(False)
            self.band_item.setVisible(False)
            event.accept()
            return
        super().mouseReleaseEvent(event)

    def mouseDoubleClickEvent(self, event) -> None:  # noqa: N802
        # Qt sends press, release, double-click, release: the first click has acted already; the
        # handler may give the double-click a meaning (activate a group), else it is swallowed as before.
        if (self._pan_last is None and not self._space and self.handler is not None
                and hasattr(self.handler, "double_click")):
            x, y = self.image_pos(event.position())
            if self.handler.double_click(x, y, event):
                event.accept()
                return
        super().mouseDoubleClickEvent(event)

    def _update_band(self) -> None:
        band = getattr(self.handler, "band_rect", lambda: None)()
        if band is None:
            self.band_item.setVisible(False)
            return
        x0, y0, x1, y1 = band  # inclusive pixel box
        r = QRectF(x0, y0, x1 - x0 + 1, y1 - y0 + 1)
        self.band_item.setRect(r)
        self._band_dash.setRect(r)
        self.band_item.setVisible(True)

    def set_brush_radius(self, radius: float) -> None:
        """Show a circle of ``radius`` px around the mouse (0 hides it)."""
        self.brush_radius = float(radius)
        self.cursor_item.setVisible(radius > 0)

    def _move_cursor(self, x: float, y: float) -> None:
        if self.brush_radius > 0:
            r = self.brush_radius + 0.5
            cx, cy = np.floor(x) + 0.5, np.floor(y) + 0.5
            self.cursor_item.setRect(QRectF(cx - r, cy - r, 2 * r, 2 * r))

    def view_point(self, x: float, y: float):
        """Viewport point (QPoint) of image coordinate (x, y) (tests drive the mouse with it)."""
        return self.mapFromScene(QPointF(x, y))
