"""Work off the GUI thread: fits run in a :class:`QThreadPool` worker, the window stays responsive.

:class:`FitController` owns one single-thread pool. ``start(expression)`` snapshots the project
(:meth:`StudioModel.fit_snapshot`), fits the snapshot in the worker
(:meth:`StudioModel.compute_fit`) and hands the result back to the GUI thread through a
queued Qt signal, where it is applied to the model — unless the project was replaced in the
meantime (then it is dropped). Cancelling sets a flag that :func:`photomodel.modeling.fit.fit_expression`
polls between its stages (``cancel=``).

The wireframe overlay of the photos on screen (:attr:`FitController.overlay_photos`) is
computed in the same worker job right after the fit (:meth:`StudioModel.compute_overlays`)
and travels with the result, so the GUI thread only paints it; a result that is dropped (an
older edit's, a replaced project's) drops its overlays with it, so a stale overlay never shows.

Auto-refit: after each edit, :meth:`FitController.schedule_refit` starts a warm refit
(:mod:`photomodel.modeling.refit`) after a short debounce, when the last warm refit of the project took
less than :data:`AUTO_REFIT_MAX_S`; edits made while a refit runs are picked up by one more
refit when it finishes.
"""

from __future__ import annotations

import threading
import traceback

from PySide6.QtCore import QObject, QRunnable, QThreadPool, QTimer, Signal

from app.studio_state import StudioModel
from photomodel.errors import Cancelled, FaceStudioError

#: Refit automatically after an edit only when the last warm refit was at least this fast (s).
AUTO_REFIT_MAX_S = 0.3
#: Debounce between an edit and the automatic refit it triggers (ms); a drag's release and the
#: next click within it make one refit.
AUTO_REFIT_DELAY_MS = 60


class _TaskSignals(QObject):
    progress = Signal(str, float)
    finished = Signal(object, float, bool, object)  # FitResult, seconds, built caches (cold), overlays
    failed = Signal(str)
    cancelled = Signal()


class _CancellableTask(QRunnable):
    """A :class:`QRunnable` that can be cancelled and reports through ``signals`` (progress,
    finished, failed, cancelled); kept alive by its controller until its signals are delivered."""

    def __init__(self, signals: QObject):
        super().__init__()
        self.setAutoDelete(False)
        self.signals = signals
        self._cancel = threading.Event()
        self.done = threading.Event()

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def _progress(self, stage: str, frac: float) -> None:
        self.signals.progress.emit(stage, float(frac))

    def _guarded(self, compute, finish) -> None:  # worker thread
        try:
            out = compute()
        except Cancelled:
            self.signals.cancelled.emit()
        except FaceStudioError as exc:
            self.signals.failed.emit(str(exc))
        except Exception as exc:  # an unexpected failure is reported with its cause, not swallowed
            self.signals.failed.emit(f"{type(exc).__name__}: {exc}\n\n{traceback.format_exc(limit=6)}")
        else:
            if self._cancel.is_set():  # finished after Cancel was pressed: the result is discarded
                self.signals.cancelled.emit()
            else:
                finish(out)
        finally:
            self.done.set()


class FitTask(_CancellableTask):
    """One fit of one expression of a project snapshot, run by a :class:`QThreadPool`."""

    def __init__(self, model: StudioModel, expression: str, warm: bool, overlay_photos=()):
        super().__init__(_TaskSignals())
        self.model, self.expression, self.warm = model, expression, warm
        self.snapshot = model.fit_snapshot()
        self.previous = model.warm_start(expression) if warm else None  # read here, on the GUI thread
        self.generation = model.generation
        self.photo_ids = self.photos_now()  # a result for another set of photos is not applied
        self.overlay_photos = tuple(overlay_photos)
        self.lines = model.overlay_lines if self.overlay_photos else None  # built (once) on the GUI thread

    def photos_now(self) -> tuple[str, ...] | None:
        """The ids of the expression's photos now (None: the expression is gone)."""
        try:
            return tuple(p.id for p in self.model.project.expression(self.expression).photos)
        except FaceStudioError:
            return None

    def still_valid(self) -> bool:
        """Whether the result may be applied: same project, the expression and its photos unchanged."""
        return self.generation == self.model.generation and self.photos_now() == self.photo_ids

    def _compute(self):  # worker thread
        result, seconds, cold = self.model.compute_fit(
            self.snapshot,
            self.expression,
            previous=self.previous,
            progress=self._progress,
            cancel=self._cancel.is_set,
        )
        overlays = {}
        if self.overlay_photos and not self._cancel.is_set():
            overlays = self.model.compute_overlays(result, self.overlay_photos, self.lines)
        return result, seconds, cold, overlays

    def run(self) -> None:  # worker thread
        self._guarded(self._compute, lambda out: self.signals.finished.emit(*out))


class FitController(QObject):
    """Runs fits for a :class:`StudioModel` in a worker thread, one at a time.

    Signals
    -------
    started (expression, interactive), progress (stage, fraction), finished (expression, seconds),
    failed (message), cancelled (), busy_changed (bool).

    Attributes
    ----------
    overlay_photos : callable expression → iterable of photo ids, optional
        Asked on the GUI thread when a fit starts: the photos whose overlay the worker computes
        after the fit (the window passes the photo on screen).
    """

    started = Signal(str, bool)
    progress = Signal(str, float)
    finished = Signal(str, float)
    failed = Signal(str)
    cancelled = Signal()
    busy_changed = Signal(bool)

    def __init__(self, model: StudioModel, parent: QObject | None = None):
        super().__init__(parent)
        self.model = model
        self.pool = QThreadPool(self)
        self.pool.setMaxThreadCount(1)
        self.pool.setExpiryTimeout(-1)  # keep the thread (and its caches) alive
        self.task: FitTask | None = None
        self.auto_refit = True
        self.last_warm_s: float | None = None
        self.last_fit_s: float | None = None
        self._pending_expression: str | None = None
        self.overlay_photos = None
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(AUTO_REFIT_DELAY_MS)
        self._timer.timeout.connect(self._auto_refit_now)
        model.project_replaced.connect(self._on_project_replaced)

    @property
    def busy(self) -> bool:
        return self.task is not None

    def auto_refit_possible(self, expression: str | None = None) -> bool:
        """Whether an edit would trigger a refit now: enabled, fitted before (from the photos, not a
        scan: :attr:`app.studio.fitting.FitState.from_scan`), fast enough."""
        name = expression or self.model.expression_name
        fit = self.model.fit(name) if name is not None else None
        return (
            self.auto_refit
            and fit is not None
            and not fit.from_scan  # a refit from the clicks would replace the scan's shape
            and (self.last_warm_s is None or self.last_warm_s < AUTO_REFIT_MAX_S)
        )

    def start(self, expression: str | None = None, *, warm: bool = False) -> FitTask | None:
        """Start fitting ``expression`` (default: current); returns the task, None if busy."""
        name = expression or self.model.expression_name
        if name is None or self.task is not None:
            if name is not None:
                self._pending_expression = name if warm else self._pending_expression
            return None
        task = FitTask(self.model, name, warm, self.overlay_photos(name) if self.overlay_photos else ())
        task.signals.progress.connect(self.progress)
        task.signals.finished.connect(
            lambda result, s, cold, overlays, t=task: self._on_finished(t, result, s, cold, overlays)
        )
        task.signals.failed.connect(lambda msg, t=task: self._on_ended(t, failed=msg))
        task.signals.cancelled.connect(lambda t=task: self._on_ended(t, cancelled=True))
        self.task = task
        self.busy_changed.emit(True)
        self.started.emit(name, warm)
        self.pool.start(task)
        return task

    def cancel(self) -> None:
        if self.task is not None:
            self.task.cancel()
        self._pending_expression = None
        self._timer.stop()

    def schedule_refit(self, expression: str | None = None) -> None:
        """Called after an edit: refit soon if :meth:`auto_refit_possible`."""
        name = expression or self.model.expression_name
        if not self.auto_refit_possible(name):
            return
        self._pending_expression = name
        if self.task is None:
            self._timer.start()

    def wait(self, timeout_s: float = 30.0) -> bool:
        """Block until the running task's worker is done (tests, shutdown); signals still queue."""
        t = self.task
        return True if t is None else t.done.wait(timeout_s)

    def _auto_refit_now(self) -> None:
        name, self._pending_expression = self._pending_expression, None
        if name is not None and self.task is None:
            try:
                self.model.project.expression(name)
            except FaceStudioError:
                return
            self.start(name, warm=True)

    def _on_finished(self, task: FitTask, result, seconds: float, cold: bool = False, overlays=None) -> None:
        if task is not self.task:
            return
        # a photo added or removed meanwhile (or undone), another project: the fit is of photos
        # that are no longer the expression's, and storing it would make the project invalid
        applied = task.still_valid()
        if applied:
            self.model.apply_fit(task.expression, result, seconds, overlays=overlays)
            self.last_fit_s = seconds
            if task.warm and not cold:  # a refit that rebuilt the RBF cache says nothing about the next
                self.last_warm_s = seconds
        self._end(task)
        if applied:
            self.finished.emit(task.expression, seconds)
        else:  # superseded: whoever waits for this fit (a progress dialog) hears it ended
            self.cancelled.emit()
        self._continue()

    def _on_ended(self, task: FitTask, failed: str | None = None, cancelled: bool = False) -> None:
        if task is not self.task:
            return
        self._end(task)
        if failed is not None:
            self._pending_expression = None  # the same clicks would fail again
            self.failed.emit(failed)
        elif cancelled:
            self.cancelled.emit()
        self._continue()

    def _end(self, task: FitTask) -> None:
        self.task = None
        self.busy_changed.emit(False)

    def _continue(self) -> None:
        if self._pending_expression is not None and self.task is None:
            self._timer.start()

    def _on_project_replaced(self) -> None:
        self.cancel()
        self.last_warm_s = None
        self.last_fit_s = None

    def shutdown(self, timeout_s: float = 10.0) -> None:
        """Cancel and wait for the worker (window close)."""
        self.cancel()
        self.wait(timeout_s)
        self.pool.waitForDone(int(timeout_s * 1000))


class _JobSignals(QObject):
    progress = Signal(str, float)
    finished = Signal(object)
    failed = Signal(str)
    cancelled = Signal()


class JobTask(_CancellableTask):
    """Any slow computation ``function(progress=, cancel=)`` run by a :class:`QThreadPool`.

    ``function`` must only read what it was given (snapshots taken on the GUI thread); it polls
    ``cancel()`` and may raise :class:`photomodel.errors.Cancelled`.
    """

    def __init__(self, function, generation: int):
        super().__init__(_JobSignals())
        self.function, self.generation = function, generation

    def run(self) -> None:  # worker thread
        self._guarded(
            lambda: self.function(progress=self._progress, cancel=self._cancel.is_set), self.signals.finished.emit
        )


class JobController(QObject):
    """Runs one :class:`JobTask` at a time in its own worker thread (texture extraction).

    A result is handed to ``on_result`` on the GUI thread unless the task was cancelled or the
    project was replaced meanwhile (then it is dropped).

    Signals
    -------
    progress (stage, fraction), finished (result), failed (message), cancelled (), busy_changed (bool).
    """

    progress = Signal(str, float)
    finished = Signal(object)
    failed = Signal(str)
    cancelled = Signal()
    busy_changed = Signal(bool)

    def __init__(self, model: StudioModel, parent: QObject | None = None):
        super().__init__(parent)
        self.model = model
        self.pool = QThreadPool(self)
        self.pool.setMaxThreadCount(1)
        self.task: JobTask | None = None
        model.project_replaced.connect(self.cancel)

    @property
    def busy(self) -> bool:
        return self.task is not None

    def start(self, function) -> JobTask | None:
        """Run ``function(progress=, cancel=)`` in the worker; None if a job is running."""
        if self.task is not None:
            return None
        task = JobTask(function, self.model.generation)
        task.signals.progress.connect(self.progress)
        task.signals.finished.connect(lambda result, t=task: self._on_done(t, result=result))
        task.signals.failed.connect(lambda msg, t=task: self._on_done(t, failed=msg))
        task.signals.cancelled.connect(lambda t=task: self._on_done(t, cancelled=True))
        self.task = task
        self.busy_changed.emit(True)
        self.pool.start(task)
        return task

    def cancel(self) -> None:
        if self.task is not None:
            self.task.cancel()

    def wait(self, timeout_s: float = 30.0) -> bool:
        t = self.task
        return True if t is None else t.done.wait(timeout_s)

    def _on_done(self, task: JobTask, result=None, failed: str | None = None, cancelled: bool = False) -> None:
        if task is not self.task:
            return
        self.task = None
        self.busy_changed.emit(False)
        if failed is not None:
            self.failed.emit(failed)
        elif cancelled or task.cancelled or task.generation != self.model.generation:
            self.cancelled.emit()
        else:
            self.finished.emit(result)

    def shutdown(self, timeout_s: float = 10.0) -> None:
        self.cancel()
        self.wait(timeout_s)
        self.pool.waitForDone(int(timeout_s * 1000))
