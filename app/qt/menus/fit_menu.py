"""The *Fit* menu: fit the current expression from scratch in the worker
(:class:`~app.qt.workers.FitController`) behind a cancellable progress dialog, the automatic
refit after each edit, and *Add scan…* (:mod:`app.qt.menus.fit_scan`); the status bar's fit label
says how the last fit went."""

from __future__ import annotations

from functools import partial

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QApplication, QLabel, QMenu, QMenuBar, QProgressDialog

from app.qt.menus import make_action
from app.qt.menus.fit_scan import AddScan
from app.qt.progress import close_progress, update_progress


class FitMenu(QObject):
    """The *Fit* menu of ``window`` (a :class:`~app.qt.main_window.MainWindow`) and its fit label."""

    def __init__(self, window):
        super().__init__(window)
        self.window = window
        self.fits = window.fits
        self.progress_dialog: QProgressDialog | None = None  # an explicit fit's (none for a refit)
        self.fit_label = QLabel("not fitted")
        A = partial(make_action, window)
        self.act_fit = A(
            "&Fit", self.run_fit, "Ctrl+R", tip="recover the cameras, deform the generic mesh and refine it (§5.1)"
        )
        self.act_auto = A(
            "&Auto-refit after each edit",
            self.set_auto_refit,
            checkable=True,
            checked=True,
            tip="refit after every edit while a refit takes less than 0.3 s",
        )
        self.scan = AddScan(window)
        self.act_add_scan = self.scan.act_add_scan

    def build(self, menubar: QMenuBar) -> QMenu:
        fm = menubar.addMenu("F&it")
        fm.addAction(self.act_fit)
        fm.addAction(self.act_auto)
        fm.addSeparator()
        fm.addAction(self.act_add_scan)
        return fm

    def connect_worker(self) -> None:
        """Follow the fit worker: its progress in the dialog, its end in the fit label."""
        self.fits.started.connect(self._on_fit_started)
        self.fits.progress.connect(self._on_fit_progress)
        self.fits.finished.connect(self._on_fit_finished)
        self.fits.failed.connect(self._on_fit_failed)
        self.fits.cancelled.connect(self._on_fit_cancelled)
        self.scan.connect_worker()

    def set_auto_refit(self, on: bool):
        self.fits.auto_refit = on

    def run_fit(self) -> bool:
        """Fit the current expression from scratch in the worker, with a cancellable progress dialog."""
        model = self.window.model
        if model.expression is None or not model.photos:
            self.window.show_error("Cannot fit", "a fit needs an expression with a photo; add photos first")
            return False
        if self.fits.busy:
            self.fits.cancel()
            self.fits.wait(10.0)
            QApplication.processEvents()
        task = self.fits.start(warm=False)
        if task is None:
            self.window.show_status("a fit is already running")
            return False
        self.progress_dialog = self.window.open_progress("Fit", "Fitting…", self.fits.cancel, min_duration_ms=400)
        return True

    def _close_progress(self):
        close_progress(self.progress_dialog, self.fits.cancel)
        self.progress_dialog = None

    def _on_fit_started(self, expression: str, warm: bool):
        self.fit_label.setText("refitting…" if warm else "fitting…")

    def _on_fit_progress(self, stage: str, fraction: float):
        update_progress(self.progress_dialog, stage, fraction)

    def _on_fit_finished(self, expression: str, seconds: float):
        self._close_progress()

    def _on_fit_failed(self, message: str):
        explicit = self.progress_dialog is not None
        self._close_progress()
        self.fit_label.setText("fit failed")
        if explicit:
            self.window.show_error("The fit failed", message)
        else:
            self.window.show_status(f"refit failed: {message.splitlines()[0]}", 10000)

    def _on_fit_cancelled(self):
        self._close_progress()
        self.fit_label.setText("fit cancelled")
        self.window.show_status("fit cancelled; the previous result is kept")

    def on_fit_changed(self, expression: str):
        """The fit label and the tab titles show the current expression's fit."""
        model = self.window.model
        if expression != model.expression_name:
            return
        fit = model.fit()
        if fit is None:
            self.fit_label.setText("not fitted")
        elif fit.from_scan:
            self.fit_label.setText(f"fitted to a scan ({fit.report['scan_fit'].get('unit', '?')})")
        else:
            t = "" if fit.elapsed_s is None else f" ({fit.elapsed_s * 1000:.0f} ms)"
            self.fit_label.setText(f"RMS {fit.report.get('rms_px', float('nan')):.2f} px{t}")
        self.window.tabs.update_titles()
