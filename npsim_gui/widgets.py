"""Small reusable widgets: a slider with numeric entry (linear or log scale),
an image view with zoom/pan, a loss-curve plot and a log strip."""

from __future__ import annotations

import math

import numpy as np
from PySide6.QtCore import QPointF, QRectF, QSize, Qt, Signal
from PySide6.QtGui import QColor, QImage, QPainter, QPainterPath, QPen, QPixmap
from PySide6.QtWidgets import (QDoubleSpinBox, QGraphicsPixmapItem, QGraphicsScene, QGraphicsView, QHBoxLayout,
                               QLabel, QPlainTextEdit, QSlider, QWidget)


def qimage_from_rgb(rgb: np.ndarray) -> QImage:
    """HxWx3 uint8 RGB (or HxW grey) -> a QImage that owns a copy of the pixels."""
    a = np.ascontiguousarray(rgb)
    if a.ndim == 2:
        h, w = a.shape
        return QImage(a.data, w, h, a.strides[0], QImage.Format.Format_Grayscale8).copy()
    h, w, c = a.shape
    fmt = QImage.Format.Format_RGB888 if c == 3 else QImage.Format.Format_RGBA8888
    return QImage(a.data, w, h, a.strides[0], fmt).copy()


class ValueSlider(QWidget):
    """Label + slider + spin box for one float parameter, linear or log10 scale.

    Emits ``valueChanged(float)`` on every user change (the owner debounces).
    """

    valueChanged = Signal(float)
    STEPS = 1000

    def __init__(self, label: str, lo: float, hi: float, value: float, *, log: bool = False,
                 decimals: int = 3, integer: bool = False, tooltip: str = "", parent: QWidget | None = None):
        super().__init__(parent)
        if log and lo <= 0:
            raise ValueError("log sliders need lo > 0")
        self.lo, self.hi, self.log, self.integer = lo, hi, log, integer
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        self.label = QLabel(label)
        self.label.setMinimumWidth(80)
        self.slider = QSlider(Qt.Orientation.Horizontal)
        self.slider.setRange(0, self.STEPS)
        self.spin = QDoubleSpinBox()
        self.spin.setDecimals(0 if integer else decimals)
        self.spin.setRange(lo, hi)
        self.spin.setKeyboardTracking(False)
        self.spin.setMinimumWidth(70)
        if log:
            self.spin.setStepType(QDoubleSpinBox.StepType.AdaptiveDecimalStepType)
        for w in (self.label, self.slider, self.spin):
            w.setToolTip(tooltip)
        lay.addWidget(self.label)
        lay.addWidget(self.slider, 1)
        lay.addWidget(self.spin)
        self._block = False
        self.setValue(value)
        self.slider.valueChanged.connect(self._from_slider)
        self.spin.valueChanged.connect(self._from_spin)

    def _to_pos(self, v: float) -> int:
        v = min(max(v, self.lo), self.hi)
        if self.log:
            t = (math.log10(v) - math.log10(self.lo)) / (math.log10(self.hi) - math.log10(self.lo))
        else:
            t = (v - self.lo) / (self.hi - self.lo) if self.hi > self.lo else 0.0
        return int(round(t * self.STEPS))

    def _from_pos(self, pos: int) -> float:
        t = pos / self.STEPS
        if self.log:
            v = 10 ** (math.log10(self.lo) + t * (math.log10(self.hi) - math.log10(self.lo)))
            v = float(f"{v:.3g}")
        else:
            v = self.lo + t * (self.hi - self.lo)
        return float(round(v)) if self.integer else v

    def value(self) -> float:
        return float(self.spin.value())

    def setValue(self, v: float) -> None:
        self._block = True
        self.spin.setValue(v)
        self.slider.setValue(self._to_pos(v))
        self._block = False

    def _from_slider(self, pos: int) -> None:
        if self._block:
            return
        self._block = True
        self.spin.setValue(self._from_pos(pos))
        self._block = False
        self.valueChanged.emit(self.value())

    def _from_spin(self, v: float) -> None:
        if self._block:
            return
        self._block = True
        self.slider.setValue(self._to_pos(v))
        self._block = False
        self.valueChanged.emit(self.value())


class ImageView(QGraphicsView):
    """Zoomable (wheel, anchored under the mouse), pannable (drag) image display."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self._scene = QGraphicsScene(self)
        self.setScene(self._scene)
        self._item = QGraphicsPixmapItem()
        self._item.setTransformationMode(Qt.TransformationMode.FastTransformation)
        self._scene.addItem(self._item)
        self.setDragMode(QGraphicsView.DragMode.ScrollHandDrag)
        self.setTransformationAnchor(QGraphicsView.ViewportAnchor.AnchorUnderMouse)
        self.setBackgroundBrush(QColor(32, 32, 32))
        self._fitted = False

    def sizeHint(self) -> QSize:  # noqa: N802 (Qt API)
        # QGraphicsView asks for its scene's size (up to 2/3 of the screen): a 2048-px night made the
        # night preview's dock take the room of the annotation canvas. It fits whatever it gets.
        return QSize(320, 200)

    def set_image(self, rgb: np.ndarray) -> None:
        first = self._item.pixmap().isNull() or self._item.pixmap().size().width() != rgb.shape[1]
        self._item.setPixmap(QPixmap.fromImage(qimage_from_rgb(rgb)))
        self._scene.setSceneRect(QRectF(0, 0, rgb.shape[1], rgb.shape[0]))
        if first or not self._fitted:
            self.fit()

    def fit(self) -> None:
        self.fitInView(self._scene.sceneRect(), Qt.AspectRatioMode.KeepAspectRatio)
        self._fitted = True

    def wheelEvent(self, event) -> None:  # noqa: N802 (Qt naming)
        factor = 1.2 ** (event.angleDelta().y() / 120.0)
        self.scale(factor, factor)

    def resizeEvent(self, event) -> None:  # noqa: N802
        super().resizeEvent(event)
        if self._fitted:
            self.fit()


class LossPlot(QWidget):
    """Log-scale loss curves (total and per term) drawn with QPainter."""

    COLORS = {"total": QColor(240, 240, 240), "normal": QColor(90, 170, 255), "continuity": QColor(255, 170, 60),
              "depth": QColor(120, 220, 120)}

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.series: dict[str, list[float]] = {}
        self.setMinimumHeight(80)  # the log strip under the canvas stays low: the canvas gets the height

    def set_history(self, series: dict[str, list[float]]) -> None:
        self.series = {k: [float(x) for x in v] for k, v in series.items() if len(v)}
        self.update()

    def paintEvent(self, event) -> None:  # noqa: N802
        p = QPainter(self)
        p.fillRect(self.rect(), QColor(24, 24, 28))
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        vals = [v for s in self.series.values() for v in s if v > 0 and math.isfinite(v)]
        if not vals:
            p.setPen(QColor(150, 150, 150))
            p.drawText(self.rect(), Qt.AlignmentFlag.AlignCenter, "loss curve: run a refinement")
            return
        lo, hi = math.log10(min(vals)), math.log10(max(vals))
        hi = hi if hi > lo else lo + 1
        n = max(len(s) for s in self.series.values())
        m = 34
        w, h = self.width() - m - 8, self.height() - 24
        p.setPen(QColor(90, 90, 90))
        p.drawRect(m, 6, w, h)
        p.drawText(2, 16, f"{10 ** hi:.2g}")
        p.drawText(2, h + 4, f"{10 ** lo:.2g}")
        x_lab = 8
        for name, s in self.series.items():
            col = self.COLORS.get(name, QColor(200, 120, 220))
            path = QPainterPath()
            started = False
            for i, v in enumerate(s):
                if not (v > 0 and math.isfinite(v)):
                    continue
                pt = QPointF(m + w * i / max(n - 1, 1), 6 + h * (1 - (math.log10(v) - lo) / (hi - lo)))
                if started:
                    path.lineTo(pt)
                else:
                    path.moveTo(pt)
                    started = True
            p.setPen(QPen(col, 1.6))
            p.drawPath(path)
            p.drawText(m + x_lab, self.height() - 4, name)
            x_lab += 8 + p.fontMetrics().horizontalAdvance(name) + 10
        p.end()


class LogStrip(QPlainTextEdit):
    """Read-only, bounded log of timings and messages."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        self.setReadOnly(True)
        self.setMaximumBlockCount(500)
        self.setMaximumHeight(110)

    def log(self, text: str) -> None:
        self.appendPlainText(text)
