"""Camera model and projection — the one place where conventions are written down.

Conventions (used everywhere in Face Studio)
-------------------------------------------
* World units are millimetres. The head frame is the generic mesh's frame:
  ``+x`` towards the subject's left, ``+y`` up, ``+z`` out of the face (the nose
  points along ``+z``).
* A camera maps a world point ``X`` to camera coordinates ``X_cam = R @ X + t``
  (``R`` world→camera rotation, ``t`` in mm). The camera looks along ``+z_cam``,
  ``x_cam`` points right in the image and ``y_cam`` points *down* (OpenCV).
* Pixels: ``u`` to the right, ``v`` down, pixel *centres* at integer coordinates,
  so the principal point (optical centre) of a ``W×H`` image is
  ``((W-1)/2, (H-1)/2)``. Square pixels, no skew, no lens distortion — the
  camera model of Pighin et al. 2002, §5.1.1, Eq. (1).
* Focal length ``f`` is in pixels. ``focal_mm`` converts with a 36 mm-wide
  (full-frame) sensor, the way photographers name lenses.

Paper parameterisation (§5.1.1): ``eta = 1 / t_z`` (inverse distance) and
``s = f * eta`` (world-to-image scale) so that, with image coordinates measured
from the optical centre,

    x = s (r_x·m + t_x) / (1 + eta r_z·m),   y = s (r_y·m + t_y) / (1 + eta r_z·m).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SENSOR_WIDTH_MM = 36.0

#: Rough starting poses an artist picks per photo: azimuth in degrees about the
#: world +y axis; positive moves the camera towards the subject's left (+x).
PRESET_AZIMUTH_DEG = {
    "front": 0.0,
    "three_quarter_left": 45.0,
    "left": 90.0,
    "three_quarter_right": -45.0,
    "right": -90.0,
}


def rodrigues(v: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector ``v`` (3,) (axis·angle, radians), Eq. (12)."""
    v = np.asarray(v, dtype=float)
    theta = float(np.linalg.norm(v))
    if theta < 1e-12:
        return np.eye(3) + cross_matrix(v)
    n = v / theta
    X = cross_matrix(n)
    return np.eye(3) + np.sin(theta) * X + (1.0 - np.cos(theta)) * (X @ X)


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Inverse of :func:`rodrigues`: (3,) axis·angle of a rotation matrix."""
    R = np.asarray(R, dtype=float)
    cos = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    theta = np.arccos(cos)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if theta < 1e-8:
        return w / 2.0
    if np.pi - theta < 1e-6:
        # near 180°: axis from the symmetric part
        B = (R + np.eye(3)) / 2.0
        axis = np.sqrt(np.clip(np.diag(B), 0.0, None))
        i = int(np.argmax(axis))
        axis = B[i] / np.sqrt(max(B[i, i], 1e-300))
        return axis / np.linalg.norm(axis) * theta
    return w / (2.0 * np.sin(theta)) * theta


def cross_matrix(v: np.ndarray) -> np.ndarray:
    """The cross-product operator X(v) of Eq. (13): ``cross_matrix(v) @ a == v × a``."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rotation_angle_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    """Angle in degrees of the relative rotation ``Ra Rbᵀ``."""
    c = (np.trace(np.asarray(Ra) @ np.asarray(Rb).T) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def focal_mm_to_px(focal_mm: float, width_px: int) -> float:
    """Focal length in pixels of a lens ``focal_mm`` on a 36 mm-wide sensor."""
    return float(focal_mm) * float(width_px) / SENSOR_WIDTH_MM


def focal_px_to_mm(focal_px: float, width_px: int) -> float:
    return float(focal_px) * SENSOR_WIDTH_MM / float(width_px)


@dataclass
class Camera:
    """A pinhole camera: ``X_cam = R X + t``, ``u = f X_cam/Z_cam + cx``.

    Attributes
    ----------
    R : (3, 3) float, world→camera rotation.
    t : (3,) float, translation in mm.
    f : float, focal length in pixels.
    width, height : int, image size in pixels.
    """

    R: np.ndarray
    t: np.ndarray
    f: float
    width: int
    height: int

    def __post_init__(self):
        self.R = np.asarray(self.R, dtype=float).reshape(3, 3)
        self.t = np.asarray(self.t, dtype=float).reshape(3)
        self.f = float(self.f)
        self.width = int(self.width)
        self.height = int(self.height)

    # -- intrinsics -------------------------------------------------------
    @property
    def principal_point(self) -> np.ndarray:
        """(2,) optical centre in pixels: the image centre ``((W-1)/2, (H-1)/2)``."""
        return np.array([(self.width - 1) / 2.0, (self.height - 1) / 2.0])

    @property
    def K(self) -> np.ndarray:
        cx, cy = self.principal_point
        return np.array([[self.f, 0.0, cx], [0.0, self.f, cy], [0.0, 0.0, 1.0]])

    @property
    def focal_mm(self) -> float:
        return focal_px_to_mm(self.f, self.width)

    # -- paper parameterisation --------------------------------------------
    @property
    def eta(self) -> float:
        """Inverse distance ``1/t_z`` (1/mm)."""
        return 1.0 / self.t[2]

    @property
    def s(self) -> float:
        """World-to-image scale ``f * eta`` (px/mm)."""
        return self.f / self.t[2]

    # -- extrinsics -------------------------------------------------------
    @property
    def center(self) -> np.ndarray:
        """(3,) camera centre in world mm: ``-Rᵀ t``."""
        return -self.R.T @ self.t

    @property
    def view_direction(self) -> np.ndarray:
        """(3,) unit optical axis in world coordinates."""
        return self.R[2].copy()

    def to_camera(self, X: np.ndarray) -> np.ndarray:
        """(n, 3) world mm → (n, 3) camera mm."""
        return np.asarray(X, dtype=float) @ self.R.T + self.t

    def project(self, X: np.ndarray) -> np.ndarray:
        """(n, 3) world mm → (n, 2) pixels (u right, v down)."""
        Xc = self.to_camera(X)
        return self.f * Xc[:, :2] / Xc[:, 2:3] + self.principal_point

    def depth(self, X: np.ndarray) -> np.ndarray:
        """(n,) depth ``Z_cam`` in mm."""
        return self.to_camera(X)[:, 2]

    def rays(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Viewing rays of pixels ``uv`` (n, 2): returns origin (3,) and unit directions (n, 3)."""
        uv = np.asarray(uv, dtype=float).reshape(-1, 2)
        d_cam = np.column_stack([(uv - self.principal_point) / self.f, np.ones(len(uv))])
        d = d_cam @ self.R  # = (Rᵀ d_cam)ᵀ
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return self.center, d

    def copy(self) -> Camera:
        return Camera(self.R.copy(), self.t.copy(), self.f, self.width, self.height)

    # -- (de)serialisation --------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "rotation": self.R.tolist(),
            "translation_mm": self.t.tolist(),
            "focal_px": self.f,
            "width": self.width,
            "height": self.height,
        }

    @classmethod
    def from_dict(cls, d: dict) -> Camera:
        return cls(
            np.array(d["rotation"], float),
            np.array(d["translation_mm"], float),
            float(d["focal_px"]),
            int(d["width"]),
            int(d["height"]),
        )


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 1.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """World→camera ``(R, t)`` of a camera at ``eye`` looking at ``target`` with world ``up``
    appearing up in the image (i.e. along −y_cam)."""
    eye = np.asarray(eye, float)
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(-np.asarray(up, float), z)  # x_cam = y_cam × z_cam with y_cam ≈ -up
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.vstack([x, y, z])
    return R, -R @ eye


def orbit_camera(
    azimuth_deg: float,
    width: int,
    height: int,
    *,
    distance_mm: float = 600.0,
    focal_mm: float = 50.0,
    elevation_deg: float = 0.0,
    target=(0.0, 0.0, 0.0),
) -> Camera:
    """A camera on a circle around the head, looking at ``target``.

    ``azimuth_deg`` rotates about world +y (0 = in front of the face, +90 = at the
    subject's left); ``elevation_deg`` raises the camera.
    """
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    direction = np.array([np.sin(a) * np.cos(e), np.sin(e), np.cos(a) * np.cos(e)])
    eye = np.asarray(target, float) + distance_mm * direction
    R, t = look_at(eye, target)
    return Camera(R, t, focal_mm_to_px(focal_mm, width), width, height)


def preset_camera(name: str, width: int, height: int, *, distance_mm: float = 600.0, focal_mm: float = 50.0) -> Camera:
    """The rough initial camera for a named preset (see :data:`PRESET_AZIMUTH_DEG`)."""
    try:
        az = PRESET_AZIMUTH_DEG[name]
    except KeyError:
        raise ValueError(f"unknown camera preset {name!r}; choose one of {sorted(PRESET_AZIMUTH_DEG)}") from None
    return orbit_camera(az, width, height, distance_mm=distance_mm, focal_mm=focal_mm)
