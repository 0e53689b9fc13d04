"""The side panel: features to click, curves to draw, the worst clicks and the per-view fit report.

* **Features** — the project's features (pose features first, marked ●) with the number of
  photos each is clicked in and its reprojection RMS after a fit, then the generic mesh's other
  named features (greyed; clicking one in a photo adds it to the project). Selecting a row makes
  it the *active feature* — the one a click in a photo places.
* **Curves** — the mesh curves (brows, eyelids, lips, chin) with the photos they are drawn in;
  selecting one makes it the curve that "Draw curve" mode binds to.
* **Still to click** — the fit's checklist (:func:`photomodel.modeling.checklist.click_checklist`):
  every pose feature clicked in fewer than two photos and every photo short of shared clicks, at
  once; selecting a feature's line makes it active, a photo's line shows that photo
  (``photo_requested``).
* Right-click a feature: unflag (or flag) it as a pose feature, or leave it out of (hide it in)
  a photo — undoable commands (:class:`~app.studio.commands.SetPoseCommand`,
  :class:`~app.studio.commands.SetHiddenCommand`).
* **Worst clicks** — after a fit, the clicks farthest from the fitted model, largest first;
  activating one jumps to it (``jump_requested(photo_id, feature)``).
* **Fit report** — per-photo reprojection RMS, number of points and recovered focal length.
"""

from __future__ import annotations

import html

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QBrush, QColor
from PySide6.QtWidgets import (
    QHeaderView,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QMenu,
    QSplitter,
    QTreeWidget,
    QTreeWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.qt.photo_items import residual_color
from app.studio.commands import SetHiddenCommand, SetPoseCommand
from app.studio_state import StudioModel
from photomodel.modeling.fit import uses_person_prior
from photomodel.modeling.mouth import expression_note

_NAME_ROLE = Qt.ItemDataRole.UserRole


def _section(title: str, widget: QWidget) -> QWidget:
    box = QWidget()
    lay = QVBoxLayout(box)
    lay.setContentsMargins(0, 4, 0, 0)
    label = QLabel(f"<b>{title}</b>")
    lay.addWidget(label)
    lay.addWidget(widget)
    return box


class FeaturePanel(QWidget):
    """Lists observing a :class:`StudioModel`; selecting sets the model's active feature/curve."""

    jump_requested = Signal(str, str)  # photo id, feature
    photo_requested = Signal(str)  # photo id

    def __init__(self, model: StudioModel, parent=None, undo_stack=None):
        super().__init__(parent)
        self.model = model
        self.undo_stack = undo_stack  # where the feature menu's edits go (None: no menu)
        self._updating = False

        self.filter = QLineEdit()
        self.filter.setPlaceholderText("filter features…")
        self.filter.setClearButtonEnabled(True)
        self.filter.textChanged.connect(self._apply_filter)

        self.features = QTreeWidget()
        self.features.setColumnCount(3)
        self.features.setHeaderLabels(["feature", "photos", "RMS"])
        self.features.setRootIsDecorated(True)
        self.features.setUniformRowHeights(True)
        self.features.header().setStretchLastSection(False)
        self.features.header().setSectionResizeMode(0, QHeaderView.ResizeMode.Stretch)
        # fixed widths: ResizeToContents re-measures every row on each setText (0.5 ms a call)
        self.features.setColumnWidth(1, 52)
        self.features.setColumnWidth(2, 44)
        self.features.currentItemChanged.connect(self._on_feature_selected)
        self.features.setContextMenuPolicy(Qt.ContextMenuPolicy.CustomContextMenu)
        self.features.customContextMenuRequested.connect(self._on_feature_menu)
        self.todo = QListWidget()
        self.todo.setWordWrap(True)
        self.todo.itemClicked.connect(self._on_todo_activated)
        self.todo.itemActivated.connect(self._on_todo_activated)

        self.curves = QTreeWidget()
        self.curves.setColumnCount(2)
        self.curves.setHeaderLabels(["curve", "drawn in"])
        self.curves.setRootIsDecorated(False)
        self.curves.header().setSectionResizeMode(0, QHeaderView.ResizeMode.Stretch)
        self.curves.currentItemChanged.connect(self._on_curve_selected)

        self.worst = QListWidget()
        self.worst.itemActivated.connect(self._on_worst_activated)
        self.worst.itemClicked.connect(self._on_worst_activated)

        self.report = QTreeWidget()
        self.report.setColumnCount(4)
        self.report.setHeaderLabels(["photo", "RMS", "points", "lens"])
        self.report.setRootIsDecorated(False)
        self.report.header().setStretchLastSection(False)
        self.report.header().setSectionResizeMode(0, QHeaderView.ResizeMode.Stretch)
        for c in (1, 2, 3):
            self.report.header().setSectionResizeMode(c, QHeaderView.ResizeMode.ResizeToContents)
        self.summary = QLabel("not fitted yet")
        self.summary.setWordWrap(True)

        feat_box = QWidget()
        fl = QVBoxLayout(feat_box)
        fl.setContentsMargins(0, 0, 0, 0)
        fl.addWidget(QLabel("<b>Features</b> — pick one, then click it on the photos"))
        fl.addWidget(self.filter)
        fl.addWidget(self.features)

        report_box = QWidget()
        rl = QVBoxLayout(report_box)
        rl.setContentsMargins(0, 4, 0, 0)
        rl.addWidget(QLabel("<b>Fit</b>"))
        rl.addWidget(self.summary)
        rl.addWidget(self.report)

        split = QSplitter(Qt.Orientation.Vertical)
        split.addWidget(feat_box)
        split.addWidget(_section("Still to click", self.todo))
        split.addWidget(_section("Curves", self.curves))
        split.addWidget(_section("Worst clicks", self.worst))
        split.addWidget(report_box)
        split.setSizes([380, 110, 150, 130, 150])
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        lay.addWidget(split)

        self._connect_model()
        self.refresh()

    def _connect_model(self):
        """The panel follows the model's edits, fits and selection."""
        m = self.model
        m.project_replaced.connect(self.refresh)
        m.expression_changed.connect(lambda *_: self.refresh())
        m.photos_changed.connect(lambda *_: self.refresh())
        m.features_changed.connect(self.refresh_features)
        m.features_changed.connect(self.refresh_checklist)
        m.points_changed.connect(self._on_points_changed)
        m.points_changed.connect(lambda *_: self.refresh_checklist())
        m.curves_changed.connect(lambda *_: self.refresh_curves())
        m.fit_changed.connect(lambda *_: self.refresh_fit())
        m.active_feature_changed.connect(self._select_feature)
        m.active_curve_changed.connect(self._select_curve)

    # ------------------------------------------------------------------ features
    def refresh(self):
        self.refresh_features()
        self.refresh_checklist()
        self.refresh_curves()
        self.refresh_fit()

    def _feature_rms(self) -> dict[str, float]:
        fit = self.model.fit()
        if fit is None:
            return {}
        return {p["feature"]: p["rms_px"] for p in fit.report.get("points", []) if p.get("rms_px") is not None}

    def refresh_features(self):
        self._updating = True
        try:
            self.features.clear()
            m = self.model
            k = len(m.photos)
            rms = self._feature_rms()
            groups = {
                "pose": QTreeWidgetItem(["Pose features (§5.1.1)"]),
                "other": QTreeWidgetItem(["Other features (refinement)"]),
                "mesh": QTreeWidgetItem(["Generic mesh — not used yet"]),
            }
            for g in groups.values():
                g.setFlags(Qt.ItemFlag.ItemIsEnabled)
                f = g.font(0)
                f.setBold(True)
                g.setFont(0, f)
                self.features.addTopLevelItem(g)
            for name, vertex, in_project, pose in m.catalogue():
                if in_project:
                    n = m.click_count(name) if m.expression is not None else 0
                    r = rms.get(name)
                    item = QTreeWidgetItem([name, f"{n}/{k}", "" if r is None else f"{r:.2f}"])
                    if n < min(2, k):
                        item.setForeground(1, QBrush(QColor(220, 120, 0)))
                        item.setToolTip(
                            1,
                            "a feature needs clicks in at least two photos"
                            if k > 1
                            else "not clicked in the photo yet",
                        )
                    groups["pose" if pose else "other"].addChild(item)
                else:
                    item = QTreeWidgetItem([name, "", ""])
                    item.setForeground(0, QBrush(QColor(130, 130, 130)))
                    item.setToolTip(0, f"generic-mesh vertex {vertex}; click it on a photo to add it")
                    groups["mesh"].addChild(item)
                item.setData(0, _NAME_ROLE, name)
            groups["pose"].setExpanded(True)
            groups["other"].setExpanded(True)
            groups["mesh"].setExpanded(False)
            self._apply_filter(self.filter.text())
        finally:
            self._updating = False
        self._select_feature(self.model.active_feature)

    def feature_items(self):
        """The tree's feature rows (every group's children), in order."""
        for i in range(self.features.topLevelItemCount()):
            g = self.features.topLevelItem(i)
            for j in range(g.childCount()):
                yield g.child(j)

    def feature_item(self, name: str) -> QTreeWidgetItem | None:
        for item in self.feature_items():
            if item.data(0, _NAME_ROLE) == name:
                return item
        return None

    def _apply_filter(self, text: str):
        text = text.strip().lower()
        for item in self.feature_items():
            item.setHidden(bool(text) and text not in item.data(0, _NAME_ROLE).lower())
        if text:
            for i in range(self.features.topLevelItemCount()):
                self.features.topLevelItem(i).setExpanded(True)

    def _on_points_changed(self, expression, photo_id, feature):
        if expression != self.model.expression_name:
            return
        item = self.feature_item(feature)
        if item is None:
            return
        k = len(self.model.photos)
        n = self.model.click_count(feature)
        item.setText(1, f"{n}/{k}")
        item.setForeground(1, QBrush(QColor(220, 120, 0) if n < 2 else self.palette().text().color()))

    def _on_feature_selected(self, current, previous):
        if self._updating or current is None:
            return
        name = current.data(0, _NAME_ROLE)
        if name is not None and name != self.model.active_feature:
            self.model.set_active_feature(name)

    def _select_feature(self, name):
        item = None if name is None else self.feature_item(name)
        if item is not None and self.features.currentItem() is not item:
            self._updating = True
            try:
                self.features.setCurrentItem(item)
                self.features.scrollToItem(item)
            finally:
                self._updating = False

    # ------------------------------------------------------------------ pose flag, left out, checklist
    def feature_menu(self, name: str) -> QMenu | None:
        """The right-click menu of a project feature: (un)flag as a pose feature, leave it out of
        a photo (or take it back in); None for a feature not in the project or without undo stack."""
        m = self.model
        if self.undo_stack is None or not m.has_feature(name):
            return None
        menu = QMenu(self)
        pose = m.project.feature(name).pose
        menu.addAction(
            f"Unflag {name} as a pose feature" if pose else f"Flag {name} as a pose feature",
            lambda: self.set_pose(name, not pose),
        )
        if m.expression is not None and m.photos:
            sub = menu.addMenu("Leave out of photo")
            for p in m.photos:
                act = sub.addAction(p.id)
                act.setCheckable(True)
                act.setChecked(name in p.hidden)
                act.toggled.connect(lambda on, pid=p.id: self.set_left_out(name, pid, on))
        return menu

    def set_pose(self, name: str, pose: bool) -> None:
        self.undo_stack.push(SetPoseCommand(self.model, name, pose))

    def set_left_out(self, name: str, photo_id: str, left_out: bool) -> None:
        self.undo_stack.push(SetHiddenCommand(self.model, self.model.expression_name, photo_id, name, left_out))

    def _on_feature_menu(self, pos):
        item = self.features.itemAt(pos)
        name = None if item is None else item.data(0, _NAME_ROLE)
        menu = None if name is None else self.feature_menu(name)
        if menu is not None:
            self._menu = menu  # tests read it
            menu.popup(self.features.viewport().mapToGlobal(pos))

    def refresh_checklist(self):
        """The fit's checklist, one line per missing feature or photo."""
        self.todo.clear()
        if self.model.expression is None or not self.model.photos:
            return
        items = self.model.checklist()
        one = len(self.model.photos) == 1
        if not items:
            done = QListWidgetItem(
                "✓ enough clicks in the photo (one photo: depth from the generic head)"
                if one
                else "✓ every pose feature is clicked in 2+ photos"
            )
            done.setFlags(Qt.ItemFlag.ItemIsEnabled)
            done.setForeground(QBrush(QColor(60, 160, 60)))
            self.todo.addItem(done)
        for it in items:
            if it.feature is not None:
                text = f"● {it.feature} — {it.photos_clicked}/{it.needed} photos"
                data = ("feature", it.feature)
            else:
                text = f"▣ {it.photo} — {it.photos_clicked}/{it.needed} {'clicks' if one else 'shared clicks'}"
                data = ("photo", it.photo)
            item = QListWidgetItem(text)
            item.setData(_NAME_ROLE, data)
            item.setToolTip(it.hint)
            item.setForeground(QBrush(QColor(220, 120, 0)))
            self.todo.addItem(item)

    def _on_todo_activated(self, item: QListWidgetItem):
        if item.data(_NAME_ROLE) is None:
            return
        kind, name = item.data(_NAME_ROLE)
        if kind == "feature":
            self.model.set_active_feature(name)
        else:
            self.photo_requested.emit(name)

    # ------------------------------------------------------------------ curves
    def refresh_curves(self):
        self._updating = True
        try:
            self.curves.clear()
            photos = self.model.photos
            for name, _ in self.model.curve_catalogue():
                drawn = [p.id for p in photos if name in p.curves]
                item = QTreeWidgetItem([name, ", ".join(drawn) if drawn else "–"])
                item.setData(0, _NAME_ROLE, name)
                if len(drawn) == 1:
                    item.setToolTip(1, "a curve is used once it is drawn in at least two photos")
                    item.setForeground(1, QBrush(QColor(220, 120, 0)))
                self.curves.addTopLevelItem(item)
        finally:
            self._updating = False
        self._select_curve(self.model.active_curve)

    def _on_curve_selected(self, current, previous):
        if self._updating or current is None:
            return
        name = current.data(0, _NAME_ROLE)
        if name != self.model.active_curve:
            self.model.set_active_curve(name)

    def _select_curve(self, name):
        for i in range(self.curves.topLevelItemCount()):
            item = self.curves.topLevelItem(i)
            if item.data(0, _NAME_ROLE) == name and self.curves.currentItem() is not item:
                self._updating = True
                try:
                    self.curves.setCurrentItem(item)
                finally:
                    self._updating = False

    # ------------------------------------------------------------------ fit
    def refresh_fit(self):
        fit = self.model.fit()
        self.worst.clear()
        self.report.clear()
        if fit is None:
            self.summary.setText("not fitted yet — click each pose feature in at least two photos, then Fit")
            self.refresh_features_rms()
            return
        rep = fit.report
        when = "" if fit.elapsed_s is None else f" in {fit.elapsed_s * 1000:.0f} ms"
        prior = uses_person_prior(rep.get("camera_solve"))
        self.summary.setText(
            f"reprojection RMS <b>{rep.get('rms_px', float('nan')):.2f} px</b> "
            f"(pose features {rep.get('pose', {}).get('rms_px', float('nan')):.2f} px){when}"
            + (
                "<br>the most probable face: automatic clicks count as far as the detector is "
                "sure of them, so the RMS against them is about its error"
                if prior
                else ""
            )
        )
        note = expression_note(rep)
        if note:  # the neutral fitted to an expressive face: said first, where the fit is read
            said = "".join(f"<b>⚠</b> {html.escape(n, quote=False)}<br>" for n in note)
            self.summary.setText(said + self.summary.text())
            item = QListWidgetItem(f"⚠ expression not fitted: {', '.join(rep['expressive_photos'])} show one")
            item.setData(_NAME_ROLE, (next(iter(rep["expressive_photos"])), ""))
            item.setForeground(QBrush(QColor(200, 120, 0)))
            item.setToolTip("\n".join(note))
            self.worst.addItem(item)
        for v in rep.get("views", []):
            rms = "–" if v.get("rms_px") is None else f"{v['rms_px']:.2f}"
            item = QTreeWidgetItem([v["photo"], rms, str(v.get("points", "")), f"{v.get('focal_mm', 0):.0f} mm"])
            self.report.addTopLevelItem(item)
        suspect = set()
        for c in rep.get("suspect_clicks") or []:
            # the robust fit left these out: likely misplaced; listed first
            item = QListWidgetItem(f"⚠ {c['error_px']:5.1f} px   {c['feature']}  @ {c['photo']}  (suspect, not used)")
            item.setData(_NAME_ROLE, (c["photo"], c["feature"]))
            item.setForeground(QBrush(QColor(200, 30, 30)))
            item.setToolTip(
                "The fit found this click inconsistent with the others and left it out. "
                "Drag it to the right place (or hide it) and refit."
            )
            self.worst.addItem(item)
            suspect.add((c["photo"], c["feature"]))
        for c in rep.get("expression_clicks") or []:
            # a click on a photo that shows an expression, moved with it: not a misclick
            item = QListWidgetItem(
                f"~ {c['error_px']:5.1f} px   {c['feature']}  @ {c['photo']}  (the expression, not used)"
            )
            item.setData(_NAME_ROLE, (c["photo"], c["feature"]))
            item.setForeground(QBrush(QColor(200, 120, 0)))
            item.setToolTip(
                "This photo shows an expression (its mouth is not neutral) and this feature moves with it: the "
                "click disagrees with the other photos because the face changed, not because it is wrong. "
                "It is left out of the neutral fit; add a neutral photo to fit the neutral face."
            )
            self.worst.addItem(item)
            suspect.add((c["photo"], c["feature"]))
        for photo_id, why in (rep.get("photos_left_out") or {}).items():
            # a photo the fit left out (no face found, a profile's automatic clicks): says why
            item = QListWidgetItem(f"⚠ {photo_id}: left out of the fit (no camera)")
            item.setData(_NAME_ROLE, (photo_id, ""))
            item.setForeground(QBrush(QColor(200, 120, 0)))
            item.setToolTip(why)
            self.worst.addItem(item)
        for px, pid, name in self.model.worst_clicks(25):
            if (pid, name) in suspect:
                continue
            item = QListWidgetItem(f"{px:5.2f} px   {name}  @ {pid}")
            item.setData(_NAME_ROLE, (pid, name))
            item.setForeground(QBrush(residual_color(px).darker(130)))
            self.worst.addItem(item)
        self.refresh_features_rms()

    def refresh_features_rms(self):
        rms = self._feature_rms()
        for item in self.feature_items():
            r = rms.get(item.data(0, _NAME_ROLE))
            text = "" if r is None else f"{r:.2f}"
            if item.text(2) != text:
                item.setText(2, text)

    def _on_worst_activated(self, item: QListWidgetItem):
        pid, name = item.data(_NAME_ROLE)
        self.jump_requested.emit(pid, name)
