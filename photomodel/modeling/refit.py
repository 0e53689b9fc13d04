"""Interactive refits: the pipeline of :mod:`photomodel.modeling.fit` made fast enough to rerun after every click.

The studio refits an expression each time the artist moves a point, so that the fitted mesh
follows the clicks live. A full :func:`~photomodel.modeling.fit.fit_expression` on the sample project
takes ~0.6 s; almost all of it is the scattered-data interpolation (§5.1.2, Eq. 3) run three
times over ~8k vertices and ~300 centres, and a second curve pass of the refinement (§5.1.3).
Two observations make a refit cheap without changing what it computes:

* **The interpolant is linear in the displacements.** For a fixed set of constrained vertices
  the deformed mesh is ``V + W (T − V[idx])`` with ``W`` (N × n) depending only on the
  generic mesh and on which vertices are constrained. Moving a click moves targets, not the
  set, so :class:`CachedDeformer` builds ``W`` once — by fitting the very
  :class:`~photomodel.modeling.rbf.RBFInterpolant` of :mod:`photomodel.modeling.rbf` to the identity (n
  right-hand sides sharing one factorisation) and evaluating it at the vertices — and then
  each refit costs one (N × n)·(n × 3) product. The result equals
  :func:`~photomodel.modeling.rbf.deform_vertices` to rounding (tested to 1e-8 mm).
* **The previous fit is a warm start for the curves.** Curves are turned into vertex
  correspondences by arc length on the current fitted mesh, and :func:`fit_expression`
  repeats that step (``curve_passes = 2``) because the pose-only mesh is a poor
  parameterisation. After one moved click the previous fitted mesh is already a good one,
  so :class:`Refitter` runs a single pass on it. This is the one place where a refit differs
  from a fit from scratch: a warm refit after an unchanged fit *is* a third curve pass (equal
  to ``curve_passes = 3`` to 1e-11 mm on the sample project), and successive passes move the
  sample mesh by 0.04 mm on average (the curve-to-vertex assignment settles slowly; ≤ 1.4 mm
  at a few curve vertices), against ~0.3 mm per pixel of click noise.

Pose recovery (§5.1.1) is not warm-started: it takes ~10 ms from the presets and stays
independent of the edit history. Nothing here touches Qt or files.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from photomodel.errors import FitError
from photomodel.modeling.fit import FitOptions, FitResult, fit_expression
from photomodel.modeling.rbf import RBFInterpolant, deform_vertices

#: Weight matrices kept (one per constrained-vertex set; ~20 MB each for 8k vertices × 300 centres).
DEFAULT_CACHE_ENTRIES = 3


class CachedDeformer:
    """:func:`photomodel.modeling.rbf.deform_vertices` with the interpolation weights cached per vertex set.

    Call it exactly like :func:`~photomodel.modeling.rbf.deform_vertices`. Thread-safe.

    Parameters
    ----------
    max_entries : int
        Number of ``(vertices, constrained, options)`` combinations kept (least recently used
        dropped first).
    """

    def __init__(self, max_entries: int = DEFAULT_CACHE_ENTRIES):
        if max_entries < 1:
            raise ValueError(f"max_entries must be >= 1, got {max_entries}")
        self.max_entries = int(max_entries)
        self._cache: OrderedDict = OrderedDict()
        self._lock = threading.Lock()
        self.hits = 0
        self.misses = 0

    def clear(self) -> None:
        with self._lock:
            self._cache.clear()

    def __call__(self, vertices, constrained, targets, **kw) -> np.ndarray:
        """Deformed vertices ``(N, 3)`` mm; see :func:`photomodel.modeling.rbf.deform_vertices`."""
        V = np.asarray(vertices, dtype=float)
        idx = np.asarray(constrained)
        T = np.asarray(targets, dtype=float)
        if (
            V.ndim != 2
            or V.shape[1] != 3
            or idx.ndim != 1
            or not np.issubdtype(idx.dtype, np.integer)
            or T.shape != (idx.shape[0], 3)
            or np.any(idx < 0)
            or np.any(idx >= V.shape[0])
        ):
            return deform_vertices(vertices, constrained, targets, **kw)  # let it word the error
        bad = np.flatnonzero(~np.all(np.isfinite(T), axis=1))
        if bad.size:
            raise FitError(f"target of vertex {int(idx[bad[0]])} is not finite (NaN or inf); remove it")
        options = {k: v for k, v in kw.items() if k != "labels"}  # labels only word error messages
        key = (_fingerprint(V), idx.astype(np.int64).tobytes(), tuple(sorted(options.items())))
        with self._lock:
            W = self._cache.get(key)
            if W is not None:
                self._cache.move_to_end(key)
                self.hits += 1
        if W is None:
            self.misses += 1
            try:
                # the interpolant of the identity: column j is the response to a unit move of centre j
                interp = RBFInterpolant.fit(V[idx], np.eye(idx.shape[0]), **options)
            except FitError:
                # coincident centres (a vertex constrained twice) or a degenerate set: the plain
                # solver merges what can be merged and words the error
                return deform_vertices(vertices, constrained, targets, **kw)
            if interp.merged:  # pragma: no cover - identity rows never agree, so nothing merges
                return deform_vertices(vertices, constrained, targets, **kw)
            W = interp(V)
            with self._lock:
                self._cache[key] = W
                while len(self._cache) > self.max_entries:
                    self._cache.popitem(last=False)
        out = V + W @ (T - V[idx])
        if options.get("smoothing", 0.0) == 0:
            out[idx] = T  # exact interpolation, as deform_vertices does
        return out


def _fingerprint(a: np.ndarray) -> bytes:
    return hashlib.blake2b(np.ascontiguousarray(a).tobytes(), digest_size=16).digest() + str(a.shape).encode()


class Refitter:
    """Repeated fits of a project's expressions as the artist edits the clicks.

    Parameters
    ----------
    mesh : photomodel.modeling.generic_mesh.GenericMesh
    options : FitOptions, optional
        Options of a fit from scratch; a warm refit uses them with ``curve_passes = 1``.
    wrap : callable, optional
        ``wrap(inner)`` → the deformation a fit uses, built around the cached RBF ``inner`` (e.g.
        :func:`photomodel.prior.face_prior.prior_deformer`'s, as ``facestudio fit`` and the studio
        use it; this module sits below the prior and does not import it). When the wrapped
        deformation has a ``warm`` method (same signature), warm refits call that instead.
    """

    def __init__(self, mesh, options: FitOptions | None = None, *, wrap: Callable | None = None):
        self.mesh = mesh
        self.options = options or FitOptions()
        self.deformer = CachedDeformer()
        self.wrapped = None if wrap is None else wrap(self.deformer)

    def fit(
        self,
        project,
        expression_name: str,
        previous: FitResult | np.ndarray | None = None,
        progress: Callable[[str, float], None] | None = None,
        cancel: Callable[[], bool] | None = None,
    ) -> FitResult:
        """Fit one expression, reusing cached solves and warm-starting from ``previous``.

        Parameters
        ----------
        project : photomodel.project.Project
        expression_name : str
        previous : FitResult or (N, 3) float mm, optional
            The last fit of this expression (or its fitted vertices). When given, curves are
            parameterised on it in a single refinement pass; otherwise this is
            :func:`~photomodel.modeling.fit.fit_expression` from scratch (with the cached deformer).
        progress, cancel : as for :func:`~photomodel.modeling.fit.fit_expression`.

        Returns
        -------
        FitResult
        """
        warm = previous.vertices if isinstance(previous, FitResult) else previous
        if warm is not None and np.shape(warm) != self.mesh.vertices.shape:
            warm = None  # a fit of another mesh: start from scratch
        options = self.options
        if warm is not None and options.refine:
            options = replace(options, curve_passes=1)
        deform = self.deformer if self.wrapped is None else self.wrapped
        if warm is not None and hasattr(deform, "warm"):
            deform = deform.warm
        return fit_expression(
            project,
            expression_name,
            self.mesh,
            options,
            progress=progress,
            cancel=cancel,
            deform=deform,
            curve_mesh=warm,
        )
