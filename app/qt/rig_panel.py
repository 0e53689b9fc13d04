"""The rig panel: the project's blend shapes (ARKit names, then the photographed expressions), a slider each,
and identity sliders making a new face from the people model.

Moving a slider sets the shape's weight in the :class:`~app.studio_state.StudioModel`
(:meth:`~app.studio_state.StudioModel.set_rig_weight`); the 3D view then shows the rig's neutral
+ Σ wᵢ·Δᵢ live. *Reset* puts every weight back to 0. Without a rig the panel says how to make
one (``facestudio rig PROJECT``, or *Rig ▸ Build rig*). The weights are the view's, never the
project's: nothing here modifies the project.

Under them, *New face from the people model* (:class:`IdentitySliders`, off until ticked: ticking reads
the model file, :mod:`photomodel.people.model_file`) offers a slider per first identity mode of the
multilinear model (:class:`app.studio.identity.IdentityFace`, ±3 standard deviations of its people);
the 3D view shows the face they make, and *Save as project…* writes it as a new project (its neutral
fitted, the model's 51 shapes as its rig), which opens, poses and exports like any other.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QFileDialog,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QScrollArea,
    QSlider,
    QVBoxLayout,
    QWidget,
)

from app.studio.identity import SIGMA_RANGE, default_model_file
from app.studio_state import StudioModel
from photomodel.errors import FaceStudioError
from photomodel.project import FILE_SUFFIX

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
        self.identity = IdentitySliders(model)
        lay.addWidget(self.identity)
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


#: Identity slider steps over [-SIGMA_RANGE, SIGMA_RANGE].
IDENTITY_STEPS = 60


class IdentitySliders(QGroupBox):
    """*New face from the people model*: a slider per first identity mode, *Mean face*, *Save as project…*.

    Ticking the box reads the people model (:meth:`StudioModel.load_identity`, from :attr:`model_file`)
    and shows the new face in the 3D view; unticking shows the project again.

    Attributes
    ----------
    model_file : Path, the people model read when the box is ticked (:func:`app.studio.identity.default_model_file`).
    sliders : list of QSlider, mode 1, 2, … (−:data:`IDENTITY_STEPS` … +:data:`IDENTITY_STEPS` = ±3 σ).
    hint : QLabel, why there are no sliders (the model missing) or what was saved last.
    last_saved : Path or None, the project last written by *Save as project…*.
    """

    def __init__(self, model: StudioModel, parent=None):
        super().__init__("New face from the people model", parent)
        self.model = model
        self.model_file: Path = default_model_file()
        self.sliders: list[QSlider] = []
        self._values: list[QLabel] = []
        self.last_saved: Path | None = None
        self.setCheckable(True)
        self.setChecked(False)
        self.setToolTip(
            "sliders along the multilinear people model's first identity modes (seed 000): a new face, "
            "shown in the 3D view, saved as a project that takes any performance through its rig"
        )
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        self.hint = QLabel()
        self.hint.setWordWrap(True)
        lay.addWidget(self.hint)
        self.grid_host = QWidget()
        self.grid = QGridLayout(self.grid_host)
        self.grid.setContentsMargins(0, 0, 0, 0)
        self.grid.setVerticalSpacing(1)
        lay.addWidget(self.grid_host)
        buttons = QHBoxLayout()
        self.mean_button = QPushButton("Mean face")
        self.mean_button.setToolTip("every identity slider back to 0: the mean of the model's people")
        self.mean_button.clicked.connect(model.reset_identity)
        self.save_button = QPushButton("Save as project…")
        self.save_button.setToolTip(
            "write the new face as a project: its neutral fitted, the model's 51 shapes as its rig"
        )
        self.save_button.clicked.connect(lambda: self.save_as())
        buttons.addWidget(self.mean_button)
        buttons.addWidget(self.save_button)
        lay.addLayout(buttons)
        self.toggled.connect(self._on_toggled)
        model.identity_changed.connect(self.sync)
        model.project_replaced.connect(lambda *_: self.setChecked(False))  # show the opened project
        self._show_controls(False)

    def _show_controls(self, on: bool) -> None:
        for w in (self.grid_host, self.mean_button, self.save_button):
            w.setVisible(on)

    def _on_toggled(self, on: bool) -> None:
        if not on:
            self.model.show_identity(False)
            self._show_controls(False)
            self.hint.setVisible(False)
            return
        try:
            face = self.model.load_identity(self.model_file)
        except FaceStudioError as exc:
            self.hint.setText(f"<b>No people model:</b> {exc}")
            self.hint.setVisible(True)
            return
        if not self.sliders:
            self._build(face.modes)
        self.hint.setVisible(False)
        self._show_controls(True)
        self.model.show_identity(True)

    def _build(self, modes: int) -> None:
        for k in range(modes):
            slider = QSlider(Qt.Orientation.Horizontal)
            slider.setRange(-IDENTITY_STEPS, IDENTITY_STEPS)
            slider.setObjectName(f"identity:{k}")
            slider.setToolTip(f"identity mode {k + 1} of the people model, in standard deviations of its people")
            slider.valueChanged.connect(
                lambda v, k=k: self.model.set_identity_value(k, v * SIGMA_RANGE / IDENTITY_STEPS)
            )
            value = QLabel("+0.0σ")
            value.setMinimumWidth(40)
            self.grid.addWidget(QLabel(f"mode {k + 1}"), k, 0)
            self.grid.addWidget(slider, k, 1)
            self.grid.addWidget(value, k, 2)
            self.sliders.append(slider)
            self._values.append(value)
        self.grid.setColumnStretch(1, 1)

    def sync(self, *args) -> None:
        """The sliders follow the model's values (after *Mean face*)."""
        face = self.model.identity
        if face is None:
            return
        for slider, label, v in zip(self.sliders, self._values, face.values, strict=False):
            step = round(v * IDENTITY_STEPS / SIGMA_RANGE)
            if slider.value() != step:
                slider.blockSignals(True)
                slider.setValue(step)
                slider.blockSignals(False)
            label.setText(f"{v:+.1f}σ")

    def save_as(self, path: str | Path | None = None) -> Path | None:
        """Write the new face as a project at ``path`` (asked for when None); returns the file, None when
        cancelled or it could not be written (the hint says why)."""
        if self.model.identity is None:
            return None
        if path is None:
            start = str(self.model.path.parent.parent) if self.model.path is not None else ""
            path, _ = QFileDialog.getSaveFileName(
                self, "Save the new face as a project", start, f"Face Studio projects (*{FILE_SUFFIX})"
            )
            if not path:
                return None
        path = Path(path)
        if not path.name.endswith(FILE_SUFFIX):
            path = path.with_name(path.name.split(".")[0] + FILE_SUFFIX)
        try:
            self.last_saved = self.model.save_identity(path)
        except FaceStudioError as exc:
            self.hint.setText(f"<b>Not saved:</b> {exc}")
            self.hint.setVisible(True)
            return None
        self.hint.setText(f"saved as {self.last_saved} (File ▸ Open… to pose it with its rig)")
        self.hint.setVisible(True)
        return self.last_saved
