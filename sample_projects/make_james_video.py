"""Build the sample tracking video of the ``james`` project: frames of the scan blended per region with
smoothly varying expression weights under smooth head motion (:mod:`tracking.samples`).

Run from the repository root::

    .venv/bin/python sample_projects/make_james_video.py [--frames 40] [--out sample_projects/james]

It writes ``<out>/video/james_track.mp4`` (300×300, 10 fps, OpenCV's ``mp4v`` codec — a kept
encoder; the frames are lossy-compressed like real footage) and ``<out>/video_truth.json`` (per
frame: head rotation ``R`` and translation ``t`` with ``X_cam = R X + t`` in mm, the blending
weights of each control region, the camera's focal length). Deterministic.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from tracking.samples import render_video_frame, video_truth  # noqa: E402

FPS = 10


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=40)
    ap.add_argument("--out", type=Path, default=REPO / "sample_projects" / "james")
    args = ap.parse_args(argv)
    truth = video_truth(args.frames)
    folder = args.out / "video"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "james_track.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), FPS, (truth.width, truth.height))
    if not writer.isOpened():
        print("OpenCV cannot write mp4 video here", file=sys.stderr)
        return 1
    for i in range(truth.frames):
        rgb = render_video_frame(truth, i)
        writer.write(np.clip(rgb[..., ::-1] * 255.0 + 0.5, 0, 255).astype(np.uint8))
    writer.release()
    (args.out / "video_truth.json").write_text(json.dumps(truth.to_dict(), indent=1))
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, {truth.frames} frames) and video_truth.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
