"""Tests of tracking.track_result: ``track.json`` and ``track.csv`` of a run (``straight``,
tests/conftest.py: the first frames of the sample video), and continuing only results of the same
settings."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from tracking.run import track_video
from tracking.track_result import CSV_COLUMNS, load_track_results

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"
VIDEO = SAMPLE / "video" / "james_track.mp4"
FRAMES = 6


def test_csv_matches_json(straight):
    doc = load_track_results(straight.out_dir)
    with open(straight.out_dir / "track.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(doc["frames"])
    head, tail = CSV_COLUMNS
    assert list(rows[0])[: len(head)] == head and list(rows[0])[-len(tail) :] == tail
    for row, f in zip(rows, doc["frames"], strict=True):
        assert int(row["frame"]) == f["frame"]
        got = [float(row[c]) for c in ("rx_rad", "ry_rad", "rz_rad", "tx_mm", "ty_mm", "tz_mm", "cx_mm", "cy_mm")]
        np.testing.assert_allclose(got, f["rotation_vector"] + f["t_mm"] + f["centre_mm"][:2], rtol=0, atol=1e-12)
        for r, ws in f["weights"].items():
            for e, w in ws.items():
                assert float(row[f"w_{r}_{e}"]) == w
        assert float(row["rms"]) == f["rms"] and int(row["diverged"]) == int(f["diverged"])


def test_other_settings_in_the_folder_are_refused(straight, fitted_sample):
    with pytest.raises(Exception, match="other settings .*camera"):
        track_video(fitted_sample, VIDEO, straight.out_dir, max_frames=FRAMES, focal_px=500.0)
