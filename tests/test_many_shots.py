"""Tests of tracking.many_shots (``facestudio track-many``) with real Dask workers: one batch on a
2-worker ``LocalCluster`` of processes — two copies of the sample video and a corrupt one, a worker
killed mid-shot (``os._exit``) — whose killed shot must equal an uninterrupted ``facestudio track``
run (``straight``, tests/conftest.py), the corrupt shot failing alone; then a rerun that skips the
finished shots. Short shots (FRAMES frames) keep the file fast."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from app.cli import main
from photomodel.errors import FaceStudioError
from tracking.many_shots import EXIT_AFTER_ENV, SUMMARY_CSV, SUMMARY_JSON, plan_shots, track_many
from tracking.track_result import load_track_results

SAMPLE_VIDEO = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "video"
FRAMES = 4
#: Results saved every SAVE frames and a worker killed after KILL_AFTER: the retry must continue
#: after the saved frames (resumed_from == SAVE), not from the start.
SAVE, KILL_AFTER = 2, 3


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    """Two shots (copies of the sample video with their first-pose files) and a corrupt video."""
    d = tmp_path_factory.mktemp("clips")
    for name in ("shot_a", "shot_b", "broken"):
        shutil.copy(SAMPLE_VIDEO / "james_track.first_pose.json", d / f"{name}.first_pose.json")
    for name in ("shot_a", "shot_b"):
        shutil.copy(SAMPLE_VIDEO / "james_track.mp4", d / f"{name}.mp4")
    (d / "broken.mp4").write_bytes((SAMPLE_VIDEO / "james_track.mp4").read_bytes()[:4000])  # truncated
    return [d / "shot_a.mp4", d / "shot_b.mp4", d / "broken.mp4"]


@pytest.fixture(scope="module")
def batch(tmp_path_factory, clips, fitted_sample):
    """One batch on 2 worker processes, the first worker to track KILL_AFTER frames killed: the
    BatchResult, the output folder and the killed shot's video."""
    out = tmp_path_factory.mktemp("batch")
    flag = out.parent / f"{out.name}.killed"
    mp = pytest.MonkeyPatch()
    mp.setenv(EXIT_AFTER_ENV, f"{KILL_AFTER}:{flag}")  # the workers inherit it
    try:
        res = track_many(fitted_sample, clips, out, workers=2, max_frames=FRAMES, overlay=False, save_every=SAVE)
    finally:
        mp.undo()
    return res, out, Path(flag.read_text())


def test_killed_worker_shot_retried_equals_a_clean_run(batch, straight):
    res, out, killed = batch
    shot = next(s for s in res.shots if s.video == str(killed))
    assert shot.status == "tracked" and shot.frames == FRAMES and shot.complete
    assert shot.resumed_from == SAVE  # the retry continued after the frames the killed worker saved
    frames = load_track_results(out / f"track_{killed.stem}")["frames"]
    # the fitter is deterministic and the JSON keeps full precision: the clean run's numbers (1e-6
    # leaves room for float32 summation order in the renderer, as in tests/test_run.py)
    for a, b in zip(frames, straight.frames[:FRAMES], strict=True):
        assert a["frame"] == b["frame"] and a["start"] == b["start"]
        np.testing.assert_allclose(a["R"], b["R"], atol=1e-6)
        np.testing.assert_allclose(a["centre_mm"], b["centre_mm"], atol=1e-4)
        np.testing.assert_allclose(a["alpha"], b["alpha"], atol=1e-5)


def test_corrupt_video_fails_alone_and_the_summary_lists_every_shot(batch, clips):
    res, out, _ = batch
    by_name = {Path(s.video).name: s for s in res.shots}
    assert by_name["broken.mp4"].status == "failed" and "broken.mp4" in by_name["broken.mp4"].error
    assert "VideoError" in by_name["broken.mp4"].error
    assert [by_name[n].status for n in ("shot_a.mp4", "shot_b.mp4")] == ["tracked", "tracked"]
    assert res.workers == 2 and res.failed == 1 and res.tracked_frames >= 2 * FRAMES - SAVE
    doc = json.loads((out / SUMMARY_JSON).read_text())
    assert doc["shots"] == 3 and doc["failed"] == 1 and doc["by_status"]["tracked"] == 2
    assert [s["video"] for s in doc["shot_results"]] == [str(c) for c in clips]
    rows = list(csv.DictReader((out / SUMMARY_CSV).open()))
    assert [r["status"] for r in rows] == ["tracked", "tracked", "failed"] and rows[0]["frames"] == str(FRAMES)
    # the two good shots tracked the same video: the same results
    a, b = (load_track_results(out / f"track_{n}")["frames"] for n in ("shot_a", "shot_b"))
    np.testing.assert_allclose([f["alpha"] for f in a], [f["alpha"] for f in b], atol=1e-5)


def test_rerun_skips_finished_shots_and_prints_one_json_object(batch, clips, fitted_sample, capsys):
    _, out, _ = batch
    code = main(
        [
            "track-many",
            str(fitted_sample),
            *map(str, clips[:2]),
            "--out",
            str(out),
            "--frames",
            str(FRAMES),
            "--no-overlay",
            "--json",
        ]
    )
    summary = json.loads(capsys.readouterr().out)  # exactly one object
    assert code == 0 and summary["by_status"]["skipped"] == 2 and summary["tracked_frames"] == 0
    assert summary["workers"] == 0  # nothing to track: no cluster started


def test_two_videos_with_one_stem_are_refused(tmp_path):
    (tmp_path / "x").mkdir()
    with pytest.raises(FaceStudioError, match="share the results folder"):
        plan_shots(tmp_path / "p.facestudio.json", [tmp_path / "a.mp4", tmp_path / "x" / "a.mp4"])
    (shot,) = plan_shots(tmp_path / "p.facestudio.json", [tmp_path / "a.mp4"])
    assert shot.out_dir == tmp_path / "results" / "track_a"  # where `facestudio track` puts them


def test_pin_threads_limits_renderer_opencv_and_blas():
    # in a fresh process: the limits are process-wide and would slow the rest of the suite
    code = (
        "import os, cv2, json; from threadpoolctl import threadpool_info; "
        "from tracking.many_shots import pin_threads; pin_threads(1); "
        "print(json.dumps([os.environ['LP_NUM_THREADS'], cv2.getNumThreads(), "
        "[p['num_threads'] for p in threadpool_info() if p['user_api'] == 'blas']]))"
    )
    lp, cv, blas = json.loads(
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    )
    assert lp == "1" and cv == 1 and blas and set(blas) == {1}
