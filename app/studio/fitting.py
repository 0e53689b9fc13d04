"""Fitting in the studio: an expression's fit, its wireframe overlays and its click residuals.

:class:`Fitting` runs the fits of one :class:`app.studio_state.StudioModel` (a warm-startable
:class:`photomodel.modeling.refit.Refitter`, shared by every fit) and draws their overlays
(:func:`photomodel.modeling.wireframe.photo_overlay`); :class:`FitState` is one expression's fit as
the studio holds it; :func:`click_residuals` measures the clicks against a fit; :func:`scan_fit_job` fits a scan as an
expression's fit (*Fit → Add scan…*). No Qt: the studio's
workers call :meth:`Fitting.compute` on a snapshot of the project off the GUI thread.
"""

from __future__ import annotations

import copy
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from photomodel.modeling.rbf import deform_vertices
from photomodel.modeling.refit import Refitter
from photomodel.modeling.wireframe import mesh_lines, photo_overlay
from photomodel.prior.face_prior import prior_deformer
from photomodel.prior.scan_expression import fit_scan_as_expression
from photomodel.rendering.renderer import get_renderer


@dataclass
class FitState:
    """The last fit of one expression as the studio holds it.

    Attributes
    ----------
    cameras : dict photo id → Camera
    points_3d : dict feature → (3,) float mm
    vertices : (N, 3) float mm or None
        The fitted mesh (None when a loaded project's mesh file is missing).
    report : dict, the fit report (:func:`photomodel.modeling.fit.build_report`).
    result : photomodel.modeling.fit.FitResult or None
        The in-memory result (warm start of the next refit); None for a loaded result.
    elapsed_s : float or None, wall time of the fit.
    saved : bool, the mesh files on disk hold ``vertices``.
    overlays : dict photo id → photomodel.modeling.wireframe.PhotoOverlay
        The wireframe overlays of this fit computed so far (by the fit's worker for the photo on
        screen, by :meth:`Fitting.overlay` for the others when they are shown).
    """

    cameras: dict
    points_3d: dict
    vertices: np.ndarray | None
    report: dict
    result: object = None
    elapsed_s: float | None = None
    saved: bool = False
    overlays: dict = field(default_factory=dict)

    @classmethod
    def of_result(cls, record, result, elapsed_s: float | None = None, overlays: dict | None = None) -> FitState:
        """The state of a fresh fit: ``record`` its :class:`photomodel.project.ExpressionResult`
        (:func:`photomodel.project.record_fit`), ``result`` the :class:`photomodel.modeling.fit.FitResult`."""
        return cls(
            record.cameras,
            record.points_3d,
            np.asarray(result.vertices),
            result.report,
            result,
            elapsed_s,
            saved=False,
            overlays=dict(overlays or {}),
        )

    @classmethod
    def of_scan(cls, made) -> FitState:
        """The state of a scan fit (:class:`photomodel.prior.scan_expression.ScanExpressionFit`)."""
        r = made.result
        return cls(r.cameras, r.points_3d, np.asarray(made.vertices), r.report, None, made.report.get("seconds"))

    @property
    def from_scan(self) -> bool:
        """Whether this is a scan's fit (*Fit → Add scan…*, ``facestudio fit-scan``): a refit from
        the clicks would replace the scan's shape, so edits do not refit it automatically."""
        return "scan_fit" in self.report

    def warm_start(self):
        """What the next refit starts from: the in-memory result, else the fitted vertices (or None)."""
        return self.result if self.result is not None else self.vertices


class Fitting:
    """The fits of one generic mesh: the shared refitter, the overlay lines, the overlays.

    Parameters
    ----------
    mesh : photomodel.modeling.generic_mesh.GenericMesh
    face_prior : bool
        Fit with the localised face prior (:func:`photomodel.prior.face_prior.prior_deformer`), as
        ``facestudio fit`` does by default (``--no-face-prior``: False). A fit from scratch runs
        the prior (seconds); a refit after an edit deforms the last full fit's answer by the cached
        RBF (:meth:`~photomodel.prior.face_prior.PriorDeformer.warm`, milliseconds).
    """

    def __init__(self, mesh, face_prior: bool = True):
        self.mesh = mesh
        self.face_prior = face_prior
        self._refitter: Refitter | None = None
        self._lines = None
        self._renderers: dict = {}
        self._renderers_lock = threading.Lock()

    @property
    def refitter(self) -> Refitter:
        """The :class:`photomodel.modeling.refit.Refitter` shared by every fit (built on first use)."""
        if self._refitter is None:
            # the full fit's RBF uncached (a new prior shape each time), the refits' cached
            wrap = (
                (lambda cached: prior_deformer(self.mesh, deform_vertices, refit=cached)) if self.face_prior else None
            )
            self._refitter = Refitter(self.mesh, wrap=wrap)
        return self._refitter

    @property
    def overlay_lines(self):
        """The wireframe overlay's lines on the generic mesh (:func:`photomodel.modeling.wireframe.mesh_lines`)."""
        if self._lines is None:
            self._lines = mesh_lines(self.mesh.vertices, self.mesh.faces, curves=self.mesh.curves)
        return self._lines

    def compute(self, snapshot, expression: str, *, previous=None, progress=None, cancel=None):
        """Fit ``expression`` of a project snapshot; safe to call from a worker thread.

        With ``previous`` (:meth:`FitState.warm_start`) the refinement is warm-started from the last
        fit; otherwise this is the full pipeline of :func:`photomodel.modeling.fit.fit_expression`.
        Returns ``(FitResult, elapsed_s, cold)`` where ``cold`` says the fit had to build cached RBF
        solves (a new set of constrained vertices).
        """
        refitter = self.refitter
        misses = refitter.deformer.misses
        t0 = time.perf_counter()
        result = refitter.fit(snapshot, expression, previous=previous, progress=progress, cancel=cancel)
        return result, time.perf_counter() - t0, refitter.deformer.misses != misses

    def thread_renderer(self):
        """The calling thread's renderer, kept for this thread's next call; None without OpenGL.

        :func:`photomodel.rendering.renderer.get_renderer` keeps one per Python thread state
        (``threading.local``), but a :class:`QThreadPool` worker gets a fresh Python thread state
        for every task it runs, so each fit would build (and leak) a new OpenGL context and
        compile its shaders again: ~60–100 ms of every refit on llvmpipe. Keyed by the OS
        thread instead, the fit worker's renderer lives as long as its thread (the studio's
        pool never expires it, :class:`app.qt.workers.FitController`). The key pairs the pthread
        id, which a new thread reuses at once, with the kernel's thread id, which it does not, so a
        later thread never gets the context of one that ended.
        """
        key = (threading.get_ident(), threading.get_native_id())
        with self._renderers_lock:
            found = self._renderers.get(key)
        if found is not None and not found.released:
            return found
        try:
            found = get_renderer()
        except RuntimeError:  # no OpenGL: photo_overlay says so and draws every line
            return None
        with self._renderers_lock:
            self._renderers[key] = found
        return found

    def overlays(self, result, photo_ids, lines) -> dict:
        """The wireframe overlays of a fit in some of its photos; safe to call from a worker thread.

        Parameters
        ----------
        result : photomodel.modeling.fit.FitResult, the fit (cameras and vertices).
        photo_ids : iterable of str; ids the fit has no camera for are skipped.
        lines : photomodel.modeling.wireframe.MeshLines, :attr:`overlay_lines` read on the GUI thread.

        Returns
        -------
        dict photo id → photomodel.modeling.wireframe.PhotoOverlay, for :attr:`FitState.overlays`.
        """
        cams = dict(zip(result.photo_ids, result.cameras, strict=True))
        faces = self.mesh.faces
        wanted = [pid for pid in photo_ids if pid in cams]
        renderer = self.thread_renderer() if wanted else None
        return {pid: photo_overlay(cams[pid], result.vertices, faces, lines, renderer=renderer) for pid in wanted}

    def overlay(self, fit: FitState | None, photo_id: str):
        """The wireframe overlay of ``fit`` in one photo, or None (no fit, mesh or camera for it).

        Taken from the fit's cache (filled by the fit's worker); computed here, on the calling
        thread, and cached when missing (a photo that was not on screen when the fit ran).
        """
        if fit is None or fit.vertices is None or photo_id not in fit.cameras:
            return None
        found = fit.overlays.get(photo_id)
        if found is None:
            found = fit.overlays[photo_id] = photo_overlay(
                fit.cameras[photo_id], fit.vertices, self.mesh.faces, self.overlay_lines
            )
        return found


def scan_fit_job(project, expression: str, fit: FitState | None, mesh, path):
    """A job ``(progress=, cancel=) → ScanExpressionFit`` for a worker: the scan file ``path`` fitted
    as ``expression``'s fit as ``facestudio fit-scan`` does
    (:func:`photomodel.prior.scan_expression.fit_scan_as_expression`), in the frame of the
    expression's current ``fit`` and with its shape as the template. Reads a copy of ``project``
    and the fit's vertices now (on the calling thread)."""
    snapshot = copy.deepcopy(project)
    template = None if fit is None or fit.vertices is None else np.array(fit.vertices)

    def job(progress=None, cancel=None):
        return fit_scan_as_expression(
            snapshot, expression, path, mesh, template=template, progress=progress, cancel=cancel
        )

    return job


def click_residuals(fit: FitState | None, photos) -> dict[str, dict[str, float]]:
    """Reprojection error (px) of every click with a fitted 3D point: photo id → feature → px.

    ``|project(camera, X) − click|`` with the fitted camera of the photo and the fitted position of
    the feature; hidden clicks and photos the fit has no camera for are left out.
    """
    out: dict[str, dict[str, float]] = {}
    if fit is None:
        return out
    for photo in photos:
        cam = fit.cameras.get(photo.id)
        if cam is None:
            continue
        names = [n for n in photo.points if n in fit.points_3d and n not in photo.hidden]
        if not names:
            continue
        X = np.array([fit.points_3d[n] for n in names])
        uv = np.array([photo.points[n] for n in names])
        err = np.linalg.norm(cam.project(X) - uv, axis=1)
        out[photo.id] = {n: float(e) for n, e in zip(names, err, strict=True)}
    return out


def worst_clicks(residuals: dict[str, dict[str, float]], count: int) -> list[tuple[float, str, str]]:
    """The ``count`` largest of :func:`click_residuals`, ``(px, photo id, feature)``, largest first."""
    rows = [(px, pid, n) for pid, d in residuals.items() for n, px in d.items()]
    rows.sort(key=lambda r: (-r[0], r[1], r[2]))
    return rows[:count]


def predicted_uv(fit: FitState | None, photo_id: str, feature: str, vertex: int | None) -> np.ndarray | None:
    """Where ``fit`` puts a feature in a photo: (2,) px, or None.

    The fitted mesh's ``vertex`` (the feature's) projected with the photo's fitted camera; without a
    mesh or vertex, the fitted 3D point of the feature.
    """
    if fit is None or photo_id not in fit.cameras:
        return None
    if fit.vertices is not None and vertex is not None:
        X = np.asarray(fit.vertices)[int(vertex)]
    elif feature in fit.points_3d:
        X = np.asarray(fit.points_3d[feature])
    else:
        return None
    return fit.cameras[photo_id].project(X[None])[0]


__all__ = ["FitState", "Fitting", "click_residuals", "predicted_uv", "scan_fit_job", "worst_clicks"]
