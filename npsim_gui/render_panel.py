"""Render preview panel: the progressive night image, a day/night split slider,
light toggles per group / instance, a resample-seed button and the denoiser choice."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (QComboBox, QHBoxLayout, QLabel, QPushButton, QSlider, QSpinBox, QTreeWidget,
                               QTreeWidgetItem, QVBoxLayout, QWidget, QSplitter, QSizePolicy)

from npsim_core.labels import light_class

from .widgets import ImageView


def split_view(day: np.ndarray, night: np.ndarray, fraction: float) -> np.ndarray:
    """Left ``fraction`` of the frame from ``day``, the rest from ``night`` (same size), with a divider."""
    h, w = night.shape[:2]
    if day.shape[:2] != (h, w):
        import cv2
        day = cv2.resize(day, (w, h), interpolation=cv2.INTER_AREA)
    out = night.copy()
    x = int(round(np.clip(fraction, 0, 1) * w))
    out[:, :x] = day[:, :x]
    if 0 < x < w:
        out[:, max(0, x - 1):x + 1] = (255, 210, 60)
    return out


class RenderPanel(QWidget):
    """Shows the night preview; emits the user's light choices, seed and denoiser changes."""

    lightsToggled = Signal(dict)  # {instance_id: bool} overrides
    seedChanged = Signal(int)
    denoiserChanged = Signal(str)  # night.denoiser: oidn, guided or none
    renderRequested = Signal()

    #: The denoisers offered (``night.denoiser``) and their tool tips.
    DENOISERS = (("oidn", "Intel Open Image Denoise, guided by the scene's albedo and normals"),
                 ("guided", "the mesh-guided à-trous filter (depth, normals, labels)"),
                 ("none", "no denoising: the raw Monte Carlo noise (isolated fireflies removed)"))

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        bar = QHBoxLayout()
        self.seed = QSpinBox()
        self.seed.setRange(0, 2 ** 31 - 1)
        self.seed.setPrefix("seed ")
        self.resample = QPushButton("Resample")
        self.resample.setToolTip("Draw a new night: another seed for the light activation")
        self.render_btn = QPushButton("Render")
        self.denoiser = QComboBox()
        for i, (name, tip) in enumerate(self.DENOISERS):
            self.denoiser.addItem(name, name)
            self.denoiser.setItemData(i, tip, Qt.ItemDataRole.ToolTipRole)
        self.denoiser.setToolTip("Monte Carlo denoiser of the night (night.denoiser)")
        self.status = QLabel("no render yet")
        # a long status (an error, the render's numbers) wraps instead of widening the dock over the canvas
        self.status.setWordWrap(True)
        self.status.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.split = QSlider(Qt.Orientation.Horizontal)
        self.split.setRange(0, 100)
        self.split.setValue(0)
        self.split.setToolTip("Day / night split: drag to compare with the input photo")
        bar.addWidget(self.seed, 1)
        bar.addWidget(self.resample)
        lay.addLayout(bar)
        bar2 = QHBoxLayout()  # a second row keeps the dock narrow (small screens)
        bar2.addWidget(self.denoiser, 1)
        bar2.addWidget(self.render_btn)
        lay.addLayout(bar2)
        split_row = QHBoxLayout()
        split_row.addWidget(QLabel("day | night"))
        split_row.addWidget(self.split, 1)
        lay.addLayout(split_row)
        splitter = QSplitter(Qt.Orientation.Vertical)  # the picture on top, the light list below
        self.view = ImageView()
        self.lights = QTreeWidget()
        self.lights.setHeaderLabels(["light", "on"])
        self.lights.setColumnWidth(0, 220)
        splitter.addWidget(self.view)
        splitter.addWidget(self.lights)
        splitter.setStretchFactor(0, 3)
        splitter.setStretchFactor(1, 1)
        splitter.setSizes([320, 110])
        lay.addWidget(splitter, 1)
        lay.addWidget(self.status)
        self.day: np.ndarray | None = None
        self._day_at: tuple | None = None
        self.night: np.ndarray | None = None
        self._filling = False
        self.split.valueChanged.connect(self._refresh)
        self.resample.clicked.connect(lambda: self.seed.setValue((self.seed.value() * 1103515245 + 12345) % 2 ** 31))
        self.seed.valueChanged.connect(self.seedChanged.emit)
        self.denoiser.currentIndexChanged.connect(lambda _i: self.denoiserChanged.emit(self.denoiser.currentData()))
        self.render_btn.clicked.connect(self.renderRequested.emit)
        self.lights.itemChanged.connect(self._on_item)

    def set_denoiser(self, name: str) -> None:
        """Show ``name`` (``night.denoiser``) without emitting :attr:`denoiserChanged`."""
        i = self.denoiser.findData(name)
        if i >= 0 and i != self.denoiser.currentIndex():
            self.denoiser.blockSignals(True)
            self.denoiser.setCurrentIndex(i)
            self.denoiser.blockSignals(False)

    #: The dimmed day shown before the first night is at most this wide (display only: the dock is
    #: a few hundred pixels wide; a 2048-px placeholder cost 60 ms of conversions on the GUI thread).
    PLACEHOLDER_WIDTH = 1024

    def set_day(self, rgb: np.ndarray) -> None:
        self.day = rgb
        self._day_at = None  # (shape, day resized to it) for the split view
        self._refresh()

    def _day_like(self, night: np.ndarray) -> np.ndarray:
        """The day at the night's size, resized once per size (not on every split-slider move)."""
        import cv2

        h, w = night.shape[:2]
        if self.day.shape[:2] == (h, w):
            return self.day
        if self._day_at is None or self._day_at[0] != (h, w):
            self._day_at = ((h, w), cv2.resize(self.day, (w, h), interpolation=cv2.INTER_AREA))
        return self._day_at[1]

    def clear_night(self, status: str = "no render yet") -> None:
        """Forget the night shown (another frame opens): the dimmed day stands in until the next one."""
        self.night = None
        self.status.setText(status)
        self._refresh()

    def set_night(self, rgb: np.ndarray, status: str = "", realism: dict | None = None) -> None:
        """Show a night; ``realism`` (``NightFrame.realism``) is added to the status line and its tool tip."""
        self.night = rgb
        if realism:
            from npsim_core.realism import format_realism

            text = format_realism(realism)
            status = f"{status} · {text.splitlines()[0]}" if status else text.splitlines()[0]
            self.status.setToolTip(text)
        if status:
            self.status.setText(status)
        self._refresh()

    def _refresh(self) -> None:
        if self.night is None:
            if self.day is not None:
                day = self.day
                if day.shape[1] > self.PLACEHOLDER_WIDTH:
                    import cv2

                    k = self.PLACEHOLDER_WIDTH / day.shape[1]
                    day = cv2.resize(day, (self.PLACEHOLDER_WIDTH, max(1, round(day.shape[0] * k))),
                                     interpolation=cv2.INTER_AREA)
                self.view.set_image(day >> 2)  # a quarter of the brightness: "no night yet"
            return
        frac = self.split.value() / 100.0
        img = split_view(self._day_like(self.night), self.night, frac) \
            if (self.day is not None and frac > 0) else self.night
        self.view.set_image(img)

    def set_lights(self, groups: dict[int, list[int]], singles: list[int], state: dict[int, bool]) -> None:
        """Fill the toggle tree: groups with their members, then ungrouped lights."""
        self._filling = True
        self.lights.clear()
        for gid, members in sorted(groups.items()):
            g = QTreeWidgetItem([f"{light_class(gid // 1000).name} #{gid % 1000}", ""])
            g.setData(0, Qt.ItemDataRole.UserRole, gid)
            g.setFlags(g.flags() | Qt.ItemFlag.ItemIsUserCheckable | Qt.ItemFlag.ItemIsAutoTristate)
            for m in members:
                it = QTreeWidgetItem([f"{light_class(m // 1000).name} #{m % 1000}", ""])
                it.setData(0, Qt.ItemDataRole.UserRole, m)
                it.setFlags(it.flags() | Qt.ItemFlag.ItemIsUserCheckable)
                it.setCheckState(1, Qt.CheckState.Checked if state.get(m) else Qt.CheckState.Unchecked)
                g.addChild(it)
            self.lights.addTopLevelItem(g)
        for m in singles:
            it = QTreeWidgetItem([f"{light_class(m // 1000).name} #{m % 1000}", ""])
            it.setData(0, Qt.ItemDataRole.UserRole, m)
            it.setFlags(it.flags() | Qt.ItemFlag.ItemIsUserCheckable)
            it.setCheckState(1, Qt.CheckState.Checked if state.get(m) else Qt.CheckState.Unchecked)
            self.lights.addTopLevelItem(it)
        self._filling = False

    def light_state(self) -> dict[int, bool]:
        out: dict[int, bool] = {}
        for i in range(self.lights.topLevelItemCount()):
            top = self.lights.topLevelItem(i)
            items = [top.child(j) for j in range(top.childCount())] or [top]
            for it in items:
                out[int(it.data(0, Qt.ItemDataRole.UserRole))] = it.checkState(1) == Qt.CheckState.Checked
        return out

    def _on_item(self, item: QTreeWidgetItem, column: int) -> None:
        if self._filling or column != 1:
            return
        self.lightsToggled.emit(self.light_state())
