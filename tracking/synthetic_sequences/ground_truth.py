"""The sample tracking data: the james face model and a synthetic video with its ground truth.

Tests, benchmarks and ``sample_projects/make_james_video.py`` use this module; the tracker
(:mod:`tracking.frame_fit`, :mod:`tracking.run`) never does.

* :func:`sample_face_model` — the blend-shape model (§6.1.1) of the james basic expressions
  (:mod:`tracking.synthetic_sequences.expressions`) on the generic mesh, from their **true** geometries (the generic
  vertices' true positions on the scan moved by each expression's deformation field). Texture: the
  scan's own photographic texture, reached through the true correspondence (each generic vertex
  gets the uv of its true point on the scan), downsampled ×:data:`TEXTURE_DOWNSAMPLE` (a 300-px
  face shows the 2400×1600 texture ~8× minified; prefiltering avoids aliasing). The synthetic
  expressions move the skin without changing its colour, so all expressions share this texture
  (one array: sampled once per frame).
* :func:`video_truth` / :func:`render_video_frame` — a sequence at 300×300 of the scan blended
  per region with smoothly varying weights (the same smoothed memberships as the model, carried
  to the scan's vertices) under smooth head motion, rendered by our renderer (3× supersampled).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from scipy.spatial import cKDTree

from photomodel.alignment import similarity_transform
from photomodel.camera import Camera, rodrigues
from photomodel.closest_points import barycentric_coordinates
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.project import load_project
from photomodel.rendering.renderer import get_renderer
from photomodel.samples.fitted_sample import fitted_sample_project
from photomodel.samples.sample_data import load_james_scan
from photomodel.samples.synthetic import HEAD_CENTRE_MM, scan_surface, true_correspondence
from tracking.blendshape_face import CONTROL_REGIONS, FaceModel, build_face_model, control_regions
from tracking.face_from_project import face_model_from_project
from tracking.synthetic_sequences.expressions import EXPRESSION_NAMES, OUTSIDE_EXPRESSIONS, expression_displacements

__all__ = [
    "TEXTURE_DOWNSAMPLE",
    "VIDEO_SIZE",
    "VIDEO_FOCAL_PX",
    "VideoTruth",
    "sample_face_model",
    "fitted_sample_project",
    "fitted_sample_model",
    "model_gauge",
    "scan_uv_of_points",
    "video_truth",
    "outside_truth",
    "video_camera",
    "render_video_frame",
    "true_vertices",
    "true_scan_vertices",
]

TEXTURE_DOWNSAMPLE = 4
VIDEO_SIZE = 300
#: Focal length of the sample video (px at 300×300): a 50 mm lens on a 36 mm sensor would be
#: 417 px; 560 px frames the head (~250 mm) at ~650 mm in about 200 px.
VIDEO_FOCAL_PX = 560.0
#: Distance (mm) of the head centre from the camera in the sample video.
VIDEO_DISTANCE_MM = 650.0
BACKGROUND_RGB = (0.55, 0.6, 0.65)


def scan_uv_of_points(scan, points: np.ndarray) -> np.ndarray:
    """(n, 2) uv of the scan's texture at surface ``points`` (n, 3) mm (closest scan triangle,
    barycentric interpolation of its corners' uv)."""

    surf = scan_surface(scan)
    closest, _, face = surf.closest(points)
    # scan_surface works on the welded surface; find the textured triangle with the same corners
    welded = scan.welded
    order, first = np.unique(scan.obj_vertex, return_index=True)
    remap = np.searchsorted(order, scan.obj_vertex)
    key_textured = {tuple(sorted(f)): i for i, f in enumerate(remap[scan.faces])}
    tri_ids = np.array([key_textured[tuple(sorted(f))] for f in np.asarray(welded.faces)[face]])
    bary = barycentric_coordinates(closest, scan.vertices[scan.faces[tri_ids]])
    bary /= bary.sum(1, keepdims=True)
    return np.einsum("nc,ncd->nd", bary, scan.uv[scan.faces[tri_ids]])


@lru_cache(maxsize=4)
def sample_face_model(names: tuple = EXPRESSION_NAMES, basis: str = "gram_schmidt") -> FaceModel:
    """The james face model of ``names`` (see the module docstring). Cached per arguments."""

    mesh, scan = load_generic_mesh(), load_james_scan()
    C = true_correspondence(mesh, scan)
    E = C[None] + expression_displacements(C, scan.landmarks, names)
    uv = scan_uv_of_points(scan, C)
    tex = cv2.resize(
        scan.texture, None, fx=1.0 / TEXTURE_DOWNSAMPLE, fy=1.0 / TEXTURE_DOWNSAMPLE, interpolation=cv2.INTER_AREA
    )
    regions = control_regions(mesh.regions, C, mesh.landmarks)
    # drop triangles whose corners lie on different charts of the scan's texture atlas
    tri_uv = uv[mesh.faces]
    span = np.linalg.norm(tri_uv - np.roll(tri_uv, 1, axis=1), axis=2).max(axis=1)
    faces = mesh.faces[span < 0.05]
    return build_face_model(names, E, faces, uv, [tex] * len(names), regions, face_mask=mesh.face_mask, basis=basis)


@lru_cache(maxsize=1)
def _scan_membership() -> np.ndarray:
    """(n_scan, R) region memberships of the scan's vertices: inverse-distance average of the
    4 nearest generic vertices' (at their true positions) smoothed memberships."""

    model = sample_face_model()
    scan = load_james_scan()
    d, idx = cKDTree(model.geometry[0]).query(scan.vertices, 4)
    w = 1.0 / np.maximum(d, 0.5)
    w /= w.sum(1, keepdims=True)
    return np.einsum("nj,njr->nr", w, model.membership[idx])


@dataclass
class VideoTruth:
    """Ground truth of a synthetic video.

    Attributes
    ----------
    R : (T, 3, 3) float, head rotation (``X_cam = R X + t``).
    t : (T, 3) float, mm: camera-space translation of the head-frame origin.
    weights : (T, R, m) float, blending weights per control region (row 0, rest, neutral).
    names : tuple of m str.
    focal_px, width, height : camera intrinsics.
    """

    R: np.ndarray
    t: np.ndarray
    weights: np.ndarray
    names: tuple
    focal_px: float
    width: int
    height: int

    @property
    def frames(self) -> int:
        return len(self.R)

    def camera(self, i: int) -> Camera:
        return Camera(self.R[i], self.t[i], self.focal_px, self.width, self.height)

    def to_dict(self) -> dict:
        return {
            "names": list(self.names),
            "regions": list(CONTROL_REGIONS),
            "focal_px": self.focal_px,
            "width": self.width,
            "height": self.height,
            "frames": [
                {
                    "R": self.R[i].round(10).tolist(),
                    "t": self.t[i].round(6).tolist(),
                    "weights": self.weights[i].round(8).tolist(),
                }
                for i in range(self.frames)
            ],
        }

    @classmethod
    def from_dict(cls, d: dict) -> VideoTruth:
        fr = d["frames"]
        return cls(
            np.array([f["R"] for f in fr], float),
            np.array([f["t"] for f in fr], float),
            np.array([f["weights"] for f in fr], float),
            tuple(d["names"]),
            float(d["focal_px"]),
            int(d["width"]),
            int(d["height"]),
        )


def video_camera(focal_px: float = VIDEO_FOCAL_PX, size: int = VIDEO_SIZE) -> Camera:
    """The fixed video camera at the origin looking along +z (identity extrinsics)."""
    return Camera(np.eye(3), np.zeros(3), focal_px, size, size)


def video_truth(
    frames: int = 40, *, seed: int = 6, names: tuple = EXPRESSION_NAMES, yaw_deg: float = 14.0
) -> VideoTruth:
    """Smooth head motion and region weights for a ``frames``-long synthetic video.

    Head: yaw ±``yaw_deg`` (14°), pitch ±7°, roll ±4°, translation ±12 mm sideways, ±15 mm in depth, as sums
    of slow sinusoids (random phases from ``seed``). Weights: in the mouth, smile and open mouth
    rise and fall in turn (each up to 0.8); on the forehead, brows raised up to 0.9; in the eyes,
    the forehead's weights (the expressions barely move the eyes).
    """
    rng = np.random.default_rng(seed)
    T = int(frames)
    s = np.arange(T) / max(T - 1, 1)  # 0..1 over the clip
    ph = rng.uniform(0, 2 * np.pi, 6)
    yaw = np.radians(yaw_deg) * np.sin(2 * np.pi * 0.9 * s + ph[0])
    pitch = np.radians(7.0) * np.sin(2 * np.pi * 1.3 * s + ph[1])
    roll = np.radians(4.0) * np.sin(2 * np.pi * 0.7 * s + ph[2])
    # facing the camera: the subject's left (+x) is on the image's right, up (+y) is image up
    # (camera y is down), and out of the face (+z) points back at the camera (−z_cam)
    R0 = np.diag([1.0, -1.0, -1.0])

    R = np.array([rodrigues(np.array([p, y, r])) @ R0 for p, y, r in zip(pitch, yaw, roll, strict=True)])
    centre_cam = np.column_stack(
        [
            12.0 * np.sin(2 * np.pi * 0.6 * s + ph[3]),
            8.0 * np.sin(2 * np.pi * 0.8 * s + ph[4]),
            VIDEO_DISTANCE_MM + 15.0 * np.sin(2 * np.pi * 0.5 * s + ph[5]),
        ]
    )
    t = centre_cam - np.einsum("tij,j->ti", R, HEAD_CENTRE_MM)
    m = len(names)
    W = np.zeros((T, len(CONTROL_REGIONS), m))
    W[:, :, 0] = 1.0

    def bump(centre, width, height):
        return height * np.exp(-0.5 * ((s - centre) / width) ** 2)

    k = {n: i for i, n in enumerate(names)}
    mouth = CONTROL_REGIONS.index("mouth")
    W[:, mouth, k["smile"]] = bump(0.3, 0.12, 0.8)
    W[:, mouth, k["open_mouth"]] = bump(0.7, 0.12, 0.8)
    fore = CONTROL_REGIONS.index("forehead")
    W[:, fore, k["brows_raised"]] = bump(0.5, 0.15, 0.9)
    W[:, CONTROL_REGIONS.index("eyes")] = W[:, fore]
    for r in range(1, len(CONTROL_REGIONS)):
        W[:, r, 0] = 1.0 - W[:, r, 1:].sum(1)
    return VideoTruth(R, t, W, tuple(names), VIDEO_FOCAL_PX, VIDEO_SIZE, VIDEO_SIZE)


def outside_truth(frames: int = 40, *, seed: int = 6, yaw_deg: float = 14.0) -> VideoTruth:
    """:func:`video_truth`'s head motion with expressions outside every model's set
    (:data:`tracking.synthetic_sequences.expressions.OUTSIDE_EXPRESSIONS`), each over the whole face (mouth,
    eyes and forehead alike): ``cheek_smile`` rises and falls early in the clip (up to 0.9),
    ``surprise`` late (up to 0.9), with a short overlap."""
    base = video_truth(frames, seed=seed, yaw_deg=yaw_deg)
    names = ("neutral",) + OUTSIDE_EXPRESSIONS
    s = np.arange(base.frames) / max(base.frames - 1, 1)
    W = np.zeros((base.frames, len(CONTROL_REGIONS), len(names)))
    W[:, :, 0] = 1.0
    for k, centre in ((1, 0.3), (2, 0.68)):
        W[:, 1:, k] = (0.9 * np.exp(-0.5 * ((s - centre) / 0.13) ** 2))[:, None]
    W[:, 1:, 0] = 1.0 - W[:, 1:, 1:].sum(2)
    return VideoTruth(base.R, base.t, W, names, base.focal_px, base.width, base.height)


def true_vertices(truth: VideoTruth, i: int) -> np.ndarray:
    """(n, 3) mm, head frame: the generic mesh's true geometry in frame ``i``."""
    model = sample_face_model(truth.names)
    return model.blend_geometry(model.vertex_weights(truth.weights[i]))


def true_scan_vertices(truth: VideoTruth, i: int) -> tuple[np.ndarray, np.ndarray]:
    """The true surface of frame ``i``: the scan deformed by the frame's region weights (what
    :func:`render_video_frame` draws), as vertices (n_scan, 3) mm in the head frame and triangles."""

    scan = load_james_scan()
    Wv = _scan_membership() @ truth.weights[i]  # (n_scan, m)
    return scan.vertices + np.einsum("nk,knd->nd", Wv, _scan_displacements(truth.names)), scan.faces


def render_video_frame(truth: VideoTruth, i: int, *, supersample: int = 3) -> np.ndarray:
    """(H, W, 3) float32 in [0, 1]: frame ``i`` — the textured scan deformed by the frame's
    region weights, seen by the video camera at the frame's head pose, on a plain background."""

    scan = load_james_scan()
    V, _ = true_scan_vertices(truth, i)
    res = get_renderer().render(
        truth.camera(i),
        V,
        scan.faces,
        uv=scan.uv,
        texture=_scan_texture_handle(),
        background=BACKGROUND_RGB,
        supersample=supersample,
    )
    return res.color


@lru_cache(maxsize=2)
def _scan_displacements(names: tuple) -> np.ndarray:

    scan = load_james_scan()
    return expression_displacements(scan.vertices, scan.landmarks, names)


_TEX_HANDLES: dict = {}


def _scan_texture_handle():

    r = get_renderer()
    if id(r) not in _TEX_HANDLES:
        _TEX_HANDLES[id(r)] = r.upload_texture(load_james_scan().texture)
    return _TEX_HANDLES[id(r)]


@lru_cache(maxsize=4)
def fitted_sample_model(names: tuple = EXPRESSION_NAMES) -> FaceModel:
    """The face model of the fitted sample project (:func:`fitted_sample_project`) on ``names``,
    E_1 = neutral — the model a user of the sample gets, built by
    :func:`tracking.face_from_project.face_model_from_project`. Cached per arguments."""

    return face_model_from_project(load_project(fitted_sample_project()), names)[0]


#: model_gauge results per model object (a few seconds each; the sample models are cached objects).
_GAUGES: dict = {}


def model_gauge(model: FaceModel, iterations: int = 15) -> tuple[float, np.ndarray, np.ndarray]:
    """``(s, R, t)``: the similarity taking a james model's head frame to the true one
    (``X_true ≈ s R X + t``): its neutral face vertices registered onto the scan's surface
    (similarity ICP: closest points on the scan, :func:`photomodel.alignment.similarity_transform`,
    repeated; started from the vertices' true positions).

    A model modeled from photos has its own frame and scale (structure from motion fixes neither):
    tests and benchmarks compare a tracked pose with the truth through this one fixed map, and
    multiply camera-space results by ``s`` (a model ``s`` times too small is seen at ``1/s`` the
    distance). Surface registration, not vertex to vertex: a fitted vertex may slide along the skin
    by millimetres without changing the surface, and the image — what the tracker matches — only
    sees the surface.
    """

    key = (id(model), iterations)
    cached = _GAUGES.get(key)
    if cached is not None and cached[0] is model:  # the same (cached, unchanged) model object
        return cached[1]
    truth = sample_face_model()
    face = model.face_mask
    P = model.geometry[0][face]
    s, R, t = similarity_transform(P, truth.geometry[0][face])
    surface = scan_surface(load_james_scan())
    for _ in range(iterations):
        closest = surface.closest(P @ (s * R).T + t)[0]
        s, R, t = similarity_transform(P, closest)
    _GAUGES[key] = (model, (s, R, t))
    return s, R, t
