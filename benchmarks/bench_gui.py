"""How fast the studio refits after one moved click: edit → refit in the worker → overlay redrawn.

Runs the real window offscreen on a copy of the sample project. After one fit from scratch, it
moves one click (alternately by ±2 px, through the undo stack exactly as a drag does) and
measures, for each move, the wall time from the edit until the fitted result has been applied,
the current photo's wireframe overlay drawn (the model's ``fit_changed`` observers, the
overlay among them, have all run) and the window repainted with it (a synchronous repaint of
the photo view also repaints the other dirty widgets of the window: the 3D view, re-rendered
with the new mesh, is included): ``refit_ms``, the time until the new overlay is on screen, which
is also when the GUI thread is free again. The auto-refit debounce is set to 0 so that it is
not counted.

The overlay's lines are computed in the fit's worker right after the refit (:mod:`app.qt.workers`),
so the GUI thread only paints them. ``gui_busy_ms`` is the GUI thread's share of an edit: the
edit itself (the undo-stack push and its observers) plus the time from the fit's result
arriving (``StudioModel.apply_fit``) to the window repainted; the rest of ``refit_ms`` the GUI
thread waits in its event loop, free for input. ``overlay_ms`` is the time computing the
overlay's lines (wherever it ran; ``overlay_in_worker`` says where), ``overlay_gui_ms`` the GUI
thread's part of drawing it.

What makes the refit fast (see :mod:`photomodel.modeling.refit`): the RBF weights for the constrained
vertex set are cached (a refit is one matrix product instead of three solves and kernel
evaluations), and the previous fit warm-starts the curve parameterisation so one refinement
pass replaces two. Pose recovery runs in full every time. Since 2026-12-04 (issue 40): the fit
worker keeps its OpenGL renderer across refits (:meth:`app.studio.fitting.Fitting.thread_renderer`;
a QThreadPool task runs under a fresh Python thread state, so the per-thread renderer was rebuilt,
shaders compiled, for every refit), the overlay's depth map is read back alone
(``Renderer.render_depth``), and the refinement triangulates every point and curve vertex in one
batched call. Per refit on the sample (thread CPU time, the same loaded host, main → now): the
worker's fit 31 → 22 ms, its overlay 30 → 6 ms, the GUI thread ~65 ms unchanged. Since 2026-12-05
the GUI thread's part is smaller: the overlay is drawn as one ``QPainterPath`` per kind read from a
numpy buffer (:func:`app.qt.photo_items.segments_path`), the worker's snapshot copies the clicks
as one array per photo, the 3D view keeps its features' visibility per render and draws its image
with ``Renderer.render_rgb8``: GUI-thread CPU of an applied result ~34–43 → ~26 ms.

    .venv/bin/python benchmarks/bench_gui.py [--repeats 7] [--json]

Prints the medians; ``--json`` prints ``{"refit_ms", "gui_busy_ms", "refit_compute_ms", "overlay_ms",
"overlay_gui_ms", "overlay_in_worker", "view3d_ms", "pose_point_refit_ms", "pose_point_gui_busy_ms",
"pose_point_refit_compute_ms", "cold_refit_ms", "full_fit_ms", "repeats", "bar_ms", "passes"}``
(milliseconds).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

from photomodel.modeling.fit import fit_expression

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

BAR_MS = 100.0  # issue 40: refit after one moved click ≤ 100 ms (was 300)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7, help="moves measured per kind of point (median reported)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)

    from PySide6.QtCore import QEventLoop, QSettings, QTimer
    from PySide6.QtWidgets import QApplication

    from app.qt.main_window import MainWindow
    from app.studio.commands import SetPointCommand

    app = QApplication.instance() or QApplication([])
    tmp = Path(tempfile.mkdtemp(prefix="bench_gui_"))
    try:
        shutil.copytree(REPO / "sample_projects" / "james", tmp / "james")
        project_file = tmp / "james" / "james.facestudio.json"
        window = MainWindow(
            settings=QSettings(str(tmp / "settings.ini"), QSettings.Format.IniFormat), autosave_interval_ms=0
        )
        window.resize(1400, 900)
        window.show()
        if not window.open_project(project_file):
            raise SystemExit("could not open the sample project")
        model = window.model
        view = window.show_photo("front")
        app.processEvents()

        applied = {}
        apply_fit = model.apply_fit

        def timed_apply_fit(*a, **k):  # when the fit's result reaches the GUI thread
            applied["t"] = time.perf_counter()
            return apply_fit(*a, **k)

        model.apply_fit = timed_apply_fit

        def wait_for_fit(timeout_ms: int = 60_000) -> float:
            """Run the event loop until the next fit has been applied and observed; the time then."""
            loop = QEventLoop()
            done = {}

            def on_fit(expression):
                view.viewport().repaint()  # the photo with its markers and new overlay, painted now
                done["t"] = time.perf_counter()
                loop.quit()

            model.fit_changed.connect(on_fit)  # connected last: runs after the views' overlay update
            QTimer.singleShot(timeout_ms, loop.quit)
            loop.exec()
            model.fit_changed.disconnect(on_fit)
            if "t" not in done:
                raise SystemExit("timed out waiting for a fit")
            return done["t"]

        # reference: the full pipeline from scratch, no caches
        t0 = time.perf_counter()
        fit_expression(model.fit_snapshot(), "neutral", model.mesh)
        full_fit_ms = (time.perf_counter() - t0) * 1000

        window.fits._timer.setInterval(0)
        window.run_fit()
        wait_for_fit()

        def measure(feature: str, n: int):
            rows = []
            for i in range(n):
                uv = model.photo("front").points[feature] + (2.0 if i % 2 == 0 else -2.0)
                t0 = time.perf_counter()
                window.undo_stack.push(SetPointCommand(model, "neutral", "front", feature, uv))
                t_pushed = time.perf_counter()
                t1 = wait_for_fit()
                fit = model.fit()
                gui_ms = (t_pushed - t0 + t1 - applied["t"]) * 1000
                overlay_gui = (view.overlay_time_s or 0.0) * 1000
                # before the overlay moved to the worker, its whole computation was GUI time
                compute = getattr(view, "overlay_compute_s", None)
                overlay_ms = overlay_gui if compute is None else compute * 1000
                rows.append(
                    (
                        (t1 - t0) * 1000,
                        fit.elapsed_s * 1000,
                        overlay_ms,
                        (window.view3d.last_render_s or 0.0) * 1000,
                        gui_ms,
                        overlay_gui,
                        bool(getattr(view, "overlay_from_cache", False)),
                    )
                )
            return rows

        # the first refit after the fit from scratch, measured apart (first use of the warm path)
        cold = measure("jaw_05", 1)[0][0]
        rows = measure("jaw_05", args.repeats)
        pose_rows = measure("nose_tip", args.repeats)
        model.modified = False
        window.close()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)

    med = lambda k, r=rows: statistics.median(x[k] for x in r)  # noqa: E731
    out = {
        "refit_ms": round(med(0), 1),
        "gui_busy_ms": round(med(4), 1),
        "refit_compute_ms": round(med(1), 1),
        "overlay_ms": round(med(2), 1),
        "overlay_gui_ms": round(med(5), 1),
        "overlay_in_worker": all(r[6] for r in rows + pose_rows),
        "view3d_ms": round(med(3), 1),
        "pose_point_refit_ms": round(med(0, pose_rows), 1),
        "pose_point_gui_busy_ms": round(med(4, pose_rows), 1),
        "pose_point_refit_compute_ms": round(med(1, pose_rows), 1),
        "cold_refit_ms": round(cold, 1),
        "full_fit_ms": round(full_fit_ms, 1),
        "repeats": args.repeats,
        "bar_ms": BAR_MS,
        "passes": max(med(0), med(0, pose_rows)) < BAR_MS,
    }
    if args.json:
        print(json.dumps(out))
    else:
        where = "worker" if out["overlay_in_worker"] else "GUI thread"
        rows_out = [
            (f"edit → overlay painted, refinement point moved (median of {args.repeats})", out["refit_ms"]),
            ("  of which the refit in the worker", out["refit_compute_ms"]),
            (f"  of which computing the current photo's overlay ({where})", out["overlay_ms"]),
            ("  of which the 3D view's render (GUI thread)", out["view3d_ms"]),
            ("  GUI thread busy (edit + result applied → repainted)", out["gui_busy_ms"]),
            ("    of which the overlay", out["overlay_gui_ms"]),
            ("edit → overlay painted, pose point moved", out["pose_point_refit_ms"]),
            ("  of which the refit in the worker", out["pose_point_refit_compute_ms"]),
            ("  GUI thread busy", out["pose_point_gui_busy_ms"]),
            ("first refit after the fit from scratch", out["cold_refit_ms"]),
            ("full fit from scratch, no caches (reference)", out["full_fit_ms"]),
        ]
        print("studio refit after one moved click (sample project, 5 photos, offscreen)")
        for label, ms in rows_out:
            print(f"  {label:<66} {ms:7.1f} ms")
        print(f"  bar < {BAR_MS:.0f} ms: {'PASS' if out['passes'] else 'FAIL'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
