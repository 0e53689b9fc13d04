"""Live Link Face CSV: ARKit blend-shape weights per frame, as Epic's Live Link Face app records them.

One row per frame: ``Timecode`` (``HH:MM:SS:FF.fff``, frames ``FF`` at the take's rate),
``BlendShapeCount`` (61), the 52 ARKit weights in [0, 1] with capitalised names
(``EyeBlinkLeft`` … ``TongueOut``, :data:`ARKIT_SHAPES` order; ``Left`` is the
subject's left), then ``HeadYaw, HeadPitch, HeadRoll`` and each eye's ``Yaw, Pitch, Roll``
(:data:`ROTATION_COLUMNS`). Rotations are written and read in radians. The reader finds columns
by name (any order, case-insensitive), so files from the app and from other tools read alike;
a missing blend-shape column is an error naming it, missing rotation columns read as 0.
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np

from photomodel.errors import FaceStudioError
from photomodel.exchange.files import atomic_write_bytes

__all__ = [
    "ARKIT_SHAPES",
    "BLENDSHAPE_COLUMNS",
    "ROTATION_COLUMNS",
    "livelink_csv_bytes",
    "write_livelink_csv",
    "read_livelink_csv",
    "timecode",
]

#: ARKit's 52 blend shapes in the order of ARFaceAnchor's documentation and Live Link Face's CSV.
ARKIT_SHAPES = (
    "eyeBlinkLeft",
    "eyeLookDownLeft",
    "eyeLookInLeft",
    "eyeLookOutLeft",
    "eyeLookUpLeft",
    "eyeSquintLeft",
    "eyeWideLeft",
    "eyeBlinkRight",
    "eyeLookDownRight",
    "eyeLookInRight",
    "eyeLookOutRight",
    "eyeLookUpRight",
    "eyeSquintRight",
    "eyeWideRight",
    "jawForward",
    "jawLeft",
    "jawRight",
    "jawOpen",
    "mouthClose",
    "mouthFunnel",
    "mouthPucker",
    "mouthLeft",
    "mouthRight",
    "mouthSmileLeft",
    "mouthSmileRight",
    "mouthFrownLeft",
    "mouthFrownRight",
    "mouthDimpleLeft",
    "mouthDimpleRight",
    "mouthStretchLeft",
    "mouthStretchRight",
    "mouthRollLower",
    "mouthRollUpper",
    "mouthShrugLower",
    "mouthShrugUpper",
    "mouthPressLeft",
    "mouthPressRight",
    "mouthLowerDownLeft",
    "mouthLowerDownRight",
    "mouthUpperUpLeft",
    "mouthUpperUpRight",
    "browDownLeft",
    "browDownRight",
    "browInnerUp",
    "browOuterUpLeft",
    "browOuterUpRight",
    "cheekPuff",
    "cheekSquintLeft",
    "cheekSquintRight",
    "noseSneerLeft",
    "noseSneerRight",
    "tongueOut",
)
#: The 52 weight columns, in ARKit's order, capitalised as Live Link Face writes them.
BLENDSHAPE_COLUMNS = tuple(s[0].upper() + s[1:] for s in ARKIT_SHAPES)
#: Head and eye rotations (radians) after the weights.
ROTATION_COLUMNS = (
    "HeadYaw",
    "HeadPitch",
    "HeadRoll",
    "LeftEyeYaw",
    "LeftEyePitch",
    "LeftEyeRoll",
    "RightEyeYaw",
    "RightEyePitch",
    "RightEyeRoll",
)
#: Decimals written: weights equal to 1e-7 after a round trip.
DECIMALS = 7


def timecode(frame: int, fps: float) -> str:
    """``HH:MM:SS:FF.fff`` of ``frame`` at ``fps`` (whole frames; the fraction is 0)."""
    rate = max(1, round(fps))
    s, ff = divmod(int(frame), rate)
    h, s = divmod(s, 3600)
    m, s = divmod(s, 60)
    return f"{h:02d}:{m:02d}:{s:02d}:{ff:02d}.000"


def livelink_csv_bytes(weights, fps: float, rotations=None) -> bytes:
    """The CSV of ``weights`` (f, 52) (ARKit order) and optional ``rotations`` (f, 9) radians."""
    W = np.asarray(weights, float)
    if W.ndim != 2 or W.shape[1] != len(ARKIT_SHAPES):
        raise ValueError(f"weights must be (frames, {len(ARKIT_SHAPES)}), got {W.shape}")
    rot = np.zeros((len(W), len(ROTATION_COLUMNS))) if rotations is None else np.asarray(rotations, float)
    if rot.shape != (len(W), len(ROTATION_COLUMNS)):
        raise ValueError(f"rotations must be (frames, {len(ROTATION_COLUMNS)}), got {rot.shape}")
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["Timecode", "BlendShapeCount", *BLENDSHAPE_COLUMNS, *ROTATION_COLUMNS])
    count = len(BLENDSHAPE_COLUMNS) + len(ROTATION_COLUMNS)
    for f in range(len(W)):
        w.writerow([timecode(f, fps), count, *(f"{v:.{DECIMALS}f}" for v in np.r_[W[f], rot[f]])])
    return buf.getvalue().encode()


def write_livelink_csv(path: str | os.PathLike, weights, fps: float, rotations=None) -> Path:
    """:func:`livelink_csv_bytes` written atomically to ``path``; returns the path."""
    return atomic_write_bytes(Path(path), livelink_csv_bytes(weights, fps, rotations))


def read_livelink_csv(path: str | os.PathLike) -> tuple[list[str], np.ndarray, np.ndarray]:
    """``(timecodes, weights (f, 52) in ARKit order, rotations (f, 9) radians)`` of a Live Link CSV.

    Raises FaceStudioError naming the file and the missing column or the bad cell.
    """
    path = Path(path)
    try:
        rows = list(csv.reader(io.StringIO(path.read_text(encoding="utf-8-sig"))))
    except (OSError, UnicodeDecodeError) as exc:
        raise FaceStudioError(f"{path}: cannot read the Live Link CSV ({exc})") from exc
    if not rows:
        raise FaceStudioError(f"{path}: empty file, expected a Live Link Face CSV header")
    col = {name.strip().lower(): i for i, name in enumerate(rows[0])}
    missing = [c for c in BLENDSHAPE_COLUMNS if c.lower() not in col]
    if missing or "timecode" not in col:
        raise FaceStudioError(f"{path}: not a Live Link Face CSV: no column {(missing or ['Timecode'])[0]!r}")
    body = [r for r in rows[1:] if r]

    def numbers(names, default=None) -> np.ndarray:
        out = np.zeros((len(body), len(names)))
        for j, c in enumerate(names):
            i = col.get(c.lower())
            if i is None:
                continue  # rotations are optional
            for f, r in enumerate(body):
                try:
                    out[f, j] = float(r[i])
                except (IndexError, ValueError) as exc:
                    raise FaceStudioError(f"{path}: row {f + 2}, column {c!r}: not a number") from exc
        return out

    return [r[col["timecode"]] for r in body], numbers(BLENDSHAPE_COLUMNS), numbers(ROTATION_COLUMNS)
