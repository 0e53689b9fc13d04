"""The project loader against hostile files: the crashes of issue 14's table as regression tests,
then a few hundred seeded hypothesis mutants of the sample project (byte flips, truncation,
deleted/renamed keys, type swaps, huge and tiny numbers, deep nesting, bad references), each of
which must load (and then save and reload equal) or raise ProjectError; and benign mutants
(whitespace, key order, number formatting, BOM/CRLF) that must all load equal to the original.
``benchmarks/bench_fuzz.py`` runs 10 000 of the same."""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from photomodel.errors import ProjectError
from photomodel.project import load_project, save_project
from photomodel.project.codec import project_from_dict
from photomodel.samples.project_mutants import (
    MUTATIONS,
    benign_mutants,
    check_mutant,
    dump,
    fuzz_base,
    mutants,
    raw,
    replaced,
)

SAMPLE = Path(__file__).resolve().parents[1] / "sample_projects" / "james" / "james.facestudio.json"
#: Mutants per kind and run: 9 kinds x 25 = 225 (about 20 s); the benchmark runs 10 000.
PER_KIND = 25
_SETTINGS = settings(
    max_examples=PER_KIND, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck)
)


@functools.cache
def base():
    return fuzz_base(SAMPLE, photos_per_expression=2)


def _load(tmp_path, text) -> object:
    path = tmp_path / "m.facestudio.json"
    path.write_text(text, encoding="utf-8")
    return load_project(path)


def _mutant(path: tuple, value) -> str:
    return dump(replaced(base().tree, path, lambda node: value))


RESULT = ("expressions", 0, "result")
PHOTO = ("expressions", 0, "photos", 0)
HUGE_INT = raw("1" + "0" * 400)


# ---------------------------------------------------------------------------------------
# the table
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("depth", [65, 1000, 5000, 200_000])
@pytest.mark.parametrize("where", [("name",), RESULT + ("report",), PHOTO + ("points",)])
def test_deep_nesting_is_a_project_error(tmp_path, depth, where):
    text = _mutant(where, raw("[" * depth + "]" * depth))
    with pytest.raises(ProjectError, match="nested too deeply"):
        _load(tmp_path, text)


def test_nesting_within_the_limit_in_a_report_loads(tmp_path):
    text = _mutant(RESULT + ("report", "deep"), raw("[" * 40 + "]" * 40))
    deep = _load(tmp_path, text).expressions[0].result.report["deep"]
    for _ in range(39):
        deep = deep[0]
    assert deep == []


def test_deep_dict_given_to_from_dict_is_a_project_error():
    deep: dict = {}
    node = deep
    for _ in range(3000):
        node["a"] = {}
        node = node["a"]
    d = replaced(base().tree, RESULT + ("report",), lambda r: deep)
    with pytest.raises(ProjectError, match="nested too deeply"):
        project_from_dict(d)


def _first_click(tree) -> str:
    return next(iter(tree["expressions"][0]["photos"][0]["points"]))


@pytest.mark.parametrize("what", ["click", "curve point", "points_3d"])
def test_integer_too_large_for_a_float_is_a_project_error(tmp_path, what):
    tree = base().tree
    photo = tree["expressions"][0]["photos"][0]
    path = {
        "click": PHOTO + ("points", _first_click(tree), 0),
        "curve point": PHOTO + ("curves", next(iter(photo["curves"])), 1, 0),
        "points_3d": RESULT + ("points_3d", next(iter(tree["expressions"][0]["result"]["points_3d"])), 2),
    }[what]
    with pytest.raises(ProjectError, match="not a finite number: too large for a double") as ei:
        _load(tmp_path, _mutant(path, HUGE_INT))
    assert path[2 if what == "points_3d" else 4] in str(ei.value)  # the field is named


@pytest.mark.parametrize("vertex", [10**30, 2**63, 2**31])
def test_curve_vertex_too_large_is_a_project_error(tmp_path, vertex):
    with pytest.raises(ProjectError, match=r"curves\[0\]\.vertices\[0\]: expected a generic-mesh vertex index"):
        _load(tmp_path, _mutant(("curves", 0, "vertices", 0), vertex))


@pytest.mark.parametrize("value", [-1e308, 1.7976931348623157e308, 1e300, -(2.0**60) + 0.5])
def test_huge_points_3d_load_and_save_exactly(tmp_path, value):
    name = next(iter(base().tree["expressions"][0]["result"]["points_3d"]))
    project = _load(tmp_path, _mutant(RESULT + ("points_3d", name, 0), value))
    saved = load_project(save_project(project, tmp_path / "saved.facestudio.json"))
    assert saved.expressions[0].result.points_3d[name][0] == value  # kept, not rounded to -inf


def test_sample_project_itself_round_trips(tmp_path):
    assert check_mutant(base().text, tmp_path) == "loaded"


# ---------------------------------------------------------------------------------------
# hypothesis: harmful and benign mutants
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", MUTATIONS)
def test_every_mutant_loads_or_is_a_project_error(kind):
    with tempfile.TemporaryDirectory() as folder:

        @_SETTINGS
        @given(mutants(base(), kind))
        def check(data):
            assert check_mutant(data, Path(folder)) in ("loaded", "project_error")

        check()


@pytest.fixture(scope="module")
def original(tmp_path_factory):
    path = tmp_path_factory.mktemp("original") / "o.facestudio.json"
    path.write_text(base().text, encoding="utf-8")
    return load_project(path)


@settings(max_examples=30, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_benign_mutants_load_equal(original, data):
    kind, text = data.draw(benign_mutants(base()))
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "o.facestudio.json"
        path.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
        assert load_project(path) == original, kind
