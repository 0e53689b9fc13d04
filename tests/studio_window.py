"""The studio's main window opened on a project the way the GUI tests use it (shared by their fixtures)."""

from PySide6.QtCore import QSettings

from app.qt.main_window import MainWindow


def open_studio(qtbot, tmp_path, project) -> MainWindow:
    """A shown 1300×850 main window with no autosave, its settings and recovery file in
    ``tmp_path``, with ``project`` open."""
    w = MainWindow(
        settings=QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat),
        autosave_interval_ms=0,
        recovery_file=tmp_path / "untitled.recovery.facestudio.json",
    )
    qtbot.addWidget(w)
    w.resize(1300, 850)
    w.show()
    qtbot.waitExposed(w)
    assert w.open_project(project, ask_to_save=False)
    return w


def close_studio(w: MainWindow) -> None:
    """Stop the window's workers and drop its unsaved flag (no prompt at teardown)."""
    w.tracking_view.jobs.shutdown()
    w.fits.shutdown()
    w.jobs.shutdown()
    w.scan_jobs.shutdown()
    w.model.modified = False
