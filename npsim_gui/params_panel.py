"""Parameter panel: grouped sliders with numeric entry, presets and reset.

The panel knows only *where* each value lives (``section.field`` of the core's
:class:`~npsim_core.chain.ChainParams`) and its range; it emits
``changed(section, field, value)`` and the window hands the new parameters to
the core, which recomputes only the stages downstream of the change.
"""

from __future__ import annotations

from dataclasses import dataclass

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (QCheckBox, QComboBox, QFormLayout, QGroupBox, QHBoxLayout, QPushButton, QScrollArea,
                               QVBoxLayout, QWidget)

from npsim_core.labels import light_classes

from .widgets import ValueSlider


@dataclass(frozen=True)
class SliderSpec:
    section: str
    field: str
    label: str
    lo: float
    hi: float
    log: bool = False
    integer: bool = False
    decimals: int = 3
    tooltip: str = ""


SPECS: tuple[tuple[str, tuple[SliderSpec, ...]], ...] = (
    ("Cross-bilateral filter", (
        SliderSpec("filter", "mu", "μ (colour)", 0.0, 50.0, tooltip="weight of the colour term vs the semantic term"),
        SliderSpec("filter", "sigma_s", "σs (px@2048)", 1.0, 40.0, decimals=1,
                   tooltip="spatial Gaussian in pixels of a 2048-px-wide image (scaled with the width)"),
        SliderSpec("filter", "sigma_c", "σc (Lab)", 0.5, 50.0, decimals=1, tooltip="colour Gaussian, CIELAB units"),
    )),
    ("Variance filter (uncertain map)", (
        SliderSpec("uncertainty", "l", "l (px)", 2, 32, integer=True, tooltip="region side in pixels"),
        SliderSpec("uncertainty", "tau", "τ (Var/mean²)", 1e-5, 1.0, log=True, decimals=5,
                   tooltip="scale-free threshold (mode 'relative')"),
        SliderSpec("uncertainty", "mu_v", "μv (m²)", 1e-4, 100.0, log=True, decimals=4,
                   tooltip="absolute variance threshold (mode 'absolute')"),
    )),
    ("Normal-guided refinement", (
        SliderSpec("refine", "lambda1", "λ1 normal", 1e-3, 1e3, log=True, decimals=3),
        SliderSpec("refine", "lambda2", "λ2 continuity", 1e-3, 1e3, log=True, decimals=3),
        SliderSpec("refine", "lambda3", "λ3 depth", 1e-3, 1e3, log=True, decimals=3),
        SliderSpec("refine", "steps", "steps", 0, 2000, integer=True),
        SliderSpec("refine", "lr", "learning rate", 1e-6, 10.0, log=True, decimals=6),
    )),
    ("Mesh", (
        SliderSpec("mesh", "stride", "stride (px)", 1, 16, integer=True, tooltip="one vertex every N pixels"),
        SliderSpec("mesh", "far_limit", "far limit (m)", 20.0, 1000.0, log=True, decimals=0),
        SliderSpec("camera", "hfov_deg", "h. FOV (°)", 20.0, 140.0, decimals=1,
                   tooltip="horizontal field of view (shows the scene's own until you move it)"),
    )),
    ("Night", (
        SliderSpec("night", "spp", "spp (preview)", 1, 256, integer=True, log=False),
        SliderSpec("night", "preview_scale", "preview scale", 0.1, 1.0, decimals=2),
        SliderSpec("night", "iso", "ISO", 50, 12800, log=True, integer=True),
        SliderSpec("night", "exposure", "exposure compensation (EV)", -4.0, 6.0, decimals=2,
                   tooltip="added to the metered exposure (auto-exposure); the whole exposure when the mode is manual"),
    )),
)


class ParameterPanel(QWidget):
    """Sliders for every tunable of the pipeline. ``changed`` fires on each user edit."""

    changed = Signal(str, str, object)
    presetChosen = Signal(str)
    resetRequested = Signal()

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        outer = QVBoxLayout(self)
        outer.setContentsMargins(0, 0, 0, 0)
        top = QHBoxLayout()
        self.preset = QComboBox()
        self.preset.addItem("λ preset…", None)
        self.preset.addItem("appendix B (1, 5, 1)", "appendix_b")
        self.preset.addItem("§3.4.3 (1, 1, 5)", "section_3_4_3")
        self.preset.activated.connect(self._on_preset)
        reset = QPushButton("Reset all")
        reset.clicked.connect(self.resetRequested.emit)
        top.addWidget(self.preset, 1)
        top.addWidget(reset)
        outer.addLayout(top)
        scroll = QScrollArea()
        scroll.setWidgetResizable(True)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)  # rows shrink instead
        body = QWidget()
        lay = QVBoxLayout(body)
        self.sliders: dict[tuple[str, str], ValueSlider] = {}
        self.combos: dict[tuple[str, str], QComboBox] = {}
        self.checks: dict[tuple[str, str], QCheckBox] = {}
        for title, specs in SPECS:
            box = QGroupBox(title)
            form = QVBoxLayout(box)
            for s in specs:
                w = ValueSlider(s.label, s.lo, s.hi, s.lo, log=s.log, integer=s.integer, decimals=s.decimals,
                                tooltip=s.tooltip)
                w.valueChanged.connect(lambda v, s=s: self.changed.emit(s.section, s.field, int(v) if s.integer else v))
                self.sliders[(s.section, s.field)] = w
                form.addWidget(w)
            if title.startswith("Variance"):
                self._combo(form, "uncertainty", "mode", "mode", ["relative", "absolute"])
            if title.startswith("Normal"):
                self._combo(form, "refine", "optimizer", "optimizer", ["fast", "lbfgs", "adam_faithful"])
                self._combo(form, "refine", "loss", "loss", ["thesis", "scale_aware"])
            if title == "Mesh":
                self._check(form, "mesh", "postprocess", "post-process the mesh",
                            "delete spurious faces, complete hidden background, wall depth steps")
            if title == "Night":
                self._combo(form, "night", "exposure_mode", "exposure", ["auto", "manual"])
                self._combo(form, "lights", "source", "lights", ["auto", "annotation", "proposed", "none"])
                self._check(form, "night", "ego_headlights", "ego vehicle headlights")
                self._check(form, "night", "group_all_together", "groups switch as one")
                self._check(form, "night", "noise", "camera noise")
                self._check(form, "night", "denoise", "denoise", "remove the Monte Carlo noise before the camera's")
            lay.addWidget(box)
        probs = QGroupBox("Light activation probability per class")
        pform = QVBoxLayout(probs)
        for c in light_classes():
            if c.is_group:
                continue
            w = ValueSlider(c.name, 0.0, 1.0, 0.5, decimals=2,
                            tooltip="probability that a light of this class is on (overrides the table's range)")
            w.valueChanged.connect(lambda v, cid=c.id: self.changed.emit("night", f"p_{cid}", v))
            self.sliders[("night", f"p_{c.id}")] = w
            pform.addWidget(w)
        lay.addWidget(probs)
        lay.addStretch(1)
        scroll.setWidget(body)
        outer.addWidget(scroll, 1)

    def _combo(self, form, section: str, field: str, label: str, items: list[str]) -> None:
        row = QFormLayout()
        cb = QComboBox()
        cb.addItems(items)
        cb.currentTextChanged.connect(lambda t: self.changed.emit(section, field, t))
        row.addRow(label, cb)
        form.addLayout(row)
        self.combos[(section, field)] = cb

    def _check(self, form, section: str, field: str, label: str, tooltip: str = "") -> None:
        cb = QCheckBox(label)
        cb.setToolTip(tooltip)
        cb.toggled.connect(lambda on: self.changed.emit(section, field, bool(on)))
        form.addWidget(cb)
        self.checks[(section, field)] = cb

    def _on_preset(self, index: int) -> None:
        name = self.preset.itemData(index)
        self.preset.setCurrentIndex(0)
        if name:
            self.presetChosen.emit(name)

    def set_values(self, values: dict[tuple[str, str], object]) -> None:
        """Show ``values`` without emitting ``changed``."""
        for key, v in values.items():
            if key in self.sliders:
                self.sliders[key].setValue(float(v))
            elif key in self.combos:
                cb = self.combos[key]
                cb.blockSignals(True)
                cb.setCurrentText(str(v))
                cb.blockSignals(False)
            elif key in self.checks:
                cb = self.checks[key]
                cb.blockSignals(True)
                cb.setChecked(bool(v))
                cb.blockSignals(False)
