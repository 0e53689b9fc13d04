"""Mutated project files for the loader's fuzz test and benchmark (`hypothesis` strategies).

The base is the sample project (``sample_projects/james``) with a fitted-looking result and a
texture added to its first expression (:func:`fuzz_base`), so that every part of the format is
mutated. :func:`mutants` draws harmful mutants — byte flips, truncation, deleted and renamed
keys, type swaps, huge and tiny numbers (integers beyond a double, 1e308, denormals), deep
nesting, broken references — each of which must either load or raise
:class:`~photomodel.errors.ProjectError`; :func:`benign_mutants` draws the same project written
differently (whitespace, key order, number formatting, a BOM, CRLF), which must load equal to
the original. :func:`check_mutant` is the property both the test and the benchmark check.

`hypothesis` is used rather than a hand-rolled generator: it is a kept library for exactly this
(seeded, reproducible draws; a failing mutant shrinks to a small one in the test suite).
"""

from __future__ import annotations

import copy
import json
import math
import random
from dataclasses import dataclass, field
from decimal import Decimal
from functools import cached_property
from pathlib import Path

from hypothesis import strategies as st

from photomodel.camera import preset_camera
from photomodel.errors import ProjectError
from photomodel.project import load_project, save_project
from photomodel.project.codec import project_to_dict

#: Numbers a mutant puts in place of a number: huge, tiny, negative, not quite integers. Strings
#: are JSON literals written as they are (``1e400`` cannot be a Python float).
EXTREME_NUMBERS = (
    "1" + "0" * 400,
    "-1" + "0" * 400,
    "1e400",
    "-1e400",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "5e-324",
    "-5e-324",
    "1e-300",
    "0",
    "-0.0",
    "1" + "0" * 30,
    "9223372036854775808",
    "-9223372036854775809",
    "4294967296",
    "2147483648",
    "-1",
    "0.5",
    "1e20",
    "123456789.123456789",
)
#: How deep a mutant nests lists or objects.
DEPTHS = (8, 40, 63, 64, 65, 100, 999, 1000, 5000, 100_000)
_RAW = "\u0001raw:"  # marks a string that is written as a raw JSON literal


@dataclass
class FuzzBase:
    """The project that mutants are made of: its JSON text, its parsed tree and where things are.

    Attributes
    ----------
    tree : dict, the parsed project.
    text : str, ``tree`` as written by Face Studio.
    """

    tree: dict
    text: str = field(init=False)

    def __post_init__(self):
        self.text = json.dumps(self.tree, indent=2, ensure_ascii=False)

    @cached_property
    def paths(self) -> list[tuple]:
        """Every node's path (root excluded), in document order."""
        out: list[tuple] = []
        stack = [((), self.tree)]
        while stack:
            path, node = stack.pop()
            if path:
                out.append(path)
            items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
            stack.extend(((*path, k), v) for k, v in items)
        return out

    @cached_property
    def number_paths(self) -> list[tuple]:
        return [p for p in self.paths if _is_number(get(self.tree, p))]

    @cached_property
    def key_paths(self) -> list[tuple]:
        """Paths of object members (their last step is a key)."""
        return [p for p in self.paths if isinstance(p[-1], str)]

    @cached_property
    def name_references(self) -> list[tuple]:
        """Paths of the keys and strings that name a feature, curve, photo or expression."""
        refs = ("points", "hidden", "curves", "points_3d", "cameras", "weight_maps", "click_sources")
        return [p for p in self.paths if len(p) >= 2 and (p[-2] in refs or p[-1] in ("name", "id", "cameras_from"))]


def _is_number(v) -> bool:
    return type(v) in (int, float)


def get(tree, path: tuple):
    """The node at ``path`` of a JSON tree."""
    for k in path:
        tree = tree[k]
    return tree


def replaced(tree, path: tuple, fn):
    """A copy of ``tree`` with the node at ``path`` replaced by ``fn(node)`` (``fn`` returns
    :data:`DELETE` to remove it); only the containers along ``path`` are copied."""
    if not path:
        return fn(tree)
    head, rest = path[0], path[1:]
    out = copy.copy(tree)
    new = replaced(tree.get(head) if isinstance(tree, dict) else tree[head], rest, fn)
    if new is DELETE:
        del out[head]
    else:
        out[head] = new
    return out


DELETE = object()


def fuzz_base(sample: str | Path, photos_per_expression: int | None = None) -> FuzzBase:
    """The sample project file at ``sample``, its first expression given a result (a camera per
    photo, 3-D points, mesh files, a report) and a texture, as the base of the mutants.

    ``photos_per_expression`` keeps only the first photos of each expression: every field of
    the format is still there, and a mutant loads in a third of the time."""
    tree = json.loads(Path(sample).read_text(encoding="utf-8"))
    for e in tree["expressions"]:
        e["photos"] = e["photos"][:photos_per_expression]
    expr = tree["expressions"][0]
    cams = {}
    for p in expr["photos"]:
        cam = preset_camera(p["preset"], p["width"], p["height"])
        cams[p["id"]] = {
            "rotation": cam.R.tolist(),
            "translation_mm": cam.t.tolist(),
            "focal_px": cam.f,
            "width": p["width"],
            "height": p["height"],
        }
    names = [f["name"] for f in tree["features"]][:20]
    stem = "results/" + expr["name"]
    expr["result"] = {
        "cameras": cams,
        "points_3d": {n: [float(i), -2.5 * i, 80.125 - i] for i, n in enumerate(names)},
        "mesh_obj": stem + ".obj",
        "mesh_ply": stem + ".ply",
        "report": {
            "rms_px": 0.82,
            "views": [{"photo": p["id"], "rms_px": 0.5} for p in expr["photos"]],
            "pose": {"rms_px": 0.7, "sweeps": 3},
        },
        "texture": {
            "size": 256,
            "image": stem + "_texture.png",
            "weight_maps": {p["id"]: f"{stem}_weights_{p['id']}.png" for p in expr["photos"]},
            "exports": {"obj": stem + "_textured.obj", "glb": stem + ".glb", "ply": stem + "_colors.ply"},
            "report": {"coverage": 0.9, "cylinder": {"centre": [0.0, 1.0, 2.0], "theta_cut": 3.14}},
        },
    }
    expr["photos"][0]["click_sources"] = {
        n: {"source": "auto", "confidence": 0.5} for n in list(expr["photos"][0]["points"])[:3]
    }
    return FuzzBase(tree)


# ---------------------------------------------------------------------------------------
# harmful mutants
# ---------------------------------------------------------------------------------------
def dump(tree) -> str:
    """JSON text of a mutated tree; strings made by :func:`raw` become raw literals."""
    text = json.dumps(tree, ensure_ascii=False)  # the C encoder: indent=… is ~10x slower
    marker = json.dumps(_RAW)[1:-1]
    if marker not in text:
        return text
    parts = text.split('"' + marker)
    return parts[0] + "".join(p.replace('"', "", 1) for p in parts[1:])


def raw(literal: str) -> str:
    """A string that :func:`dump` writes as the raw JSON literal ``literal`` (e.g. ``1e400``)."""
    return _RAW + literal


def _nested_text(depth: int, kind: str) -> str:
    """``depth`` lists (or objects) inside each other, as JSON text (json.dumps would recurse)."""
    if kind == "list":
        return "[" * depth + "]" * depth
    return '{"a": ' * depth + "null" + "}" * depth


_OTHER_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-5, 5),
    st.floats(allow_nan=False, allow_infinity=False),
    st.text(max_size=8),
    st.sampled_from([[], {}, [1.0], {"x": 1}, [[1.0, 2.0], [3.0]], [0, 1], ["a", "b"]]),
)


@st.composite
def _byte_flips(draw, base: FuzzBase):
    data = bytearray(base.text.encode("utf-8"))
    for _ in range(draw(st.integers(1, 4))):
        data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
    return bytes(data)


@st.composite
def _truncated(draw, base: FuzzBase):
    data = base.text.encode("utf-8")
    return data[: draw(st.integers(0, len(data) - 1))]


@st.composite
def _deleted_key(draw, base: FuzzBase):
    path = draw(st.sampled_from(base.key_paths))
    return dump(replaced(base.tree, path, lambda node: DELETE))


@st.composite
def _renamed_key(draw, base: FuzzBase):
    path = draw(st.sampled_from(base.key_paths))
    key = path[-1]
    new = draw(
        st.sampled_from(
            [
                key[:-1],
                key + "s",
                key.upper(),
                "",
                " " + key,
                "pionts",
                "x" * 300,
                "\u00e9" + key,
                "name",
                "id",
                "result",
                "nose_tip",
            ]
        )
    )
    return dump(replaced(base.tree, path[:-1], lambda d: {(new if k == key else k): v for k, v in d.items()}))


@st.composite
def _type_swap(draw, base: FuzzBase):
    path = draw(st.sampled_from(base.paths))
    value = draw(_OTHER_VALUES)
    return dump(replaced(base.tree, path, lambda node: value))


@st.composite
def _extreme_number(draw, base: FuzzBase):
    tree = base.tree
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(base.number_paths))
        literal = draw(st.sampled_from(EXTREME_NUMBERS))
        tree = replaced(tree, path, lambda node, lit=literal: raw(lit))
    return dump(tree)


@st.composite
def _deep(draw, base: FuzzBase):
    path = draw(st.sampled_from(base.paths))
    text = dump(replaced(base.tree, path, lambda node: raw("\u0002deep")))
    inner = _nested_text(draw(st.sampled_from(DEPTHS)), draw(st.sampled_from(["list", "dict"])))
    return text.replace("\u0002deep", inner, 1)


@st.composite
def _bad_reference(draw, base: FuzzBase):
    path = draw(st.sampled_from(base.name_references))
    other = draw(
        st.sampled_from(
            [get(base.tree, p) for p in base.name_references[:400] if isinstance(get(base.tree, p), str)]
            + ["nosuch", "", "neutral"]
        )
    )
    if isinstance(path[-1], str) and path[-1] not in ("name", "id", "cameras_from"):
        key = path[-1]  # a map keyed by a name: rename the key
        return dump(replaced(base.tree, path[:-1], lambda d: {(other if k == key else k): v for k, v in d.items()}))
    return dump(replaced(base.tree, path, lambda node: other))


@st.composite
def _cameras_cycle(draw, base: FuzzBase):
    names = [e["name"] for e in base.tree["expressions"]]
    a, b = draw(st.permutations(names))[:2]
    tree = replaced(
        base.tree,
        ("expressions",),
        lambda es: [
            {**e, "cameras_from": (b if e["name"] == a else a if e["name"] == b else e.get("cameras_from"))}
            if e["name"] in (a, b)
            else e
            for e in es
        ],
    )
    return dump(tree)


MUTATIONS = (
    "byte_flips",
    "truncated",
    "deleted_key",
    "renamed_key",
    "type_swap",
    "extreme_number",
    "deep",
    "bad_reference",
    "cameras_cycle",
)


def mutants(base: FuzzBase, kind: str):
    """Strategy: the text (or bytes) of a harmful mutant of ``base`` of one of :data:`MUTATIONS`
    (drawn per kind, so that each kind gets its share: hypothesis favours a ``one_of``'s first
    branches)."""
    makers = {
        "byte_flips": _byte_flips,
        "truncated": _truncated,
        "deleted_key": _deleted_key,
        "renamed_key": _renamed_key,
        "type_swap": _type_swap,
        "extreme_number": _extreme_number,
        "deep": _deep,
        "bad_reference": _bad_reference,
        "cameras_cycle": _cameras_cycle,
    }
    return makers[kind](base)


# ---------------------------------------------------------------------------------------
# benign mutants
# ---------------------------------------------------------------------------------------
def _shuffled(node, rng: random.Random):
    if isinstance(node, dict):
        items = list(node.items())
        rng.shuffle(items)
        return {k: _shuffled(v, rng) for k, v in items}
    if isinstance(node, list):
        return [_shuffled(v, rng) for v in node]
    return node


def _reformatted_number(x: float, k: int, style: int) -> str:
    """The float ``x`` written another way that reads back as the same double: the decimal point
    moved by ``k`` digits with an exponent to match (``12.5`` → ``0.00125e4``, ``12500E-3``), or
    trailing zeros."""
    d = Decimal(repr(x))
    if style == 0:
        return f"{d.scaleb(-k):f}e{k}"
    if style == 1:
        return f"{d.scaleb(k):f}E-{k}"
    return f"{d:f}" + ("" if "." not in f"{d:f}" else "0" * k)


@st.composite
def benign_mutants(draw, base: FuzzBase):
    """Strategy: ``(kind, text)``: the base project written differently — whitespace, key
    order, number formatting, a BOM or CRLF line ends — which must load equal to it."""
    kind = draw(st.sampled_from(["whitespace", "key_order", "numbers", "bom_crlf"]))
    tree = base.tree
    if kind == "key_order":
        tree = _shuffled(tree, random.Random(draw(st.integers(0, 2**32 - 1))))
    if kind == "numbers":
        rng = random.Random(draw(st.integers(0, 2**32 - 1)))
        floats = [p for p in base.number_paths if type(get(tree, p)) is float]
        for p in rng.sample(floats, min(len(floats), draw(st.integers(1, 200)))):
            literal = _reformatted_number(get(tree, p), rng.randint(1, 5), rng.randint(0, 2))
            tree = replaced(tree, p, lambda node, lit=literal: raw(lit))
    if kind == "whitespace":
        indent = draw(st.sampled_from([None, 0, 1, 4, "\t"]))
        sep = draw(st.sampled_from([(",", ":"), (", ", ": "), (" ,\n", " :  ")]))
        text = json.dumps(tree, indent=indent, separators=sep, ensure_ascii=draw(st.booleans()))
        return kind, draw(st.sampled_from(["", " ", "\n", "\t\r\n"])) + text + draw(st.sampled_from(["", "\n", " \n "]))
    text = dump(tree)
    if kind == "bom_crlf":
        return kind, ("\ufeff" + text.replace("\n", "\r\n")).encode("utf-8")
    return kind, text


# ---------------------------------------------------------------------------------------
# the property
# ---------------------------------------------------------------------------------------
def check_mutant(data: str | bytes, folder: Path) -> str:
    """Load the mutant ``data`` from ``folder``: ``"project_error"`` if it is refused with a
    :class:`ProjectError`, ``"loaded"`` if it loads, saves and reloads equal (saving twice gives
    the same bytes). Any other exception propagates; AssertionError if the round trip differs."""
    path = Path(folder) / "mutant.facestudio.json"
    path.write_bytes(data.encode("utf-8") if isinstance(data, str) else data)
    try:
        project = load_project(path)
    except ProjectError:
        return "project_error"
    first = save_project(project, Path(folder) / "saved.facestudio.json").read_bytes()
    again = load_project(Path(folder) / "saved.facestudio.json")
    second = save_project(again, Path(folder) / "again.facestudio.json").read_bytes()
    assert first == second, "saving a reloaded mutant gave other bytes"
    assert _same(project_to_dict(again, None), project_to_dict(project, None)), "the reloaded project differs"
    return "loaded"


def _same(a, b) -> bool:
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-9)  # rounding twice may move the last bit
    return a == b
