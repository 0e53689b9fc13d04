"""The rig panel: the project's blend shapes (ARKit names, then the photographed expressions), a slider each.

Moving a slider sets the shape's weight in the :class:`~app.studio_state.StudioModel`
(:meth:`~app.studio_state.StudioModel.set_rig_weight`); the 3D view then shows the rig's neutral
+ Σ wᵢ·Δᵢ live. *Reset* puts every weight back to 0. Without a rig the panel says how to make
one (``facestudio rig PROJECT``, or *Rig ▸ Build rig*). The weights are the view's, never the
project's: nothing here modifies the project.
"""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QGridLayout,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSlider,
    QVBoxLayout,
    QWidget,
)

from app.studio_state import StudioModel

#: Slider steps over the weight range [0, 1].
STEPS = 100
NO_RIG_HINT = (
    "<b>No rig in this project.</b><br>Make one with <tt>facestudio rig PROJECT</tt>, "
    "or Rig ▸ Build rig (after the neutral is fitted)."
)


class RigPanel(QWidget):
    """One slider per shape of the model's rig; observes ``rig_changed`` and ``rig_weights_changed``.

    Attributes
    ----------
    sliders : dict shape name → QSlider (0 … :data:`STEPS`).
    hint : QLabel, the "no rig" hint (hidden while a rig is shown).
    reset_button : QPushButton
    """

    def __init__(self, model: StudioModel, parent=None):
        super().__init__(parent)
        self.model = model
        self.sliders: dict[str, QSlider] = {}
        self._values: dict[str, QLabel] = {}
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        self.hint = QLabel(NO_RIG_HINT)
        self.hint.setWordWrap(True)
        self.hint.setTextFormat(Qt.TextFormat.RichText)
        lay.addWidget(self.hint)
        top = QHBoxLayout()
        self.title = QLabel()
        top.addWidget(self.title, 1)
        self.reset_button = QPushButton("Reset")
        self.reset_button.setToolTip("Every weight back to 0: the neutral")
        self.reset_button.clicked.connect(model.reset_rig_weights)
        top.addWidget(self.reset_button)
        lay.addLayout(top)
        self.scroll = QScrollArea()
        self.scroll.setWidgetResizable(True)
        lay.addWidget(self.scroll, 1)
        model.rig_changed.connect(self.rebuild)
        model.rig_weights_changed.connect(self.sync)
        self.rebuild()

    def rebuild(self, *args) -> None:
        """The rows of the model's rig (or the hint)."""
        rig = self.model.rig()
        self.sliders.clear()
        self._values.clear()
        body = QWidget()
        grid = QGridLayout(body)
        grid.setContentsMargins(2, 2, 2, 2)
        grid.setVerticalSpacing(1)
        has = rig is not None
        self.hint.setVisible(not has)
        if self.model.project.rig is not None and not has:
            self.hint.setText(f"<b>The rig cannot be shown:</b> {self.model.rig_problem}")
        else:
            self.hint.setText(NO_RIG_HINT)
        self.title.setVisible(has)
        self.reset_button.setVisible(has)
        self.scroll.setVisible(has)
        if has:
            photographed = len(rig.names) - rig.arkit
            self.title.setText(
                f"<b>{rig.arkit} ARKit shapes</b> on {rig.neutral!r}"
                + (f" + {photographed} photographed" if photographed else "")
            )
            row = 0
            for i, name in enumerate(rig.names):
                if i == 0 or i == rig.arkit:
                    head = "ARKit (ICT-FaceKit)" if i < rig.arkit else "Photographed expressions"
                    grid.addWidget(QLabel(f"<i>{head}</i>"), row, 0, 1, 3)
                    row += 1
                slider = QSlider(Qt.Orientation.Horizontal)
                slider.setRange(0, STEPS)
                slider.setValue(round(rig.weights[i] * STEPS))
                slider.setObjectName(f"rig:{name}")
                slider.valueChanged.connect(lambda v, n=name: self.model.set_rig_weight(n, v / STEPS))
                value = QLabel(f"{rig.weights[i]:.2f}")
                value.setMinimumWidth(32)
                grid.addWidget(QLabel(name), row, 0)
                grid.addWidget(slider, row, 1)
                grid.addWidget(value, row, 2)
                self.sliders[name] = slider
                self._values[name] = value
                row += 1
            grid.setRowStretch(row, 1)
            grid.setColumnStretch(1, 1)
        self.scroll.setWidget(body)

    def sync(self, *args) -> None:
        """The sliders follow the model's weights (after a reset)."""
        rig = self.model.rig()
        if rig is None:
            return
        for name, w in zip(rig.names, rig.weights, strict=True):
            slider = self.sliders.get(name)
            if slider is None:
                continue
            if slider.value() != round(w * STEPS):
                slider.blockSignals(True)
                slider.setValue(round(w * STEPS))
                slider.blockSignals(False)
            self._values[name].setText(f"{w:.2f}")
