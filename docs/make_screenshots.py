"""Screenshots of the studio's main states, written to ``docs/screenshots/`` (shown in the README).

    .venv/bin/python docs/make_screenshots.py [--out docs/screenshots]

Runs the real window offscreen (``QT_QPA_PLATFORM=offscreen``) on a copy of the sample project,
so the sample project itself is not modified, and grabs widgets with ``QWidget.grab()``:

* ``studio_clicking.png`` — the window as it opens: clicks on a photo (white: not fitted yet),
  the feature list, the generic mesh in the 3D view;
* ``studio_fitted.png`` — after a fit: the fitted wireframe over a three-quarter photo, markers
  coloured by reprojection error, the worst clicks and the per-photo RMS;
* ``photo_closeup.png`` — a zoomed photo: markers, the active feature's label, drawn curves
  (pink), the fitted mesh's grid (blue) and curves (yellow);
* ``view3d.png`` — the fitted mesh in the 3D view, rendered by ``photomodel.render``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "screenshots")
    args = ap.parse_args(argv)

    from PySide6.QtCore import QSettings
    from PySide6.QtWidgets import QApplication

    from app.main_window import MainWindow

    app = QApplication.instance() or QApplication([])
    args.out.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix="screenshots_"))

    def settle(seconds: float = 0.2):
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            app.processEvents()

    def save(widget, name: str):
        path = args.out / name
        if not widget.grab().save(str(path)):
            raise SystemExit(f"could not write {path}")
        print(path)

    try:
        shutil.copytree(REPO / "sample_projects" / "james", tmp / "james", ignore=shutil.ignore_patterns("results"))
        window = MainWindow(settings=QSettings(str(tmp / "settings.ini"), QSettings.Format.IniFormat),
                            autosave_interval_ms=0)
        window.resize(1600, 960)
        window.show()
        if not window.open_project(tmp / "james" / "james.facestudio.json"):
            raise SystemExit("could not open the sample project")
        model = window.model
        window.show_photo("front")
        model.set_active_feature("nose_tip")
        settle()
        save(window, "studio_clicking.png")

        window.run_fit()
        while window.fits.busy or model.fit() is None:
            settle(0.05)
        view = window.show_photo("three_quarter_left")
        model.set_active_feature("eye_l_outer")
        window.view3d.view_from(30.0, 5.0)
        settle(0.5)
        save(window, "studio_fitted.png")

        view = window.show_photo("front")
        model.set_active_feature("brow_l_mid")
        model.set_active_curve("brow_l")
        view.center_on_image(610.0, 370.0, scale=2.2)
        settle(0.3)
        save(view, "photo_closeup.png")

        v3 = window.view3d
        v3.view_from(35.0, 10.0)
        v3.distance_mm = 520.0
        v3.resize(640, 640)
        v3.render_image(640, 640).save(str(args.out / "view3d.png"))
        print(args.out / "view3d.png")
        model.modified = False
        window.close()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
