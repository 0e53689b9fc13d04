"""Focal lengths from EXIF (photomodel/exif.py) and their use when photos are added (app.studio_state).

The photos are small JPEGs written by Pillow with the EXIF tags each test needs; each test first
checks that the tags were written, so a Pillow that stopped writing them fails loudly here rather
than making the reader's tests pass vacuously."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from PIL.TiffImagePlugin import IFDRational

from app.studio_state import StudioModel
from photomodel.photos.exif import (
    EXIF_IFD,
    TAG_EXIF_IMAGE_HEIGHT,
    TAG_EXIF_IMAGE_WIDTH,
    TAG_FOCAL_LENGTH,
    TAG_FOCAL_LENGTH_35MM,
    TAG_FOCAL_PLANE_RES_UNIT,
    TAG_FOCAL_PLANE_X_RES,
    TAG_FOCAL_PLANE_Y_RES,
    focal_mm_36_from_exif,
    focal_mm_guess_from_exif,
)
from photomodel.project import load_project


def write_jpeg(path: Path, tags: dict | None = None, size=(60, 40)) -> Path:
    """A grey ``size`` (w, h) JPEG whose Exif IFD holds ``tags`` (none: no EXIF at all)."""
    img = Image.fromarray(np.full((size[1], size[0], 3), 128, np.uint8))
    if tags is None:
        img.save(path, quality=90)
        return path
    exif = Image.Exif()
    ifd = exif.get_ifd(EXIF_IFD)
    ifd.update(tags)
    img.save(path, quality=90, exif=exif)
    with Image.open(path) as back:  # the tags really are in the file
        stored = back.getexif().get_ifd(EXIF_IFD)
        assert {k: float(stored[k]) for k in tags} == pytest.approx({k: float(v) for k, v in tags.items()})
    return path


def test_35mm_equivalent_is_used_as_is(tmp_path):
    # a phone: 4.25 mm lens, 26 mm equivalent; the equivalent wins over the computed value
    p = write_jpeg(
        tmp_path / "phone.jpg",
        {TAG_FOCAL_LENGTH_35MM: 26, TAG_FOCAL_LENGTH: 4.25, TAG_FOCAL_PLANE_X_RES: 1000.0, TAG_FOCAL_PLANE_RES_UNIT: 4},
    )
    assert focal_mm_36_from_exif(p) == 26.0
    assert isinstance(focal_mm_36_from_exif(str(p)), float)


def test_focal_length_and_focal_plane_resolution(tmp_path):
    # an APS-C camera: 6000 px across a 23.5 mm sensor, 35 mm lens → 35 × 36 / 23.5 = 53.6 mm
    xres_per_cm = 6000 / 2.35
    tags = {
        TAG_FOCAL_LENGTH: 35.0,
        TAG_FOCAL_PLANE_X_RES: xres_per_cm,
        TAG_FOCAL_PLANE_RES_UNIT: 3,
        TAG_EXIF_IMAGE_WIDTH: 6000,
        TAG_EXIF_IMAGE_HEIGHT: 4000,
    }
    p = write_jpeg(tmp_path / "apsc.jpg", tags)  # resized to 60 px: the resolution counts the original 6000
    assert focal_mm_36_from_exif(p) == pytest.approx(35 * 36 / 23.5, rel=1e-4)
    # every unit: inch, cm, mm, µm
    for unit, mm in {2: 25.4, 3: 10.0, 4: 1.0, 5: 1e-3}.items():
        q = write_jpeg(
            tmp_path / f"unit{unit}.jpg",
            {**tags, TAG_FOCAL_PLANE_X_RES: 6000 / (23.5 / mm), TAG_FOCAL_PLANE_RES_UNIT: unit},
        )
        assert focal_mm_36_from_exif(q) == pytest.approx(35 * 36 / 23.5, rel=1e-4), unit
    # without ExifImageWidth the file's own width is the one the resolution counts
    own = write_jpeg(
        tmp_path / "own.jpg", {TAG_FOCAL_LENGTH: 35.0, TAG_FOCAL_PLANE_X_RES: 60 / 2.35, TAG_FOCAL_PLANE_RES_UNIT: 3}
    )
    assert focal_mm_36_from_exif(own) == pytest.approx(35 * 36 / 23.5, rel=1e-4)
    # the sensor's long side counts, also when the stored image is portrait
    portrait = write_jpeg(
        tmp_path / "portrait.jpg",
        {
            TAG_FOCAL_LENGTH: 35.0,
            TAG_FOCAL_PLANE_X_RES: 40 / 1.567,
            TAG_FOCAL_PLANE_Y_RES: 40 / 1.567,
            TAG_FOCAL_PLANE_RES_UNIT: 3,
        },
        size=(40, 60),
    )
    assert focal_mm_36_from_exif(portrait) == pytest.approx(35 * 36 / 23.5, rel=1e-3)


def test_no_focal_length_is_none(tmp_path):
    assert focal_mm_36_from_exif(write_jpeg(tmp_path / "plain.jpg")) is None  # no EXIF
    # EXIF but nothing usable: no tags / a lens without sensor size / a 35 mm tag of 0 (= unknown)
    assert focal_mm_36_from_exif(write_jpeg(tmp_path / "other.jpg", {0x9003: 1})) is None
    assert focal_mm_36_from_exif(write_jpeg(tmp_path / "lens.jpg", {TAG_FOCAL_LENGTH: 35.0})) is None
    zero = write_jpeg(
        tmp_path / "zero.jpg",
        {
            TAG_FOCAL_LENGTH_35MM: 0,
            TAG_FOCAL_LENGTH: 50.0,
            TAG_FOCAL_PLANE_X_RES: 60 / 3.6,
            TAG_FOCAL_PLANE_RES_UNIT: 3,
        },
    )
    assert focal_mm_36_from_exif(zero) == pytest.approx(50.0)  # 0 falls through to the focal length
    bad_unit = write_jpeg(
        tmp_path / "unit.jpg", {TAG_FOCAL_LENGTH: 50.0, TAG_FOCAL_PLANE_X_RES: 100.0, TAG_FOCAL_PLANE_RES_UNIT: 9}
    )
    assert focal_mm_36_from_exif(bad_unit) is None
    absurd = write_jpeg(tmp_path / "absurd.jpg", {TAG_FOCAL_LENGTH_35MM: 60000})
    assert focal_mm_36_from_exif(absurd) is None  # outside PLAUSIBLE_35MM: corrupt
    assert focal_mm_36_from_exif(tmp_path / "absent.jpg") is None


def test_garbage_is_none_never_an_error(tmp_path):
    junk = tmp_path / "junk.jpg"
    junk.write_bytes(b"\xff\xd8" + bytes(range(256)) * 4)
    assert focal_mm_36_from_exif(junk) is None
    text = tmp_path / "notes.jpg"
    text.write_text("not an image")
    assert focal_mm_36_from_exif(text) is None
    # a decodable JPEG whose APP1 EXIF block is cut short and nonsensical
    good = write_jpeg(tmp_path / "good.jpg").read_bytes()
    payload = b"Exif\x00\x00MM\x00\x2a\x00\x00\x00\x08\x00\x05" + b"\xa4\x05garbage" * 3
    app1 = b"\xff\xe1" + (len(payload) + 2).to_bytes(2, "big") + payload
    broken = tmp_path / "broken.jpg"
    broken.write_bytes(good[:2] + app1 + good[2:])
    with pytest.warns(UserWarning, match="Corrupt EXIF"), Image.open(broken) as img:
        assert img.size == (60, 40)  # still an image, with an EXIF block Pillow calls corrupt
        img.getexif().get_ifd(EXIF_IFD)
    assert focal_mm_36_from_exif(broken) is None
    # tags of the wrong type: a zero-denominator rational (reads back as nan), text, bytes

    cases = {
        "nan": {TAG_FOCAL_LENGTH: IFDRational(35, 0), TAG_FOCAL_PLANE_X_RES: 100.0},
        "text": {TAG_FOCAL_LENGTH_35MM: "fifty", TAG_FOCAL_LENGTH: 35.0, TAG_FOCAL_PLANE_X_RES: b"xx"},
        "unit": {TAG_FOCAL_LENGTH: 35.0, TAG_FOCAL_PLANE_X_RES: 100.0, TAG_FOCAL_PLANE_RES_UNIT: "cm"},
    }
    for name, tags in cases.items():
        exif = Image.Exif()
        exif.get_ifd(EXIF_IFD).update({TAG_FOCAL_PLANE_RES_UNIT: 3, **tags})
        odd = tmp_path / f"{name}.jpg"
        Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(odd, exif=exif)
        with Image.open(odd) as img:
            assert set(img.getexif().get_ifd(EXIF_IFD)) >= set(tags)
        assert focal_mm_36_from_exif(odd) is None, name


def test_project_units_for_portrait_images(tmp_path):
    """``focal_mm_guess`` is mm on a sensor 36 mm across the image's width: the 35 mm equivalent
    for landscape images, × h / w for portrait ones (same field of view across the long side)."""
    p = write_jpeg(tmp_path / "f.jpg", {TAG_FOCAL_LENGTH_35MM: 50})
    assert focal_mm_guess_from_exif(p, 60, 40) == 50.0
    assert focal_mm_guess_from_exif(p, 40, 60) == pytest.approx(75.0)
    assert focal_mm_guess_from_exif(write_jpeg(tmp_path / "n.jpg"), 60, 40) is None


def test_adding_a_photo_reads_its_focal_length(tmp_path):
    """The studio's way in (StudioModel.photo_from_file, used by File → Add photos… and drops):
    the EXIF focal length becomes the photo's focal_mm_guess, saved with the project; a value the
    caller gives wins; a photo without EXIF has none."""
    model = StudioModel()
    with_exif = write_jpeg(tmp_path / "front.jpg", {TAG_FOCAL_LENGTH_35MM: 85})
    without = write_jpeg(tmp_path / "left.jpg")
    photo = model.photo_from_file(with_exif)
    assert photo.focal_mm_guess == 85.0
    assert model.photo_from_file(with_exif, focal_mm_guess=50.0).focal_mm_guess == 50.0
    plain = model.photo_from_file(without, preset="left")
    assert plain.focal_mm_guess is None
    expression = model.expression_name
    model.insert_photo(expression, photo)
    model.insert_photo(expression, plain)
    saved = model.save(tmp_path / "p.facestudio.json")
    photos = {p.id: p for p in load_project(saved).expression(expression).photos}
    assert photos["front"].focal_mm_guess == 85.0 and photos["left"].focal_mm_guess is None
