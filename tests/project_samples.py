"""A small valid project for the tests of photomodel/project/ (tests/test_project_*.py).

Click values have ≤3 decimals and result values ≤4 so that the file's rounding (1e-3 px, 1e-4 mm)
is exact and round trips can be compared with ==.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from photomodel.camera import orbit_camera
from photomodel.project import (
    CurveDef,
    Expression,
    ExpressionResult,
    Feature,
    Photo,
    Project,
    TextureResult,
    load_project,
    save_project,
)

W, H = 64, 48  # small photos keep the image-reading tests fast


def sample_camera(azimuth_deg: float):
    cam = orbit_camera(azimuth_deg, W, H)
    cam.f = 90.0  # orbit_camera's focal (50 mm → 88.88… px) is not exact at the stored 1e-6 px
    return cam


def sample_project(tmp_path: Path | None = None, *, with_result: bool = True) -> Project:
    """A two-expression project; click values have ≤3 decimals and result values ≤4 so that the
    file's rounding (1e-3 px, 1e-4 mm) is exact and round trips can be compared with ==."""
    features = [Feature("nose_tip", 10, True), Feature("eye_l", 20, True), Feature("jaw_00", 30, False)]
    curves = [CurveDef("brow_r", [1, 2, 3]), CurveDef("lip_top", [4, 5])]
    front = Photo(
        "front",
        "photos/neutral_front.png",
        W,
        H,
        "front",
        50.0,
        points={"nose_tip": [31.5, 20.25], "eye_l": [40.125, 12.0], "jaw_00": [30.0, 47.0]},
        hidden={"jaw_00"},
        curves={"brow_r": [[10.0, 8.5], [14.0, 7.0], [18.25, 8.0]]},
    )
    left = Photo(
        "left", "photos/neutral_left.png", W, H, "left", points={"nose_tip": [12.0, 22.0], "eye_l": [-3.5, 13.0]}
    )  # slightly outside: allowed
    smile = Photo("front", "photos/smile_front.png", W, H, "three_quarter_right", points={"nose_tip": [30, 21]})
    result = None
    if with_result:
        result = ExpressionResult(
            cameras={"front": sample_camera(0.0), "left": sample_camera(90.0)},
            points_3d={"nose_tip": [0.0, -1.5, 102.25], "eye_l": [33.1234, 30.0, 60.0]},
            mesh_obj="results/neutral.obj",
            mesh_ply="results/neutral.ply",
            report={"rms_px": 0.75, "per_view": {"front": 0.5, "left": 1.0}, "iterations": 12},
        )
    p = Project(
        "james",
        features=features,
        curves=curves,
        expressions=[Expression("neutral", [front, left], result), Expression("smile", [smile])],
    )
    if tmp_path is not None:
        p.path = tmp_path / "james.facestudio.json"
    return p


def write_photos(folder: Path, project: Project) -> None:
    for e in project.expressions:
        for ph in e.photos:
            f = folder / ph.path
            f.parent.mkdir(parents=True, exist_ok=True)
            cv2.imwrite(str(f), np.full((ph.height, ph.width, 3), 128, np.uint8))


def save_sample(tmp_path: Path) -> tuple[Path, dict]:
    """(path, dict) of a valid saved project with its photos on disk."""
    p = sample_project()
    path = save_project(p, tmp_path / "james.facestudio.json")
    write_photos(tmp_path, p)
    return path, json.loads(path.read_text())


def load_text(tmp_path: Path, text: str) -> Project:
    f = tmp_path / "james.facestudio.json"
    f.write_text(text)
    return load_project(f)


def load_dict(tmp_path: Path, d: dict) -> Project:
    return load_text(tmp_path, json.dumps(d, indent=1))


def photo_dict(d, e=0, i=0):
    return d["expressions"][e]["photos"][i]


def temp_files(folder: Path) -> list[str]:
    return sorted(f.name for f in folder.iterdir() if f.name.endswith(".tmp"))


def textured_project(tmp_path: Path) -> Project:
    p = sample_project(tmp_path)
    p.expression("neutral").result.texture = TextureResult(
        size=512,
        image="results/neutral_texture.png",
        weight_maps={"left": "results/neutral_weights_left.png", "front": "results/neutral_weights_front.png"},
        exports={
            "obj": "results/neutral_textured.obj",
            "glb": "results/neutral.glb",
            "ply": "results/neutral_colors.ply",
        },
        report={"coverage": 0.97, "extract_s": 0.5},
    )
    return p
