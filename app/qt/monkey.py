"""A monkey for the studio: seeded random sequences of what an artist does, through the real widgets.

Each action (:data:`ACTIONS`) is what an artist does with the mouse and keyboard — switch the
expression (toolbar combo) or the photo tab (a click on the tab bar), pick a feature in the
panel and click a photo (sometimes off the photo), drag a marker, ``Delete``, ``H``, draw a
curve (``C`` mode, clicks, ``Enter`` or ``Esc``), undo and redo (menu actions and both redo
keys), fit, fit then cancel, extract a texture, *File → New*, *Open…*, *Save*, add and remove
photos, close the window (a new one then starts, as a restarted studio does) — driven with
``QTest`` mouse and key events on the widgets, as ``tests/test_gui.py`` drives them. The file
and message dialogs are scripted (:func:`scripted_dialogs`): every question gets a random
allowed answer, the open dialog offers the sample, the files saved so far and damaged copies.

After every action :meth:`Monkey.check` asserts the window's invariants (tabs = the current
expression's photos, the combo on the current expression, the title's modified mark, clicks and
curves naming what the project defines, no unexpected error; every few actions the whole project
written and read back with the loader's checks); before every step that empties the undo stack
(new, open, close) and at the end, :meth:`Monkey.check_undo_all` undoes every edit and compares
the project with the one opened (result records excepted: fits and textures are not edits),
then redoes them all and compares again.

Used by ``tests/test_gui_monkey.py`` (a few seeds in the suite) and ``benchmarks/fuzz_monkey.py``
(each seed in its own process, so that a crash is counted). Not imported by the studio itself.
"""

from __future__ import annotations

import json
import time
from collections import Counter
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path

import numpy as np
from PySide6.QtCore import QEventLoop, QPoint, QPointF, Qt, QTimer
from PySide6.QtTest import QTest
from PySide6.QtWidgets import QApplication, QFileDialog, QInputDialog, QMessageBox

from app.qt.photo_view import PhotoView
from photomodel.project.codec import project_from_dict, project_to_dict

#: Action kinds and their weights (relative frequencies) in a sequence.
ACTIONS = {
    "expression": 4,
    "tab": 8,
    "click": 14,
    "drag": 8,
    "delete": 4,
    "hide": 3,
    "curve": 5,
    "undo": 9,
    "redo": 5,
    "fit": 3,
    "cancel": 2,
    "texture": 3,
    "new": 1,
    "open": 3,
    "save": 2,
    "close": 1,
    "add_photos": 2,
    "remove_photo": 1,
}
#: The longest an action may wait for a worker (fit, texture) before it counts as hung (s).
WORKER_TIMEOUT_S = 120.0
#: Every this many actions :meth:`Monkey.check` also writes and validates the whole project
#: (:meth:`Monkey.check_project`, ~0.3 s on the sample); every action checks the photos shown.
FULL_CHECK_EVERY = 10
#: Texels per side of the monkey's textures: the code path of any size, at a fraction of the time.
MONKEY_TEXTURE_SIZE = 256

_B = QMessageBox.StandardButton
_ANSWERS = (_B.Save, _B.Discard, _B.Cancel, _B.Yes, _B.No)


class InvariantError(AssertionError):
    """The window or the project broke an invariant after an action (the message says which)."""


def comparable(project, target: Path) -> dict:
    """The project as the dict written to ``target``, without what is not an edit: result
    records (fits, textures) and the name a first "save as" gives an untitled project."""
    d = project_to_dict(project, target)
    d.pop("name", None)
    for e in d["expressions"]:
        e.pop("result", None)
    return d


@contextmanager
def scripted_dialogs(
    rng: np.random.Generator,
    open_choices: Callable[[], list[str]],
    save_target: Callable[[], str],
    photo_choices: Callable[[], list[str]],
    log: list,
):
    """Every modal dialog answered at once: message boxes recorded in ``log`` as ``(kind, title,
    text)`` and answered with a random button they offer; file dialogs pick from the choices."""

    def box(kind):
        def answer(parent, title, text, buttons=_B.Ok, default=_B.NoButton, *args, **kwargs):
            log.append((kind, title, text))
            offered = [b for b in _ANSWERS if buttons & b] if kind == "question" else []
            return offered[int(rng.integers(len(offered)))] if offered else _B.Ok

        return staticmethod(answer)

    def open_file(*args, **kwargs):
        choices = open_choices()
        return (choices[int(rng.integers(len(choices)))], "")

    def open_files(*args, **kwargs):
        photos = photo_choices()
        k = int(rng.integers(0, 4))
        return ([photos[i] for i in rng.choice(len(photos), size=min(k, len(photos)), replace=False)], "")

    patches = {
        (QMessageBox, "critical"): box("critical"),
        (QMessageBox, "warning"): box("warning"),
        (QMessageBox, "information"): box("information"),
        (QMessageBox, "question"): box("question"),
        (QFileDialog, "getOpenFileName"): staticmethod(open_file),
        (QFileDialog, "getOpenFileNames"): staticmethod(open_files),
        (QFileDialog, "getSaveFileName"): staticmethod(lambda *a, **k: (save_target(), "")),
        (QFileDialog, "getExistingDirectory"): staticmethod(lambda *a, **k: ""),
        (QInputDialog, "getText"): staticmethod(lambda *a, **k: ("", False)),
        (QInputDialog, "getItem"): staticmethod(lambda *a, **k: ("", False)),
        (QInputDialog, "getInt"): staticmethod(lambda *a, **k: (MONKEY_TEXTURE_SIZE, False)),
    }
    saved = {key: key[0].__dict__.get(key[1]) for key in patches}
    for (cls, name), value in patches.items():
        setattr(cls, name, value)
    try:
        yield log
    finally:
        for (cls, name), value in saved.items():
            if value is None:
                delattr(cls, name)
            else:
                setattr(cls, name, value)


def process_events_for(ms: int) -> None:
    """Run the event loop for ``ms`` milliseconds (as the studio's own loop runs).

    Not :func:`QTest.qWait`: PySide6 holds the GIL while it sleeps between its event batches, so a
    worker thread (a fit, a texture) gets the interpreter only in the gaps — measured, a fit of the
    sample's neutral took 79 s under ``qWait(10)`` polling and 6.7 s under a :class:`QEventLoop`,
    which releases the GIL while it waits, as ``QApplication.exec`` does."""
    loop = QEventLoop()
    QTimer.singleShot(max(0, int(ms)), loop.quit)
    loop.exec()


def wait_until(condition: Callable[[], bool], timeout_s: float) -> bool:
    """Process events until ``condition()`` holds; False after ``timeout_s``."""
    end = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > end:
            return False
        process_events_for(10)
    return True


def damaged_copies(project: Path, folder: Path) -> list[Path]:
    """Files an artist might open by mistake: truncated, not JSON, nested thousands deep, a
    project moved away from its photos."""
    folder.mkdir(parents=True, exist_ok=True)
    text = project.read_text()
    files = {
        "truncated.facestudio.json": text[: len(text) // 2],
        "notes.facestudio.json": "these are my notes, not a project",
        "deep.facestudio.json": '{"format": ' + "[" * 50_000 + "]" * 50_000 + "}",
        "moved.facestudio.json": text,  # its photos are not beside it: the missing-photos question
    }
    out = []
    for name, content in files.items():
        (folder / name).write_text(content)
        out.append(folder / name)
    return out


class Monkey:
    """Random artist actions on the windows ``make_window()`` builds.

    Parameters
    ----------
    make_window : () -> MainWindow, a new shown window (called again after a close).
    seed : int, the sequence (same seed, same actions).
    workdir : a folder for saved projects and damaged files.
    project : the project to start on (a copy; None: an empty project) — also in the open dialog.
    photos : image files the *Add photos* dialog offers.
    weights : action kind → weight (default :data:`ACTIONS`).
    """

    def __init__(
        self,
        make_window,
        seed: int,
        workdir: Path,
        project: Path | None,
        photos: list[Path],
        weights: dict | None = None,
    ):
        self.make_window, self.rng = make_window, np.random.default_rng(seed)
        self.workdir = Path(workdir)
        self.photos = [str(p) for p in photos]
        weights = dict(ACTIONS if weights is None else weights)
        self.kinds = list(weights)
        p = np.array([weights[k] for k in self.kinds], float)
        self.p = p / p.sum()
        self.by_kind: Counter = Counter()
        self._steps = 0
        self.messages: list = []
        self.saved: list[str] = []
        # the open dialog offers the project, damaged copies, a file that is not there (and, in
        # run, the files saved so far and a cancelled dialog)
        self.opens = [str(self.workdir / "does_not_exist.facestudio.json")]
        if project is not None:
            self.opens += [str(project), *(str(f) for f in damaged_copies(project, self.workdir / "damaged"))]
        self.window = make_window()
        self.window.texture_size = MONKEY_TEXTURE_SIZE
        if project is not None:
            assert self.window.open_project(project, ask_to_save=False), self.messages
        self._compare_to = self.workdir / "compare" / "compare.facestudio.json"
        self._rebase()

    # ------------------------------------------------------------------ running
    def run(self, actions: int, on_step: Callable[[str], None] | None = None) -> Counter:
        """``actions`` random actions, each followed by :meth:`check`; then :meth:`check_undo_all`."""
        with scripted_dialogs(
            self.rng, lambda: [*self.opens, *self.saved, ""], self._save_target, lambda: self.photos, self.messages
        ):
            for _ in range(actions):
                kind = self.kinds[int(self.rng.choice(len(self.kinds), p=self.p))]
                if on_step is not None:
                    on_step(kind)
                self.step(kind)
            self.settle()
            self.check_undo_all()
        return self.by_kind

    def step(self, kind: str) -> None:
        """One action of ``kind``, then :meth:`check`."""
        if kind in ("new", "open", "close"):  # these empty the undo stack: check it first
            self.settle()
            self.check_undo_all()
        getattr(self, f"_do_{kind}")()
        self.by_kind[kind] += 1
        process_events_for(1)
        self.check()

    def settle(self) -> None:
        """Wait for the workers (refits, textures) so that a check sees a quiet model."""
        w = self.window
        if not wait_until(lambda: not w.fits.busy and not w.jobs.busy, WORKER_TIMEOUT_S):
            raise InvariantError(f"a worker is still busy after {WORKER_TIMEOUT_S} s")
        process_events_for(70)  # the auto-refit's debounce (60 ms) may start one more
        wait_until(lambda: not w.fits.busy, WORKER_TIMEOUT_S)

    def _save_target(self) -> str:
        target = self.workdir / f"saved_{len(self.saved)}.facestudio.json"
        self.saved.append(str(target))
        return str(target)

    # ------------------------------------------------------------------ invariants
    def _rebase(self) -> None:
        self._base_project = self.window.model.project
        self._base = comparable(self._base_project, self._compare_to)

    def check(self) -> None:
        """The window's invariants after an action; :class:`InvariantError` names the broken one."""
        w, m = self.window, self.window.model
        if m.project is not self._base_project:  # replaced: new, open, recover
            if len(w.undo_stack) != 0:
                raise InvariantError("a new project came with the previous project's undo history")
            self._rebase()
        ids = [p.id for p in m.photos]
        tabs = [w.tabs.widget(i) for i in range(w.tabs.count())]
        shown = [t.photo_id for t in tabs if isinstance(t, PhotoView)]
        if shown != ids or list(w.views) != ids or (not ids and w.tabs.count() != 1):
            raise InvariantError(f"tabs {shown} / views {list(w.views)} but photos {ids}")
        if any(t.expression != m.expression_name or t.detached for t in tabs if isinstance(t, PhotoView)):
            raise InvariantError("a tab shows a photo of another expression or a detached view")
        if w.expr_combo.currentData() != m.expression_name:
            raise InvariantError(f"combo on {w.expr_combo.currentData()!r}, model on {m.expression_name!r}")
        if w.isWindowModified() != m.modified:
            raise InvariantError(f"title modified mark {w.isWindowModified()} but model {m.modified}")
        self._check_photos()
        self._steps += 1
        if self._steps % FULL_CHECK_EVERY == 0:
            self.check_project()
        if w.unexpected_errors:
            raise InvariantError(f"unexpected errors: {w.unexpected_errors}")

    def _check_photos(self) -> None:
        """The current expression's clicks, hidden features and curves name what the project defines."""
        project = self.window.model.project
        features, curves = set(project.feature_names()), {c.name for c in project.curves}
        for p in self.window.model.photos:
            if not set(p.points) <= features or not set(p.hidden) <= features or not set(p.curves) <= curves:
                raise InvariantError(f"photo {p.id!r} refers to a feature or curve the project lacks")
            uv = np.array([*p.points.values()], float).reshape(-1, 2)
            if not np.isfinite(uv).all():
                raise InvariantError(f"photo {p.id!r} holds a click that is not a finite number")

    def check_project(self) -> None:
        """The project in memory can be written and read back with every check of the loader."""
        try:
            project_from_dict(json.loads(json.dumps(project_to_dict(self.window.model.project, self._compare_to))))
        except Exception as exc:
            raise InvariantError(f"the project in memory does not validate: {type(exc).__name__}: {exc}") from exc

    def check_undo_all(self) -> None:
        """Undo every edit: the project equals the one opened (results excepted); redo them all."""
        w = self.window
        now = comparable(w.model.project, self._compare_to)
        n = w.undo_stack.index
        for _ in range(n):
            w.act_undo.trigger()
        if comparable(w.model.project, self._compare_to) != self._base:
            raise InvariantError(f"undoing all {n} edits does not give the project back")
        for _ in range(n):
            w.act_redo.trigger()
        if comparable(w.model.project, self._compare_to) != now:
            raise InvariantError(f"redoing all {n} edits does not give the edited project back")
        self.check_project()
        self.check()

    # ------------------------------------------------------------------ helpers
    def _pick(self, items):
        items = list(items)
        return items[int(self.rng.integers(len(items)))] if items else None

    def _view(self) -> PhotoView | None:
        return self.window.current_view()

    def _pos_of(self, view: PhotoView, uv) -> QPoint:
        p = view.mapFromScene(QPointF(float(uv[0]), float(uv[1])))
        r = view.viewport().rect()
        return QPoint(min(max(p.x(), 0), r.width() - 1), min(max(p.y(), 0), r.height() - 1))

    def _random_uv(self, view: PhotoView) -> tuple[float, float]:
        w, h = view.photo_size  # 5 % of clicks land off the photo (a misplaced click)
        return tuple(self.rng.uniform(-0.05, 1.05, 2) * (w, h))

    def _pick_feature(self) -> None:
        panel = self.window.panel
        item = self._pick(panel.feature_items())
        if item is not None:
            panel.features.setCurrentItem(item)

    def _points_mode(self) -> None:
        if self.window.mode != "points":
            self.window.act_mode_points.trigger()

    # ------------------------------------------------------------------ actions
    def _do_expression(self):
        combo = self.window.expr_combo
        if combo.count():
            i = int(self.rng.integers(combo.count()))
            combo.setCurrentIndex(i)
            combo.activated.emit(i)

    def _do_tab(self):
        bar = self.window.tabs.tabBar()
        if bar.count():
            QTest.mouseClick(
                bar,
                Qt.MouseButton.LeftButton,
                Qt.KeyboardModifier.NoModifier,
                bar.tabRect(int(self.rng.integers(bar.count()))).center(),
            )

    def _do_click(self):
        view = self._view()
        if view is None:
            return
        self._points_mode()
        self._pick_feature()
        QTest.mouseClick(
            view.viewport(),
            Qt.MouseButton.LeftButton,
            Qt.KeyboardModifier.NoModifier,
            self._pos_of(view, self._random_uv(view)),
        )

    def _do_drag(self):
        view = self._view()
        name = None if view is None else self._pick(view.markers)
        if name is None:
            return
        self._points_mode()
        start = self._pos_of(view, view.markers[name].pos().toTuple())
        d = QPoint(*(int(x) for x in self.rng.integers(-40, 41, 2)))
        vp = view.viewport()
        QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, start)
        QTest.mouseMove(vp, start + d / 2)
        QTest.mouseMove(vp, start + d)
        QTest.mouseRelease(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, start + d)

    def _key(self, key) -> None:
        view = self._view()
        if view is not None:
            view.setFocus()
            QTest.keyClick(view, key)

    def _do_delete(self):
        self._pick_feature()
        self._key(Qt.Key.Key_Delete)

    def _do_hide(self):
        self._pick_feature()
        self._key(Qt.Key.Key_H)

    def _do_curve(self):
        view, panel = self._view(), self.window.panel
        if view is None:
            return
        item = self._pick(panel.curves.topLevelItem(i) for i in range(panel.curves.topLevelItemCount()))
        if item is not None:
            panel.curves.setCurrentItem(item)
        self.window.act_mode_curve.trigger()
        for _ in range(int(self.rng.integers(1, 6))):
            QTest.mouseClick(
                view.viewport(),
                Qt.MouseButton.LeftButton,
                Qt.KeyboardModifier.NoModifier,
                self._pos_of(view, self._random_uv(view)),
            )
        self._key(Qt.Key.Key_Escape if self.rng.random() < 0.15 else Qt.Key.Key_Return)
        self._points_mode()

    def _do_undo(self):
        w = self.window
        if self.rng.random() < 0.5 and self._view() is not None:
            w.activateWindow()
            self._view().setFocus()
            QTest.keyClick(self._view(), Qt.Key.Key_Z, Qt.KeyboardModifier.ControlModifier)
        else:
            w.act_undo.trigger()

    def _do_redo(self):
        w, r = self.window, self.rng.random()
        if r < 0.6 and self._view() is not None:
            w.activateWindow()
            self._view().setFocus()
            ctrl = Qt.KeyboardModifier.ControlModifier
            key, mods = (Qt.Key.Key_Y, ctrl) if r < 0.3 else (Qt.Key.Key_Z, ctrl | Qt.KeyboardModifier.ShiftModifier)
            QTest.keyClick(self._view(), key, mods)
        else:
            w.act_redo.trigger()

    def _do_fit(self):
        self.window.act_fit.trigger()
        self.settle()

    def _do_cancel(self):
        w = self.window
        w.act_fit.trigger()
        process_events_for(int(self.rng.integers(0, 400)))
        if w.fit_progress is not None:
            w.fit_progress.cancel()  # the progress dialog's Cancel button
        else:
            w.fits.cancel()
        self.settle()

    def _do_texture(self):
        self.window.act_texture.trigger()
        self.settle()

    def _do_new(self):
        self.window.act_new.trigger()

    def _do_open(self):
        self.window.act_open.trigger()

    def _do_save(self):
        self.window.act_save.trigger()

    def _do_add_photos(self):
        self.window.act_add_photos.trigger()

    def _do_remove_photo(self):
        self.window.act_remove_photo.trigger()

    def _do_close(self):
        w = self.window
        w.close()
        QApplication.processEvents()
        if w.isVisible():  # the artist cancelled the unsaved-changes question
            return
        w.model.modified = False  # answered Discard: nothing to ask when the test closes it again
        self.window = self.make_window()  # the studio started again
        self.window.texture_size = MONKEY_TEXTURE_SIZE
        self.window.offer_recovery()
        self._rebase()


__all__ = ["ACTIONS", "InvariantError", "Monkey", "comparable", "scripted_dialogs", "wait_until"]
