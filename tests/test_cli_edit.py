"""``facestudio edit`` (app/cli/edit.py, tracking/edit_video.py) on a tracked run of the sample video."""

import json
import shutil

import av
import numpy as np
import pytest

from app.cli import main
from photomodel.photos.video import VideoFrames
from tracking.edit import load_edits
from tracking.edit_video import write_video
from tracking.track_result import load_track_results


@pytest.fixture
def track_copy(straight, tmp_path):
    out = tmp_path / "track"
    shutil.copytree(straight.out_dir, out)
    return out


def test_edit_writes_frames_video_and_edits_json(track_copy, fitted_sample, tmp_path, capsys):
    out = tmp_path / "edited.mp4"
    rc = main(
        [
            "edit",
            str(fitted_sample),
            "--track",
            str(track_copy),
            "--scale",
            "smile=0",
            "--span",
            "2:5",
            "--replace",
            "0:1@4",
            "--no-smooth",
            "--out",
            str(out),
            "--json",
        ]
    )
    assert rc == 0
    rep = json.loads(capsys.readouterr().out)
    doc = load_track_results(track_copy)
    n = len(doc["frames"])
    assert rep["frames"] == n and 1 <= rep["edited"] <= n and rep["audio"] is False  # the sample has no audio
    edits = load_edits(track_copy)
    assert [e["op"] for e in edits["edits"]] == ["scale", "replace"] and edits["smooth"] is None
    assert edits["edits"][0]["span"] == [2, 5]
    # the video: every frame, at the footage's frame rate
    source = VideoFrames(doc["video"]["path"])
    with av.open(str(out)) as c:
        stream = c.streams.video[0]
        assert float(stream.average_rate) == pytest.approx(source.fps, rel=1e-3)
        assert sum(1 for _ in c.decode(stream)) == n
    # the PNG frames: lossless, the footage's own pixels away from the face
    written = VideoFrames(rep["frames_dir"])
    assert written.count == n
    changed = 0
    for (_, got), (_, orig) in zip(written.frames(), source.frames(0, n), strict=False):
        border = np.ones(got.shape[:2], bool)
        border[20:, 45:255] = False  # the head and shoulders of the sample video stay inside this box
        np.testing.assert_array_equal(got[border], orig[border])
        changed += bool(np.any(got != orig))
    # the face did change: frames 2–5 lose their smile, frame 1 is replaced (frame 0, the clip's first,
    # is the replacement's own end)
    assert changed == n - 1 == rep["edited"]


def test_edit_reuses_stored_edits_and_names_bad_arguments(track_copy, fitted_sample, tmp_path, capsys):
    args = ["edit", str(fitted_sample), "--track", str(track_copy), "--no-smooth", "--out", str(tmp_path / "f")]
    assert main(args + ["--json"]) == 2  # nothing to edit yet
    assert "nothing to edit" in json.loads(capsys.readouterr().out)["error"]["message"]
    assert main(args + ["--scale", "grin=2", "--json"]) == 2
    assert "grin" in json.loads(capsys.readouterr().out)["error"]["message"]
    assert main(args + ["--replace", "5:2@3"]) == 2
    assert "FIRST:LAST" in capsys.readouterr().err
    assert main(args + ["--scale", "smile=1.5"]) == 0
    assert main(args) == 0  # the stored edits again
    assert len(list((tmp_path / "f").glob("frame_*.png"))) == len(load_track_results(track_copy)["frames"])


def test_video_keeps_the_footages_audio(tmp_path):
    src = tmp_path / "with_audio.mp4"
    with av.open(str(src), "w") as c:
        v = c.add_stream("libx264", rate=25)
        v.width = v.height = 32
        v.pix_fmt = "yuv420p"
        a = c.add_stream("aac", rate=44100)
        a.layout = "mono"
        for i in range(10):
            for p in v.encode(av.VideoFrame.from_ndarray(np.full((32, 32, 3), 20 * i, np.uint8), format="rgb24")):
                c.mux(p)
        for p in v.encode():
            c.mux(p)
        t = np.arange(44100 * 10 // 25) / 44100
        frame = av.AudioFrame.from_ndarray(
            0.3 * np.sin(2 * np.pi * 440 * t).astype(np.float32)[None], format="fltp", layout="mono"
        )
        frame.sample_rate = 44100
        for p in [*a.encode(frame), *a.encode()]:
            c.mux(p)
    out = tmp_path / "edited.mp4"
    assert write_video(out, [np.full((31, 33, 3), i / 10, np.float32) for i in range(10)], 25.0, src) is True
    with av.open(str(out)) as c, av.open(str(src)) as s:
        assert c.streams.audio[0].codec_context.name == "aac"
        got = [bytes(p) for p in c.demux(c.streams.audio[0]) if p.size]
        want = [bytes(p) for p in s.demux(s.streams.audio[0]) if p.size]
        assert got == want  # copied packet for packet, not re-encoded
    with av.open(str(out)) as c:
        assert sum(1 for _ in c.decode(video=0)) == 10


def test_an_unknown_expression_is_named_before_the_smoothing(track_copy, fitted_sample, tmp_path, monkeypatch, capsys):
    """Issue 35: ``--scale nosuch=2`` is an error before any work (the whole-clip smoothing ran first)."""
    import tracking.edit_video  # noqa: PLC0415 - the module whose smoothing must not run

    def smoothing(*args, **kwargs):
        raise AssertionError("the smoothing ran before the arguments were checked")

    monkeypatch.setattr(tracking.edit_video, "smooth_clip", smoothing)
    out = tmp_path / "e.mp4"
    args = ["edit", str(fitted_sample), "--track", str(track_copy), "--scale", "nosuch=2", "--out", str(out)]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "'nosuch' is not one of the model's" in err and not out.exists()
    assert main([*args[:5], "smile=2", "--replace", "0:999@1", "--out", str(out)]) == 2
    assert "outside the clip's frames" in capsys.readouterr().err
