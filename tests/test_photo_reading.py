"""Tests of photomodel/photos/reading.py: the one photo reader — EXIF orientation, truncated files,
a working resolution for very large photos, photos of the same image.

Photos are a few hundred pixels so that every test is fast; "very large" is simulated with a small
``max_side`` (the reduction logic does not depend on the threshold's value)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from PIL import Image
from project_samples import sample_project, write_photos

from photomodel.errors import PhotoError, ProjectError
from photomodel.photos.exif import EXIF_IFD, TAG_FOCAL_LENGTH, camera_identity
from photomodel.photos.reading import (
    duplicate_pairs,
    fingerprint,
    photo_size,
    photos_in_folder,
    read_photo,
    to_original,
    to_working,
    truncation_problem,
    unreadable_photos_in_folder,
)
from photomodel.project import save_project

TAG_ORIENTATION = 0x0112


def textured(h=300, w=400, seed=0) -> np.ndarray:
    """A smooth RGB image with structure at every scale (JPEG-friendly, not flat)."""
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (h // 20 + 1, w // 20 + 1, 3), dtype=np.uint8)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC)


def write(path, rgb, **kw):
    Image.fromarray(rgb).save(path, **kw)
    return path


# ------------------------------------------------------------------------- truncation
@pytest.mark.parametrize("suffix, kind", [(".jpg", "truncated JPEG"), (".png", "truncated PNG")])
@pytest.mark.parametrize("keep", [0.3, 0.9, -2])
def test_a_truncated_photo_is_an_error_naming_the_file(tmp_path, suffix, kind, keep):
    good = write(tmp_path / f"good{suffix}", textured())
    data = good.read_bytes()
    cut = tmp_path / f"IMG_0007{suffix}"
    cut.write_bytes(data[: int(len(data) * keep)] if keep > 0 else data[:keep])  # -2: only the end marker lost
    with pytest.raises(PhotoError, match=rf"^IMG_0007{suffix}: {kind}"):
        read_photo(cut)
    assert read_photo(good).image.shape == (300, 400, 3)


def test_complete_files_with_extras_are_not_truncated(tmp_path):
    # a progressive JPEG (several scans), bytes appended after the end marker (as phones append a
    # second picture), a JPEG with EXIF, a PNG with trailing bytes
    img = textured()
    prog = write(tmp_path / "prog.jpg", img, progressive=True, quality=90)
    assert truncation_problem(prog.read_bytes()) is None
    tail = tmp_path / "tail.jpg"
    tail.write_bytes(prog.read_bytes() + b"\x00" * 100 + b"MPF junk")
    assert read_photo(tail).image.shape == (300, 400, 3)
    exif = Image.Exif()
    exif[TAG_ORIENTATION] = 1
    assert truncation_problem(write(tmp_path / "exif.jpg", img, exif=exif).read_bytes()) is None
    png = write(tmp_path / "p.png", img)
    png.write_bytes(png.read_bytes() + b"\n")
    np.testing.assert_array_equal(read_photo(png).image, img)


def test_other_damaged_files_are_errors_naming_the_file(tmp_path):
    cv2.imwrite(str(tmp_path / "a.bmp"), textured())
    data = (tmp_path / "a.bmp").read_bytes()
    (tmp_path / "cut.bmp").write_bytes(data[: len(data) // 2])
    with pytest.raises(PhotoError, match=r"^cut\.bmp: not an image this program can decode"):
        read_photo(tmp_path / "cut.bmp")
    (tmp_path / "notes.png").write_text("hello")
    with pytest.raises(PhotoError, match=r"^notes\.png: "):
        read_photo(tmp_path / "notes.png")
    with pytest.raises(PhotoError, match=r"^missing\.jpg: no such file"):
        read_photo(tmp_path / "missing.jpg")
    (tmp_path / "empty.jpg").write_bytes(b"")  # a copy that never started (OpenCV asserts on it)
    with pytest.raises(PhotoError, match=r"^empty\.jpg: the file is empty"):
        read_photo(tmp_path / "empty.jpg")


# ------------------------------------------------------------------------- orientation
@pytest.mark.parametrize("orientation, size", [(1, (400, 300)), (3, (400, 300)), (6, (300, 400)), (8, (300, 400))])
def test_exif_orientation_is_applied_and_gives_the_oriented_size(tmp_path, orientation, size):
    img = np.full((300, 400, 3), 40, np.uint8)
    img[:60, :80] = (250, 20, 20)  # a red block in the stored image's top-left corner
    exif = Image.Exif()
    exif[TAG_ORIENTATION] = orientation
    p = write(tmp_path / "rot.jpg", img, exif=exif, quality=95)
    with Image.open(p) as back:
        assert back.getexif()[TAG_ORIENTATION] == orientation  # the tag really is in the file
    photo = read_photo(p)
    assert (photo.width, photo.height) == size == photo_size(p)
    assert photo.image.shape[1::-1] == size and photo.scale == 1.0
    # where the red block lands: 6 = rotate 90° clockwise to display (top-left → top-right),
    # 8 = counter-clockwise (→ bottom-left), 3 = 180° (→ bottom-right)
    red = photo.image[..., 0] > 200
    ys, xs = np.nonzero(red)
    corner = (ys.mean() < size[1] / 2, xs.mean() < size[0] / 2)  # (top?, left?)
    assert corner == {1: (True, True), 3: (False, False), 6: (True, False), 8: (False, True)}[orientation]


def test_check_photos_compares_the_oriented_size_and_finds_a_truncated_photo(tmp_path):
    p = sample_project(tmp_path)
    save_project(p)
    write_photos(tmp_path, p)
    front = p.expression("neutral").photo("front")
    exif = Image.Exif()
    exif[TAG_ORIENTATION] = 6  # stored 48 x 64, shown 64 x 48: the project's size
    write(tmp_path / "rotated.jpg", np.zeros((front.width, front.height, 3), np.uint8), exif=exif)
    front.path = "rotated.jpg"
    p.check_photos(read_size=photo_size)
    data = (tmp_path / "rotated.jpg").read_bytes()
    (tmp_path / "rotated.jpg").write_bytes(data[:-10])
    with pytest.raises(ProjectError, match=r"photo 'front': rotated\.jpg could not be decoded: .*truncated JPEG"):
        p.check_photos(read_size=photo_size)


# ------------------------------------------------------------------------- large photos
def test_a_large_photo_is_read_at_a_working_resolution(tmp_path):
    img = np.zeros((400, 640, 3), np.uint8)
    img[198:203, 478:483] = 255  # a white dot centred on (480, 200) of the original
    p = write(tmp_path / "big.png", img)
    full = read_photo(p, max_side=None)
    assert not full.reduced and full.scale == 1.0
    work = read_photo(p, max_side=80)  # averaged down to 80 px across
    assert (work.width, work.height) == (640, 400)  # the original's size, what the project stores
    assert work.image.shape == (50, 80, 3) and work.reduced and work.scale == pytest.approx(80 / 640)
    ys, xs = np.nonzero(work.image[..., 0] > 10)
    w = work.image[ys, xs, 0].astype(float)
    centre = np.array([(xs * w).sum(), (ys * w).sum()]) / w.sum()
    # the dot maps back to where it is in the original, within half a working pixel (4 px)
    assert np.abs(to_original(centre, work.scale) - [480, 200]).max() < 4
    np.testing.assert_allclose(to_original(to_working([[480, 200]], 0.125), 0.125), [[480, 200]])
    jpg = write(tmp_path / "big.jpg", img, quality=95)  # JPEG: decoded at 1/2, 1/4 or 1/8 by libjpeg
    assert read_photo(jpg, max_side=170).image.shape == (100, 160, 3)  # /4: the smallest reduction that fits
    assert read_photo(jpg, max_side=70).image.shape == (44, 70, 3)  # even /8 is too big: resized to fit


# ------------------------------------------------------------------------- duplicates
def test_the_same_image_twice_is_found_and_different_views_are_not(tmp_path):
    img = textured()
    a = read_photo(write(tmp_path / "a.png", img)).image
    again = read_photo(write(tmp_path / "a_q75.jpg", img, quality=75)).image  # re-saved
    small = cv2.resize(img, (200, 150), interpolation=cv2.INTER_AREA)  # resized
    shifted = np.roll(img, 12, axis=1)  # the subject moved a little: another view
    other = textured(seed=1)
    prints = [fingerprint(x) for x in (a, again, small, shifted, other)]
    assert duplicate_pairs(prints) == [(0, 1), (0, 2), (1, 2)]
    assert duplicate_pairs(prints[:1]) == []


def test_photos_in_folder_and_camera_identity(tmp_path):
    for name in ("b.JPG", "a.png", "c.tiff", "notes.txt", ".hidden.jpg"):
        (tmp_path / name).write_bytes(b"x")
    (tmp_path / "sub.jpg").mkdir()
    assert [p.name for p in photos_in_folder(tmp_path)] == ["a.png", "b.JPG", "c.tiff"]
    for name in ("IMG_10.jpg", "img_9.JPG", "IMG_0011.jpg"):  # as a file browser orders them
        (tmp_path / name).write_bytes(b"x")
    assert [p.name for p in photos_in_folder(tmp_path)] == [
        "a.png",
        "b.JPG",
        "c.tiff",
        "img_9.JPG",
        "IMG_10.jpg",
        "IMG_0011.jpg",
    ]
    for name in ("IMG_10.jpg", "img_9.JPG", "IMG_0011.jpg"):
        (tmp_path / name).unlink()
    (tmp_path / "empty").mkdir()
    with pytest.raises(PhotoError, match="no photos in it"):
        photos_in_folder(tmp_path / "empty")
    with pytest.raises(PhotoError, match="no such folder"):
        photos_in_folder(tmp_path / "nowhere")
    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = "Canon", "Canon EOS R5"
    exif.get_ifd(EXIF_IFD)[TAG_FOCAL_LENGTH] = 50.0
    assert camera_identity(write(tmp_path / "cam.jpg", textured(), exif=exif)) == "Canon EOS R5 50 mm"
    assert camera_identity(write(tmp_path / "plain.jpg", textured())) is None


def test_webp_is_read_and_photos_of_unread_types_are_named(tmp_path):
    rgb = textured()
    write(tmp_path / "a.webp", rgb, quality=100)
    p = read_photo(tmp_path / "a.webp")
    assert (p.width, p.height) == (400, 300)
    assert np.abs(p.image.astype(int) - rgb).mean() < 3  # lossy WebP at quality 100: ~1 grey level
    data = (tmp_path / "a.webp").read_bytes()
    (tmp_path / "cut.webp.bin").write_bytes(data[: len(data) // 2])
    with pytest.raises(PhotoError, match="cut.webp.bin: not an image this program can decode"):
        read_photo(tmp_path / "cut.webp.bin")  # a WebP cut short: libwebp refuses it
    for name in ("IMG_2.HEIC", "IMG_1.heic", "DSC_1.NEF", "x.cr3", "anim.gif"):
        (tmp_path / name).write_bytes(b"x")
    assert [q.name for q in photos_in_folder(tmp_path)] == ["a.webp"]
    assert [q.name for q in unreadable_photos_in_folder(tmp_path)] == [
        "anim.gif",
        "DSC_1.NEF",
        "IMG_1.heic",
        "IMG_2.HEIC",
        "x.cr3",
    ]
    (tmp_path / "a.webp").unlink()
    with pytest.raises(
        PhotoError,
        match=r"no photos this program reads in it; anim.gif is not read \(GIF: convert it "
        r"to PNG\); DSC_1.NEF is not read \(NEF: a camera raw file",
    ):
        photos_in_folder(tmp_path)
    assert unreadable_photos_in_folder(tmp_path / "nowhere") == []
