"""Tests of photomodel.data.cache and photomodel.data.arrays: the cache folder, derived results kept
under their key (built only on a miss), the few most recently used kept, array files written whole."""

from __future__ import annotations

import os

import numpy as np
import pytest

from photomodel.data import cache
from photomodel.data.arrays import load_npz, save_npz
from photomodel.data.cache import cached_arrays, cached_folder


def test_cache_folder_follows_environment(monkeypatch, tmp_path):
    monkeypatch.delenv("FACESTUDIO_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "xdg" / "facestudio"
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path / "mine"))
    assert cache.cache_dir() == tmp_path / "mine"


def test_array_files_round_trip_and_unreadable_ones_read_as_missing(tmp_path):
    arrays = {"a": np.arange(5.0), "b": np.array([[1, 2]], np.int64)}
    save_npz(tmp_path / "x.npz", arrays)
    back = load_npz(tmp_path / "x.npz")
    assert back.keys() == arrays.keys() and all(np.array_equal(back[k], arrays[k]) for k in arrays)
    assert [p.name for p in tmp_path.iterdir()] == ["x.npz"]  # no temporary left over
    assert load_npz(tmp_path / "missing.npz") is None
    (tmp_path / "torn.npz").write_bytes((tmp_path / "x.npz").read_bytes()[:100])
    assert load_npz(tmp_path / "torn.npz") is None
    np.savez(tmp_path / "other.npz", a=np.arange(3))  # no layout marker: not one of ours
    assert load_npz(tmp_path / "other.npz") is None
    with pytest.raises(ValueError, match="format"):
        save_npz(tmp_path / "y.npz", {"format": np.zeros(1)})


def test_a_result_is_built_once_per_key(tmp_path, monkeypatch):
    monkeypatch.setenv("FACESTUDIO_CACHE", str(tmp_path))
    calls = []

    def build():
        calls.append(1)
        return {"v": np.full(3, len(calls))}

    first = cached_arrays("thing", "k1", build)
    again = cached_arrays("thing", "k1", build)
    assert len(calls) == 1 and np.array_equal(first["v"], again["v"])
    other = cached_arrays("thing", "k2", build)  # other code or inputs: built again
    assert len(calls) == 2 and other["v"][0] == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["thing-k1.npz", "thing-k2.npz"]


def test_only_the_most_recently_used_entries_stay(tmp_path):
    for i, key in enumerate(["old", "legacy", "used", "newer"]):
        cached_arrays("thing", key, lambda: {"v": np.zeros(1)}, folder=tmp_path)
        os.utime(tmp_path / f"thing-{key}.npz", (1000 + i, 1000 + i))
    (tmp_path / "thing.npz").write_bytes(b"an earlier scheme's file")
    (tmp_path / "unrelated-x.npz").write_bytes(b"another family")
    cached_arrays("thing", "used", lambda: {"v": np.zeros(1)}, folder=tmp_path)  # a hit marks it used
    cached_arrays("thing", "new", lambda: {"v": np.zeros(1)}, folder=tmp_path, legacy=("thing.npz",))
    left = sorted(p.name for p in tmp_path.iterdir())
    assert left == ["thing-new.npz", "thing-newer.npz", "thing-used.npz", "unrelated-x.npz"]
    assert cache.KEEP == 3


def test_a_folder_is_made_whole_or_not_at_all(tmp_path):
    def build(folder):
        (folder / "a.txt").write_text("a")

    made = cached_folder(tmp_path / "family", "k1", build)
    assert made == tmp_path / "family" / "k1" and (made / "a.txt").read_text() == "a"
    assert cached_folder(tmp_path / "family", "k1", lambda folder: pytest.fail("built twice")) == made

    def broken(folder):
        (folder / "half.txt").write_text("half")
        raise RuntimeError("the builder failed")

    with pytest.raises(RuntimeError, match="builder failed"):
        cached_folder(tmp_path / "family", "k2", broken)
    assert sorted(p.name for p in (tmp_path / "family").iterdir()) == ["k1"]  # nothing half-made left
