"""One person's tracked performance on another person's face (issue 37; seeds 000 and 001).

:func:`clone_track` takes person A's tracking results (``track.json`` of A's face model, Pighin et al.
§6.1.1: per control region, weights of A's photographed expressions) and writes B's: the same frames,
head pose and camera, with weights of *B's* face model, so ``facestudio edit``, ``export --glb --track``
and the studio's tracking view take it as they take B's own tracking. Four steps:

1. **A's faces.** Every frame's consensus geometry of A's model at its recorded weights (n, 3) mm,
   head frame (:meth:`tracking.blendshape_face.FaceModel.blend_geometry`).
2. **Onto B** (:data:`METHODS`):
   ``displacement`` — A's displacement from A's neutral, similarity-aligned, on B's neutral
   (:func:`photomodel.people.mapping.displacement_copy`);
   ``mapping`` — seed 001: A's and B's own expression spaces are the PCA of their photographed
   expressions (their models' ``E_k``, about their neutrals), mapped by Eq. 3–4 with ±3σ limits
   (:mod:`photomodel.people.mapping`);
   ``multilinear`` — seed 000's model (:mod:`photomodel.people.model_file`, built beforehand): both
   people's ARKit rigs predicted from their neutrals and other expressions, each frame said in A's rig
   and the same weights put on B's (:mod:`photomodel.people.rig_clone`);
   ``names`` — both projects have an ARKit rig (``facestudio rig``): A's faces said in A's rig weights
   (bounded least squares over the face), the same weights on B's rig.
3. **B's weights.** Each mapped face is said in B's model: per-region weights of B's expressions by least
   squares over the face against B's per-region targets ``μ_r (E_k − E_1)``
   (:func:`tracking.performance.region_targets`), the neutral's weight ``1 − Σ`` (the model's Eq. 4 form).
4. **B's results**: A's ``track.json`` with B's project and model, each frame's rotation ``R`` and head
   centre ``centre_mm`` kept (``t`` moved so that B's head centre is where A's was: the two heads' frames
   have different origins), weights and ``α`` of B, fit statistics zeroed, and a
   ``cloned_from`` record (A's project, A's results folder, the method).
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

from photomodel.camera import Camera
from photomodel.errors import Cancelled, FaceStudioError
from photomodel.people.mapping import ExpressionMapping, align_similarity, displacement_copy, expression_space
from photomodel.people.model_file import MODEL_PEOPLE, model_path
from photomodel.people.multilinear import MultilinearModel
from photomodel.people.rig_clone import RigClone
from photomodel.photos.video import VideoFrames
from photomodel.project import load_project, load_rig_shapes
from photomodel.rendering.renderer import get_renderer
from tracking.arkit_face import model_for_results
from tracking.blendshape_face import CONTROL_REGIONS, FaceModel, render_model
from tracking.face_from_project import face_model_from_project
from tracking.performance import region_targets
from tracking.track_result import load_track_results, save_results

__all__ = [
    "METHODS",
    "performance_faces",
    "map_faces",
    "weights_of_faces",
    "cloned_results",
    "side_by_side_frames",
    "CloneResult",
    "default_clone_dir",
    "clone_track",
]

METHODS = ("multilinear", "mapping", "displacement", "names")


def _region_weights(model: FaceModel, rec: dict) -> np.ndarray:
    """(R, m) region weights of a ``track.json`` frame record (rest: the neutral); with a shared basis
    (a track in ARKit terms, :mod:`tracking.arkit_face`) (R + 1, m), the last row the record's ``arkit``
    weights of the shared shapes."""
    shared = model.shared_expressions
    W = np.zeros((len(CONTROL_REGIONS) + (1 if model.n_shared else 0), model.m))
    W[0, 0] = 1.0
    for r, region in enumerate(CONTROL_REGIONS):
        if r:
            w = rec["weights"][region]
            W[r] = [0.0 if s else w[name] for name, s in zip(model.names, shared, strict=True)]
    if model.n_shared:
        arkit = rec.get("arkit", {})
        W[-1] = [arkit.get(name, 0.0) if s else 0.0 for name, s in zip(model.names, shared, strict=True)]
    return W


def performance_faces(model: FaceModel, doc: dict) -> np.ndarray:
    """(f, n, 3) mm, head frame: step 1, the tracked frames' faces of ``model`` (A's, as
    :func:`tracking.arkit_face.model_for_results` rebuilds it: photographed expressions per region,
    and the rig's shapes when the track is in ARKit terms)."""
    shared = model.shared_expressions
    photographed = [n for n, s in zip(model.names, shared, strict=True) if not s]
    if list(doc["model"]["expressions"]) != photographed:
        raise FaceStudioError(
            f"the tracking was made with the expressions {doc['model']['expressions']} but the face model has "
            f"{photographed}"
        )
    return np.array([model.blend_geometry(model.vertex_weights(_region_weights(model, r))) for r in doc["frames"]])


def _expression_shapes(model: FaceModel) -> np.ndarray:
    """(m, n, 3) mm: the model's expressions as faces (a shared shape, stored as its displacement, on the neutral)."""
    shapes = model.geometry.copy()
    shapes[model.shared_expressions] += model.geometry[0]
    return shapes


def map_faces(
    faces: np.ndarray, model_a: FaceModel, model_b: FaceModel, method: str, *, people_model=None, rigs=None
) -> np.ndarray:
    """(f, n, 3) mm: step 2, A's faces (f, n, 3) on B (see the module notes).

    ``people_model``: the :class:`photomodel.people.multilinear.MultilinearModel` (``multilinear``);
    ``rigs``: ``((names_a, deltas_a), (names_b, deltas_b))`` of the two rigs (``names``).
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    f, n = faces.shape[:2]
    nA, nB = model_a.geometry[0], model_b.geometry[0]
    mask = model_a.face_mask & model_b.face_mask
    X = faces.reshape(f, -1)
    if method == "displacement":
        out = displacement_copy(X, nA, nB, mask)
    elif method == "mapping":
        if model_a.m < 2 or model_b.m < 2:
            raise FaceStudioError("the mapping needs at least two photographed expressions in each project")
        s, R, _ = align_similarity(nA, nB, mask)
        # about each person's neutral (expression 0), not the mean of their own sets (seed 001 §5)
        space_a = expression_space(_expression_shapes(model_a).reshape(model_a.m, -1), reference=0)
        space_b = expression_space(_expression_shapes(model_b).reshape(model_b.m, -1), reference=0)
        out = ExpressionMapping.between(space_a, space_b, (s, R))(X)
    elif method == "multilinear":
        pm = people_model
        if pm is None or pm.mean.shape != (3 * n,):
            raise FaceStudioError("the multilinear model is missing or of another mesh; build it first")
        out = rig_clone(pm, model_a, model_b, mask)(X)
    else:
        (names_a, da), (names_b, db) = rigs
        if list(names_a) != list(names_b):
            raise FaceStudioError("the two rigs have different shapes; run `facestudio rig` on both")
        A = da[:, mask].reshape(len(da), -1).T
        disp = (faces - nA)[:, mask].reshape(f, -1)
        W = np.array([lsq_linear(A, d, bounds=(0.0, 1.0)).x for d in disp])
        out = nB.ravel() + W @ db.reshape(len(db), -1)
    return np.asarray(out).reshape(f, n, 3)


def rig_clone(people_model, model_a: FaceModel, model_b: FaceModel, mask: np.ndarray) -> RigClone:
    """The ``multilinear`` map of A onto B (:class:`photomodel.people.rig_clone.RigClone`): each person's rig
    predicted by ``people_model`` from their neutral and their model's other expressions (an ARKit name, a
    rig's shape or a photographed one, is that shape; any other name a mix the model solves for)."""

    def expressions(model: FaceModel) -> dict:
        shapes = _expression_shapes(model)
        return {name: shapes[e] for e, name in enumerate(model.names) if e}

    nA, nB = model_a.geometry[0], model_b.geometry[0]
    return RigClone.between(people_model, nA, expressions(model_a), nB, expressions(model_b), mask)


def weights_of_faces(model: FaceModel, faces: np.ndarray) -> np.ndarray:
    """(f, R, m): step 3, region weights of ``model`` (B's) closest to ``faces`` (f, n, 3) over its face;
    :class:`FaceStudioError` when ``model`` has no expression besides its neutral (nothing to say them in)."""
    if model.m < 2:
        raise FaceStudioError(
            f"the face taking the performance has only the expression {model.names[0]!r}: its tracking results are "
            "said in its fitted and textured expressions, so it needs at least one more (a face with only a rig "
            "takes a performance through its rig's weights instead)"
        )
    _names, targets = region_targets(model)
    mask = model.face_mask
    A = targets[:, mask].reshape(len(targets), -1).T
    rhs = (faces - model.geometry[0])[:, mask].reshape(len(faces), -1).T
    w = np.linalg.lstsq(A, rhs, rcond=None)[0].T  # (f, (R - 1)(m - 1)), region-major as region_targets
    W = np.zeros((len(faces), len(CONTROL_REGIONS), model.m))
    W[:, 0, 0] = 1.0
    W[:, 1:, 1:] = w.reshape(len(faces), len(CONTROL_REGIONS) - 1, model.m - 1)
    W[:, 1:, 0] = 1.0 - W[:, 1:, 1:].sum(axis=2)
    return W


def cloned_results(
    doc_a: dict, model_b: FaceModel, project_b: str | Path, weights: np.ndarray, cloned_from: dict
) -> dict:
    """Step 4: B's ``track.json`` document (see the module notes) from A's ``doc_a`` and B's ``weights`` (f, R, m)."""
    doc = copy.deepcopy(doc_a)
    regions = [r for r, a in zip(CONTROL_REGIONS, model_b.n_alpha, strict=True) if a]
    doc["project"] = str(Path(project_b).absolute())
    doc["model"] = {
        "source": f"cloned from {cloned_from['project']} ({cloned_from['method']})",
        "expressions": list(model_b.names),
        "regions": list(CONTROL_REGIONS),
        "regions_with_parameters": regions,
        "n_alpha": list(model_b.n_alpha),
        "centre_mm": np.asarray(model_b.centre, float).tolist(),
    }
    doc["corrections"] = []
    doc["cloned_from"] = cloned_from
    for rec, W in zip(doc["frames"], weights, strict=True):
        R = np.array(rec["R"], float)
        # B's head centre where A's was (A's recorded centre_mm kept): t = c_A − R c_B
        rec["t_mm"] = (np.array(rec["centre_mm"], float) - R @ model_b.centre).tolist()
        rec["alpha"] = model_b.alpha_of_weights(W).tolist()
        rec["weights"] = {
            region: dict(zip(model_b.names, map(float, W[r]), strict=True))
            for r, region in enumerate(CONTROL_REGIONS)
            if r
        }
        rec.update(rms=0.0, pixels=0, diverged=False, steps=0, evaluations=0, seconds=0.0)
        rec.pop("landmarks_xy", None)
    return doc


def side_by_side_frames(doc_b: dict, model_b: FaceModel, weights: np.ndarray):
    """Yield (H, 2W, 3) float RGB images: A's video frame | B's model rendered with B's texture at the
    frame's pose and B's ``weights`` (f, R, m), for the frames of ``doc_b`` (B's cloned results)."""
    video = VideoFrames(doc_b["video"]["path"])
    cam = doc_b["camera"]
    recs = {r["frame"]: (r, W) for r, W in zip(doc_b["frames"], weights, strict=True)}
    renderer = get_renderer()
    for i, frame in video.frames(0, max(recs) + 1):
        if i not in recs:
            continue
        rec, W = recs[i]
        vw = model_b.vertex_weights(W)
        camera = Camera(
            np.array(rec["R"], float), np.array(rec["t_mm"], float), cam["focal_px"], video.width, video.height
        )
        image = render_model(renderer, camera, model_b, model_b.blend_geometry(vw), vw).image
        yield np.concatenate([frame, image], axis=1)


#: Frames mapped per step of :func:`clone_track` (between progress reports and cancel checks).
CLONE_CHUNK = 25


@dataclass
class CloneResult:
    """What :func:`clone_track` wrote: B's results folder ``out_dir`` (``track.json`` + ``track.csv``),
    its document ``doc``, B's region ``weights`` (f, R, m) and B's face model ``model_b``."""

    out_dir: Path
    doc: dict
    weights: np.ndarray
    model_b: FaceModel

    @property
    def frames(self) -> int:
        return len(self.doc["frames"])


def default_clone_dir(project_a: str | Path, track: str | Path, project_b: str | Path) -> Path:
    """B's results folder of a clone: ``<B's folder>/results/<A's track folder>_from_<A's name>`` (absolute)."""
    a_stem = Path(project_a).name.split(".")[0]
    return Path(project_b).absolute().parent / "results" / f"{Path(track).name}_from_{a_stem}"


def clone_track(
    project_a: str | Path,
    track: str | Path,
    project_b: str | Path,
    method: str,
    out_dir: str | Path | None = None,
    *,
    people_model=None,
    progress: Callable[[str, float], None] | None = None,
    cancel: Callable[[], bool] | None = None,
) -> CloneResult:
    """Clone the tracked performance in ``track`` (A's results folder) of project file ``project_a``
    onto project file ``project_b`` by ``method`` (:data:`METHODS`): steps 1–4 of the module notes,
    B's results written to ``out_dir`` (default :func:`default_clone_dir`).

    ``people_model``: the multilinear model (``multilinear``; default: the model file of
    :mod:`photomodel.people.model_file`, :class:`FaceStudioError` when it has not been built).
    ``progress(message, fraction)`` hears of every :data:`CLONE_CHUNK` frames; ``cancel()`` true stops
    between them (:class:`photomodel.errors.Cancelled`, nothing written).
    """

    def report(message: str, fraction: float) -> None:
        if cancel is not None and cancel():
            raise Cancelled()
        if progress is not None:
            progress(message, fraction)

    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    out = default_clone_dir(project_a, track, project_b) if out_dir is None else Path(out_dir).absolute()
    report("reading the two projects and the tracked performance…", 0.0)
    pa, pb = load_project(project_a), load_project(project_b)
    doc_a = load_track_results(track)
    if doc_a is None or not doc_a["frames"]:
        raise FaceStudioError(f"{track} holds no tracked frames (track.json); track a video first")
    report("building the two face models…", 0.02)
    model_a = model_for_results(pa, doc_a)
    model_b, _ = face_model_from_project(pb)
    rigs = None
    if method == "multilinear" and people_model is None:
        people_model = _people_model()
    elif method == "names":
        rigs = (load_rig_shapes(pa), load_rig_shapes(pb))
    frames = doc_a["frames"]
    weights = []
    for start in range(0, len(frames), CLONE_CHUNK):
        report(
            f"cloning frames {start}–{min(start + CLONE_CHUNK, len(frames)) - 1} of {len(frames)} ({method})…",
            0.1 + 0.85 * start / len(frames),
        )
        faces = performance_faces(model_a, {**doc_a, "frames": frames[start : start + CLONE_CHUNK]})
        mapped = map_faces(faces, model_a, model_b, method, people_model=people_model, rigs=rigs)
        weights.append(weights_of_faces(model_b, mapped))
    W = np.concatenate(weights)
    report("writing B's tracking results…", 0.97)
    cloned_from = {"project": str(Path(project_a).absolute()), "track": str(Path(track).absolute()), "method": method}
    doc = cloned_results(doc_a, model_b, project_b, W, cloned_from)
    out.mkdir(parents=True, exist_ok=True)
    save_results(out, doc, bool(doc_a.get("complete")))
    return CloneResult(out, doc, W, model_b)


def _people_model():
    """The multilinear model file (:mod:`photomodel.people.model_file`), never built here."""
    path = model_path(MODEL_PEOPLE)
    if not path.is_file():
        raise FaceStudioError(
            f"the multilinear model {path} is missing; build it: python -m photomodel.people.model_file"
        )
    return MultilinearModel.load(path)
