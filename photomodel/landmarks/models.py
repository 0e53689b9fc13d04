"""MediaPipe's face models, taken out of the ``mediapipe==0.10.21`` wheel (Apache-2.0).

Face Studio runs four of MediaPipe's TensorFlow Lite models with OpenCV's ``cv2.dnn``, not the
MediaPipe runtime:

* ``face_detection_short_range.tflite`` — BlazeFace, a 128×128 face detector (boxes and six
  key points per face);
* ``face_landmark.tflite`` — 468 face-mesh points from a 192×192 face crop, plus a
  face-presence score;
* ``selfie_segmentation.tflite`` — the person against the background, a 256×256 probability map
  (:mod:`photomodel.landmarks.segment`: what texturing may take from a photo);
* ``hand_landmark_full.tflite`` — 21 points of a hand and a hand-presence score from a 224×224
  crop (:mod:`photomodel.landmarks.hands`: a hand in front of the face).

``mediapipe==0.10.21`` is the last wheel that carries ``face_landmark.tflite``; its wheels
exist for CPython 3.9–3.12 only, so pip is asked for one fixed wheel (CPython 3.11,
``manylinux_2_28_x86_64``, binary only) whatever Python runs Face Studio, and the files are
read out of it (:mod:`photomodel.data.fetch`: archive and file checksums, cache, atomic
install). The full-range detector of the same wheel is not used: it is stored sparse and
OpenCV 5 cannot import its ``DENSIFY`` operator.

Cache: ``<cache>/mediapipe-0.10.21/`` (see :func:`photomodel.data.cache.cache_dir`).
Offline, set ``FACESTUDIO_MEDIAPIPE_WHEEL`` to a local copy of the wheel.

``python -m photomodel.landmarks.models`` fetches the models ahead of time (install.sh runs it)
and prints the folder.
"""

from __future__ import annotations

import sys
from pathlib import Path

from photomodel.data.fetch import PackageFiles, package_files, print_folder

LANDMARK_MODEL = "face_landmark.tflite"
DETECTION_MODEL = "face_detection_short_range.tflite"
SEGMENTATION_MODEL = "selfie_segmentation.tflite"
HAND_MODEL = "hand_landmark_full.tflite"

MEDIAPIPE = PackageFiles(
    package="mediapipe",
    version="0.10.21",
    archive_name="mediapipe-0.10.21-cp311-cp311-manylinux_2_28_x86_64.whl",
    archive_sha256="05dc4a9e593655a79558d05d6227d31018c2537a4bd3362b51e230cf22aecfe3",
    members={
        LANDMARK_MODEL: (
            "mediapipe/modules/face_landmark/face_landmark.tflite",
            "1055cb9d4a9ca8b8c688902a3a5194311138ba256bcc94e336d8373a5f30c814",
        ),
        DETECTION_MODEL: (
            "mediapipe/modules/face_detection/face_detection_short_range.tflite",
            "bbff11cebd1eb27a1e004cae0b0e63ec8c551cbf34a4451148b4908b8db3eca8",
        ),
        SEGMENTATION_MODEL: (
            "mediapipe/modules/selfie_segmentation/selfie_segmentation.tflite",
            "9ee168ec7c8f2a16c56fe8e1cfbc514974cbbb7e434051b455635f1bd1462f5c",
        ),
        HAND_MODEL: (
            "mediapipe/modules/hand_landmark/hand_landmark_full.tflite",
            "11c272b891e1a99ab034208e23937a8008388cf11ed2a9d776ed3d01d0ba00e3",
        ),
        "LICENSE": (
            "mediapipe-0.10.21.dist-info/LICENSE",
            "8707eef0533987efc5b155d64761eeb6e20793f50b9bd1a68dad1cf4719d0ed8",  # Apache-2.0
        ),
    },
    pip_args=(
        "--only-binary=:all:",
        "--python-version",
        "3.11",
        "--platform",
        "manylinux_2_28_x86_64",
    ),
    env_archive="FACESTUDIO_MEDIAPIPE_WHEEL",
)


def model_dir() -> Path:
    """Folder holding the verified MediaPipe models; fetch them if needed.

    Raises
    ------
    SampleDataError
        when the wheel cannot be obtained or a checksum fails; the message says what to do.
    """
    return package_files(MEDIAPIPE)


def main(argv: list[str] | None = None) -> int:
    """``python -m photomodel.landmarks.models``: fetch and verify the models, print their folder."""
    del argv
    return print_folder(model_dir)


if __name__ == "__main__":
    sys.exit(main())
