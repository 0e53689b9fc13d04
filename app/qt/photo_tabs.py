"""The window's centre: the current expression's photos in tabs, one :class:`~app.qt.photo_view.PhotoView` each.

The tab title shows the photo's reprojection RMS after a fit; an expression without photos shows
a hint instead. The editing mode and the overlay / curve switches (*View* menu) apply to every
tab. :class:`PhotoTabs` is rebuilt from the model (:meth:`PhotoTabs.rebuild`) and announces it
(``rebuilt``), and announces a photo brought forward by the artist (``photo_shown``), so the
toolbar's photo fields follow.
"""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QLabel, QTabWidget

from app.qt.photo_view import POINTS, PhotoView
from app.studio_state import StudioModel
from photomodel.errors import FaceStudioError


class PhotoTabs(QTabWidget):
    """The photo tabs of ``model``'s current expression; edits are pushed on ``undo_stack``."""

    #: the tabs were made again (a new expression, photos added or removed, another project)
    rebuilt = Signal()
    #: another tab was brought forward (not while rebuilding)
    photo_shown = Signal()
    #: a photo view's status-bar message
    status_message = Signal(str)

    def __init__(self, model: StudioModel, undo_stack, parent=None):
        super().__init__(parent)
        self.model, self.undo_stack = model, undo_stack
        self.setDocumentMode(True)
        # room under the text: some fonts draw "_" below the compact tab's text box, and photo ids
        # such as three_quarter_right then read "three quarter right" (issue 35)
        self.tabBar().setStyleSheet("QTabBar::tab { padding-bottom: 3px; }")
        self.currentChanged.connect(self._on_tab_changed)
        self.empty_label = QLabel("<h3>No photos yet</h3><p>Drop photos here, or use File → Add photos…</p>")
        self.empty_label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.views: dict[str, PhotoView] = {}
        self.mode = POINTS
        self.show_overlay = True
        self.show_curves = True
        self._rebuilding = False

    def current_view(self) -> PhotoView | None:
        w = self.currentWidget()
        return w if isinstance(w, PhotoView) else None

    def show_photo(self, photo_id: str) -> PhotoView | None:
        view = self.views.get(photo_id)
        if view is not None:
            self.setCurrentWidget(view)
        return view

    def clear_views(self) -> None:
        """Take every photo view down (detached first: none looks its photo up again)."""
        was, self._rebuilding = self._rebuilding, True
        try:
            for view in self.views.values():
                view.detach()
            self.clear()
            for view in self.views.values():
                view.deleteLater()
            self.views = {}
        finally:
            self._rebuilding = was

    def rebuild(self) -> None:
        """A tab per photo of the current expression, the photo shown before kept in front."""
        current = self.current_view()
        keep = current.photo_id if current is not None else None
        self._rebuilding = True
        try:
            self.clear_views()
            expr = self.model.expression_name
            for photo in self.model.photos:
                view = PhotoView(self.model, self.undo_stack, expr, photo.id)
                view.set_mode(self.mode)
                view.set_overlay_visible(self.show_overlay)
                view.set_curves_visible(self.show_curves)
                view.status_message.connect(self.status_message)
                self.views[photo.id] = view
                self.addTab(view, photo.id)
                if view.missing:
                    self.setTabToolTip(self.count() - 1, view.missing)
            if not self.views:
                self.addTab(self.empty_label, "no photos")
        finally:
            self._rebuilding = False
        if keep in self.views:
            self.setCurrentWidget(self.views[keep])
        self.update_titles()
        self.rebuilt.emit()

    def overlay_photo_ids(self, expression: str) -> list[str]:
        """The photo on screen, if it shows ``expression``'s overlay (:attr:`FitController.overlay_photos`)."""
        view = self.current_view()
        if view is None or not self.show_overlay or view.expression != expression:
            return []
        return [view.photo_id]

    def _on_tab_changed(self, index: int):
        if self._rebuilding:
            return
        self.photo_shown.emit()
        view = self.current_view()
        if view is not None:
            view.setFocus()

    def update_titles(self) -> None:
        """Each tab titled with its photo and, after a fit, the photo's reprojection RMS."""
        fit = self.model.fit()
        rms = {}
        if fit is not None:
            rms = {v["photo"]: v.get("rms_px") for v in fit.report.get("views", [])}
        for i in range(self.count()):
            w = self.widget(i)
            if isinstance(w, PhotoView):
                r = rms.get(w.photo_id)
                self.setTabText(i, w.photo_id if r is None else f"{w.photo_id}  {r:.2f} px")

    def jump_to(self, photo_id: str, feature: str) -> None:
        """Show a click: its photo, zoomed in around it, with its feature active."""
        view = self.show_photo(photo_id)
        if view is None:
            return
        try:
            self.model.set_active_feature(feature)
        except FaceStudioError:
            pass
        uv = view.photo.points.get(feature)
        if uv is not None:
            view.center_on_image(float(uv[0]), float(uv[1]), scale=max(view.scale_factor, 2.0))
        view.setFocus()

    # ------------------------------------------------------------------ what every tab shows
    def set_mode(self, mode: str) -> None:
        self.mode = mode
        for view in self.views.values():
            view.set_mode(mode)

    def set_overlay_visible(self, on: bool) -> None:
        self.show_overlay = on
        for view in self.views.values():
            view.set_overlay_visible(on)

    def set_curves_visible(self, on: bool) -> None:
        self.show_curves = on
        for view in self.views.values():
            view.set_curves_visible(on)
