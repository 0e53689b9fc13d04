"""Runs inside Blender's Python (``bpy``), not the project's: a glb imported as an artist imports it, read back.

    <blender-venv>/bin/python benchmarks/blender_glb_report.py -- FILE.glb NAMES.json OUT.json

``benchmarks/bench_blender.py`` runs it in its own virtual environment (``bpy`` from PyPI, pinned in
``benchmarks/blender-requirements.txt``). The glb is imported into an empty scene with
``bpy.ops.import_scene.gltf`` (Blender's own glTF add-on, default options); then, as an artist
would look: each mesh's shape keys (``key_blocks``, the reference key ``Basis`` left out), every
action and its fcurves (``data_path`` such as ``key_blocks["jawOpen"].value``), the keyframes per
channel, and — stepping the scene through every frame of the shape keys' action
(``scene.frame_set``) — each named shape key's value on every frame (what the shape-key panel
shows), its minimum and maximum. ``NAMES.json`` is a list of the ARKit shape names to look at.
Writes one JSON object to ``OUT.json`` (Blender prints its own log on stdout) and exits at once
(``os._exit``: bpy's teardown at interpreter exit can crash).
"""

import json
import os
import sys

import bpy

#: A channel counts as moving when its value in Blender varies by more than this over the frames
#: (as ``tracking.auto_pipeline.glb_summary`` counts the glb's own channels).
MOVING = 0.05


def shape_key_meshes():
    """The mesh objects with shape keys beyond the reference one."""
    return [ob for ob in bpy.data.objects if ob.type == "MESH" and ob.data.shape_keys is not None]


def frame_steps(actions):
    """The whole frames the shape-key actions span: from the one nearest the first keyframe to the
    one nearest the last (a clip's frame times fall between Blender's frames when its rate is not
    the scene's, e.g. 23.976 against 24 frames/s)."""
    lo = min(a.frame_range[0] for a in actions)
    hi = max(a.frame_range[1] for a in actions)
    return list(range(round(lo), round(hi) + 1))


def report(glb, arkit):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if bpy.ops.import_scene.gltf(filepath=glb) != {"FINISHED"}:
        raise SystemExit(f"Blender did not import {glb}")
    meshes = shape_key_meshes()
    blocks = {kb.name: kb for ob in meshes for kb in ob.data.shape_keys.key_blocks[1:]}
    key_actions = [
        ob.data.shape_keys.animation_data.action
        for ob in meshes
        if ob.data.shape_keys.animation_data is not None and ob.data.shape_keys.animation_data.action is not None
    ]
    actions = {
        a.name: {"fcurves": len(a.fcurves), "data_paths": [f.data_path for f in a.fcurves], "users": a.users}
        for a in bpy.data.actions
    }
    curves = [f for a in key_actions for f in a.fcurves]
    keys_per_channel = sorted({len(f.keyframe_points) for f in curves})
    names = [n for n in arkit if n in blocks]
    frames = frame_steps(key_actions) if key_actions else []
    scene = bpy.context.scene
    values = {n: [] for n in names}
    for f in frames:
        scene.frame_set(f)
        for n in names:
            values[n].append(blocks[n].value)
    lo = {n: min(v) if v else 0.0 for n, v in values.items()}
    hi = {n: max(v) if v else 0.0 for n, v in values.items()}
    return {
        "version": bpy.app.version_string,
        "shape_keys": len(blocks),
        "arkit_keys": len(names),
        "actions": len(actions),
        "shape_key_actions": len(key_actions),
        "frames": len(frames),
        "arkit_keys_moving": sum(hi[n] - lo[n] > MOVING for n in names),
        "jawOpen_max": hi.get("jawOpen", 0.0),
        "keys_per_channel": keys_per_channel[-1] if keys_per_channel else 0,
        "fcurves_on_shape_keys": sum(f.data_path.startswith("key_blocks[") for f in curves),
        "cameras": sum(ob.type == "CAMERA" for ob in bpy.data.objects),
        "fps": scene.render.fps / scene.render.fps_base,
        "action_names": actions,
        "arkit_min": lo,
        "arkit_max": hi,
    }


def main():
    glb, names_json, out = sys.argv[sys.argv.index("--") + 1 :][:3]
    with open(names_json) as fh:
        arkit = json.load(fh)
    result = report(glb, arkit)
    with open(out, "w") as fh:
        json.dump(result, fh)
        fh.flush()
    # bpy 4.2 as a module can crash in its own teardown at interpreter exit (a segfault after the work
    # is done): leave at once, the report written
    os._exit(0)


if __name__ == "__main__":
    main()
