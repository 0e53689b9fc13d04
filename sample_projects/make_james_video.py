"""Build the sample tracking video of the ``james`` project: frames of the scan blended per region with
smoothly varying expression weights under smooth head motion (:mod:`tracking.synthetic_sequences.ground_truth`).

Run from the repository root::

    .venv/bin/python sample_projects/make_james_video.py [--frames 40] [--out sample_projects/james]

It writes ``<out>/video/james_track.mp4`` (300×300, 10 fps, OpenCV's ``mp4v`` codec — a kept
encoder; the frames are lossy-compressed like real footage) and ``<out>/video_truth.json`` (per
frame: head rotation ``R`` and translation ``t`` with ``X_cam = R X + t`` in mm, the blending
weights of each control region, the camera's focal length) and ``<out>/video/james_track.first_pose.json``,
what a user gives ``facestudio track`` for the first frame: the video camera's focal length and the
13 pose features of the project clicked in frame 0 (their true positions with 0.5 px noise, as a
careful user would click them). Deterministic.
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

from photomodel.project import load_project  # noqa: E402
from tracking.synthetic_sequences.ground_truth import render_video_frame, sample_face_model, video_truth  # noqa: E402

FPS = 10
PROJECT = REPO / "sample_projects" / "james" / "james.facestudio.json"
#: Click noise (px, per coordinate) of the sample's first-pose clicks.
CLICK_NOISE_PX = 0.5


def first_pose_clicks(truth) -> dict:
    """The first-pose JSON of the sample video (:func:`tracking.first_pose.load_first_pose`): the focal
    length and the project's pose features clicked in frame 0 (true positions + noise)."""
    project = load_project(PROJECT)
    names = project.feature_names(pose_only=True)
    model = sample_face_model(truth.names)
    X = model.blend_geometry(model.vertex_weights(truth.weights[0]))[project.feature_vertices(names)]
    uv = truth.camera(0).project(X) + np.random.default_rng(2).normal(0.0, CLICK_NOISE_PX, (len(names), 2))
    return {
        "focal_px": truth.focal_px,
        "clicks": {n: [round(float(u), 2), round(float(v), 2)] for n, (u, v) in zip(names, uv, strict=True)},
    }


def first_pose_json(spec: dict) -> str:
    """The first-pose JSON text with one line per click (easy to edit by hand)."""
    clicks = ",\n".join(f"  {json.dumps(n)}: {json.dumps(uv)}" for n, uv in spec["clicks"].items())
    return f'{{\n "focal_px": {spec["focal_px"]},\n "clicks": {{\n{clicks}\n }}\n}}\n'


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
    (folder / "james_track.first_pose.json").write_text(first_pose_json(first_pose_clicks(truth)))
    print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB, {truth.frames} frames) and video_truth.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
