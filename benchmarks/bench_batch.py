"""Batch tracking benchmark (issue 17): ``facestudio track-many`` on a 2-worker Dask ``LocalCluster``
against the same shots tracked one after another, and a worker killed mid-shot.

The shots: ``--shots`` (4) clips of ``--frames`` (100) frames made from the sample video
(``sample_projects/james/video/james_track.mp4``, 40 frames, played forward, back, forward again),
each with the sample's first-pose file, tracked with the fitted sample project's face model
(:func:`tracking.synthetic_sequences.ground_truth.fitted_sample_project`), plots and overlay video included
(what the command does).

* ``sequential_s`` — the shots one after another in one worker process (a 1-worker
  ``LocalCluster``), with the same per-process thread settings as each parallel worker (llvmpipe,
  OpenCV and BLAS pinned to cores // workers threads, :func:`tracking.many_shots.pin_threads`);
  its cluster start-up left out.
* ``parallel_s`` — the same shots on a ``--workers`` (2) worker ``LocalCluster``, in the same run,
  cluster start-up included; ``startup_s`` is that start-up. The bar: ``parallel_s ≤ 0.8 ×
  sequential_s``.
* ``killed_worker`` — two shots of 20 frames on a 2-worker cluster, the first worker to track 12
  frames killed (``os._exit``, :data:`tracking.many_shots.EXIT_AFTER_ENV`): ``completed`` (every
  shot tracked), ``identical`` (the killed shot's ``track.json`` frames equal the parallel run's
  first 20 frames of that clip bit for bit, the frames' own timing ``seconds`` aside).

On a shared machine the times move with the other work on it; the printout says the load.

Run::

    .venv/bin/python benchmarks/bench_batch.py [--shots 4] [--frames 100] [--workers 2] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

import cv2

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from tracking.many_shots import EXIT_AFTER_ENV, track_many  # noqa: E402
from tracking.synthetic_sequences.ground_truth import fitted_sample_project  # noqa: E402
from tracking.track_result import load_track_results  # noqa: E402

SAMPLE_VIDEO = REPO / "sample_projects" / "james" / "video"
KILL_FRAMES, KILL_AFTER = 20, 12


def make_clips(folder: Path, shots: int, frames: int) -> list[Path]:
    """``shots`` copies of a ``frames``-frame clip: the sample video forward, back, forward…, each
    with the sample's first-pose file beside it."""
    cap = cv2.VideoCapture(str(SAMPLE_VIDEO / "james_track.mp4"))
    src = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        src.append(bgr)
    cap.release()
    order, step, i = [], 1, 0
    while len(order) < frames:  # bounce between the ends, never repeating a frame twice in a row
        order.append(i)
        if not 0 <= i + step < len(src):
            step = -step
        i += step
    first = folder / "clip_0.mp4"
    h, w = src[0].shape[:2]
    out = cv2.VideoWriter(str(first), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (w, h))
    for k in order:
        out.write(src[k])
    out.release()
    clips = []
    for n in range(shots):
        clip = folder / f"clip_{n}.mp4"
        if n:
            shutil.copy(first, clip)
        shutil.copy(SAMPLE_VIDEO / "james_track.first_pose.json", folder / f"clip_{n}.first_pose.json")
        clips.append(clip)
    return clips


def frames_without_timing(out_dir: Path, n: int) -> list[dict]:
    return [{k: v for k, v in f.items() if k != "seconds"} for f in load_track_results(out_dir)["frames"][:n]]


def killed_worker(project: Path, clips: list[Path], clean_root: Path, work: Path, workers: int) -> dict:
    """Two shots on a ``workers``-worker cluster with a worker killed mid-shot; completed and
    identical (see the module docstring)."""
    flag = work / "killed.flag"
    os.environ[EXIT_AFTER_ENV] = f"{KILL_AFTER}:{flag}"  # the workers inherit it
    try:
        res = track_many(project, clips[:2], work / "killed", workers=workers, max_frames=KILL_FRAMES)
    finally:
        del os.environ[EXIT_AFTER_ENV]
    killed = Path(flag.read_text()) if flag.is_file() else None
    completed = killed is not None and all(s.status == "tracked" and s.frames == KILL_FRAMES for s in res.shots)
    identical = completed and frames_without_timing(
        work / "killed" / f"track_{killed.stem}", KILL_FRAMES
    ) == frames_without_timing(clean_root / f"track_{killed.stem}", KILL_FRAMES)
    resumed = next((s.resumed_from for s in res.shots if killed and s.video == str(killed)), None)
    return {
        "completed": bool(completed),
        "identical": bool(identical),
        "_resumed_from": resumed,
        "_killed": str(killed),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--shots", type=int, default=4)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    project = fitted_sample_project()
    threads = max(1, (os.cpu_count() or 1) // args.workers)
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        work = Path(tmp)
        clips = make_clips(work, args.shots, args.frames)
        seq = track_many(project, clips, work / "sequential", workers=1, threads=threads)
        par = track_many(project, clips, work / "parallel", workers=args.workers, threads=threads)
        kill = killed_worker(project, clips, work / "parallel", work, args.workers)
    ok = all(s.status == "tracked" for s in seq.shots + par.shots)
    out = {
        "shots": args.shots,
        "frames_per_shot": args.frames,
        "workers": args.workers,
        "sequential_s": round(seq.seconds - seq.startup_s, 2),
        "parallel_s": round(par.seconds, 2),
        "startup_s": round(par.startup_s, 2),
        "killed_worker": {"completed": kill["completed"], "identical": kill["identical"]},
    }
    if args.json:
        print(json.dumps(out))
        return 0 if ok else 1
    ratio = out["parallel_s"] / out["sequential_s"]
    print(
        f"{args.shots} shots x {args.frames} frames, {os.cpu_count()} cores, {threads} thread(s) per worker, "
        f"load average {load:.1f} at the start, {os.getloadavg()[0]:.1f} at the end"
    )
    print(
        f"  sequential (1 worker):      {out['sequential_s']:8.1f} s ({seq.tracked_frames / out['sequential_s']:.2f} "
        f"frames/s; its start-up {seq.startup_s:.1f} s left out)"
    )
    print(
        f"  parallel ({args.workers} workers):       {out['parallel_s']:8.1f} s (start-up {out['startup_s']:.1f} s "
        f"included) = {ratio:.2f} x sequential (bar 0.80)"
    )
    print(
        f"  worker killed mid-shot:     completed {kill['completed']}, identical {kill['identical']} (killed "
        f"{Path(kill['_killed']).name}, the retry resumed from frame {kill['_resumed_from']})"
    )
    if not ok:
        print("  some shots failed:", [(s.video, s.error) for s in seq.shots + par.shots if s.status != "tracked"])
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
