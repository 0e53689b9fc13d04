"""The MediaPipe ``.tflite`` networks run through ``cv2.dnn``, one instance per thread.

A ``cv2.dnn.Net`` keeps its input and intermediate blobs in the object, so two threads may not
run the same net at once. Until 2026-12-05 each module held one net behind a lock; ``facestudio
auto`` runs the detector in three threads at once (the tracker's pass per frame, the landmark
checks on every 3rd frame, the overlay) and the lock made them queue: the tracker waited for a
full detection (~50 ms) every few frames. Each thread now reads its own copy of a model (a few
MB; read once per thread and file).
"""

from __future__ import annotations

import threading
from pathlib import Path

import cv2
import numpy as np

_local = threading.local()


def thread_net(path: Path) -> cv2.dnn.Net:
    """This thread's ``cv2.dnn`` net of the ``.tflite`` file at ``path`` (classic engine: the
    default one returns only the first output)."""
    nets = getattr(_local, "nets", None)
    if nets is None:
        nets = _local.nets = {}
    net = nets.get(path)
    if net is None:
        net = nets[path] = cv2.dnn.readNetFromTFLite(str(path), engine=cv2.dnn.ENGINE_CLASSIC)
    return net


def run_net(net: cv2.dnn.Net, image: np.ndarray, names: list[str] | None = None) -> list[np.ndarray]:
    """Outputs ``names`` of ``net`` for one (s, s, 3) float32 image (NHWC → NCHW); without
    ``names``, the net's default output alone (a list of one)."""
    net.setInput(np.ascontiguousarray(image.transpose(2, 0, 1)[None]))
    return [net.forward()] if names is None else list(net.forward(names))
