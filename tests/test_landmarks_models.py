"""The MediaPipe model files: fetched by package name, checked, cached (install.sh fetches them)."""

import pytest

from photomodel.data.fetch import package_files, sha256_of
from photomodel.errors import SampleDataError
from photomodel.landmarks.models import DETECTION_MODEL, LANDMARK_MODEL, MEDIAPIPE, model_dir


def test_models_in_the_cache_match_their_checksums():
    folder = model_dir()
    for name in (LANDMARK_MODEL, DETECTION_MODEL, "LICENSE"):
        assert sha256_of(folder / name) == MEDIAPIPE.members[name][1]
    assert "Apache License" in (folder / "LICENSE").read_text()  # the licence we ship under


def test_a_missing_local_wheel_is_an_error_that_says_what_to_do(tmp_path, monkeypatch):
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path))
    monkeypatch.setenv(MEDIAPIPE.env_archive, str(tmp_path / "nowhere.whl"))
    with pytest.raises(SampleDataError, match="is not a file.*To fix"):
        package_files(MEDIAPIPE)


def test_a_corrupt_cached_file_is_fetched_again_from_a_local_wheel(tmp_path, monkeypatch):
    """A damaged cache copy is replaced, never used: the local-wheel path (offline installs)."""
    good = model_dir()
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path))
    folder = MEDIAPIPE.folder
    folder.mkdir(parents=True)
    (folder / LANDMARK_MODEL).write_bytes(b"not a model")
    wheel = tmp_path / MEDIAPIPE.archive_name
    wheel.write_bytes(b"not a wheel either")
    monkeypatch.setenv(MEDIAPIPE.env_archive, str(wheel))
    with pytest.raises(SampleDataError, match="SHA-256"):
        package_files(MEDIAPIPE)
    assert good.is_dir()
