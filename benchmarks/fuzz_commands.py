"""The command section of ``benchmarks/bench_fuzz.py``: every ``facestudio`` command × five kinds of bad input.

    .venv/bin/python benchmarks/bench_fuzz.py --only commands [--json]

Each case runs the command in a process of its own (as a user runs it) on a fresh copy of the
fitted sample project, and is one of

* ``read_only`` — the folder it writes to is read-only (a read-only bind mount as root, where
  ``mount`` is allowed; else the folder's write permission removed; the case is left out where
  neither works);
* ``missing_input`` — the project (or the photos, the track) does not exist;
* ``wrong_size_photo`` — a photo of the project (or of the folder given) replaced by a 1×1 image;
* ``unknown_name`` — an expression name the project does not have (``--expression``,
  ``--expressions``, ``--scale``, ``--neutral``), where the command takes one;
* ``odd_path`` — every path under a folder whose name has spaces and non-Latin letters
  (``my prôjects/Зоя 张``): this one must succeed.

A case passes when the command either succeeds (exit 0, and for ``odd_path`` it must) or fails with
exit status 2 and the path or name at fault in its message; never a traceback, and a failed case
leaves the case's folder as it was (no partial output). The section's keys: ``cases``,
``tracebacks``, ``partial_outputs``, ``unnamed`` (failures whose message names neither),
``exit_codes`` ({code: cases}), ``failures`` (the cases that missed a bar, with the end of their
stderr) and ``seconds``. ``studio`` runs offscreen and quits after a few seconds.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "sample_projects" / "james"
VIDEO = SAMPLE / "video" / "james_track.mp4"
ODD = "my prôjects/Зоя 张"
#: A case running longer than this is a failure (hung).
CASE_TIMEOUT_S = 600
#: The studio is quit after this long (it opened, or showed its error).
STUDIO_S = 6

#: command → its arguments that succeed: {p} project, {o} output folder, {t} track folder, {photos} a photo folder.
COMMANDS = {
    "new": ["new", "{o}/n.facestudio.json", "--photos", "{photos}"],
    "add-photos": ["add-photos", "{p}", "--photos", "{photos}", "--expression", "extra"],
    "fit": ["fit", "{p}", "--expression", "neutral", "--no-refine"],
    "texture": ["texture", "{p}", "--expression", "neutral", "--size", "64"],
    "track": ["track", "{p}", "--video", "{video}", "--out", "{o}/t", "--frames", "2", "--no-overlay"],
    "track-many": ["track-many", "{p}", "{video}", "--out", "{o}", "--frames", "1", "--no-overlay", "--workers", "1"],
    "edit": ["edit", "{p}", "--track", "{t}", "--scale", "smile=0.5", "--no-smooth", "--out", "{o}/e"],
    "rig": ["rig", "{p}"],
    "export": ["export", "{p}", "--track", "{t}", "--glb", "{o}/x.glb"],
    "auto": ["auto", "{video}", "--out", "{o}/a", "--frames", "2", "--no-validate"],
    "fit-scan": ["fit-scan", "{p}", "{scan}", "--expression", "neutral"],
    "clone": ["clone", "--from", "{p}", "--track", "{t}", "--to", "{p}", "--method", "displacement", "--out", "{o}/c"],
    "sample-data": ["sample-data"],
    "studio": ["studio", "{p}"],
}
#: Commands that write into the project's folder (their read-only case makes that folder read-only).
WRITE_PROJECT = {"add-photos", "fit", "texture", "rig", "fit-scan"}
#: command → (argument to replace, replacement) of the unknown-name case; absent: no name to give.
UNKNOWN = {
    "fit": ("neutral", "nosuch"),
    "texture": ("neutral", "nosuch"),
    "track": ("--no-overlay", "--no-overlay --expressions neutral,nosuch"),
    "track-many": ("--no-overlay", "--no-overlay --expressions neutral,nosuch"),
    "edit": ("smile=0.5", "nosuch=0.5"),
    "rig": ("{p}", "{p} --neutral nosuch"),
    "fit-scan": ("neutral", "nosuch"),
    "clone": ("displacement", "nosuch"),
}
KINDS = ("read_only", "missing_input", "wrong_size_photo", "unknown_name", "odd_path")


def _base(work: Path, log) -> Path:
    """The fitted sample with its video, photos and a 3-frame track, in ``work/base``."""
    sys.path.insert(0, str(REPO))
    from tracking.run import track_video  # noqa: PLC0415 - the stack, loaded by the section only
    from tracking.synthetic_sequences.ground_truth import fitted_sample_project  # noqa: PLC0415

    log("commands: the fitted sample project (cached after the first run)")
    fitted = fitted_sample_project()
    base = work / "base"
    shutil.copytree(fitted.parent, base / "james")
    shutil.copytree(SAMPLE / "video", base / "james" / "video")
    photos = base / "photos"
    photos.mkdir()
    for name in ("neutral_front.png", "neutral_three_quarter_left.png"):
        shutil.copy(SAMPLE / "photos" / name, photos / name)
    log("commands: a 3-frame track for edit and export")
    track_video(base / "james" / fitted.name, base / "james" / "video" / VIDEO.name, base / "track", max_frames=3)
    return base / "james" / fitted.name


def _cache_with_sample(folder: Path) -> None:
    """A cache folder holding a copy of the verified sample data (nothing to fetch)."""
    from photomodel.samples.sample_data import sample_data_dir  # noqa: PLC0415

    src = sample_data_dir()
    shutil.copytree(src, folder / src.name)


def _listing(folder: Path) -> dict:
    """Every file (size, modification time) and folder under ``folder``: what a partial output changes
    (a folder's own time is left out: a write check's probe file, made and removed, touches it)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        with contextlib.suppress(OSError):
            st = p.lstat()
            out[str(p.relative_to(folder))] = None if p.is_dir() else (st.st_size, st.st_mtime_ns)
    return out


def _read_only(folder: Path) -> str | None:
    """Make ``folder`` read-only; how ("mount", "chmod"), or None where this machine cannot."""
    if os.geteuid() == 0:
        ok = subprocess.run(["mount", "--bind", str(folder), str(folder)], capture_output=True).returncode == 0
        if ok and subprocess.run(["mount", "-o", "remount,bind,ro", str(folder)], capture_output=True).returncode == 0:
            return "mount"
        if ok:
            subprocess.run(["umount", str(folder)], capture_output=True)
        return None
    folder.chmod(0o555)
    return "chmod"


def _writable_again(folder: Path, how: str | None) -> None:
    if how == "mount":
        subprocess.run(["umount", str(folder)], capture_output=True)
    elif how == "chmod":
        folder.chmod(0o755)


def _case(command: str, kind: str, base_project: Path, work: Path) -> dict | None:
    """Prepare one case in a fresh folder: ``{argv, env, root, culprit, lock}``, or None where it does not apply."""
    root = work / f"{command}-{kind}" / (ODD if kind == "odd_path" else "")
    root.mkdir(parents=True)
    shutil.copytree(base_project.parent, root / "james")
    shutil.copytree(base_project.parents[1] / "photos", root / "photos")
    shutil.copytree(base_project.parents[1] / "track", root / "track")
    (root / "out").mkdir()
    names = {
        "p": root / "james" / base_project.name,
        "o": root / "out",
        "t": root / "track",
        "photos": root / "photos",
        "video": root / "james" / "video" / VIDEO.name,
        "scan": root / "james" / "results" / "neutral.obj",  # the fitted neutral's mesh as a scan
    }
    env = {**os.environ, "PYTHONPATH": str(REPO), "QT_QPA_PLATFORM": "offscreen"}
    argv = list(COMMANDS[command])
    culprit, lock = None, None
    if command == "sample-data":  # a cache folder of its own (the others share the user's cache)
        env["FACESTUDIO_CACHE"] = str(root / "cache")
        if kind in ("missing_input", "wrong_size_photo", "unknown_name"):
            return None
        (root / "cache").mkdir()
        if kind == "odd_path":
            _cache_with_sample(root / "cache")
        lock = culprit = root / "cache"
    elif kind == "read_only":
        if command == "studio":
            return None
        lock = culprit = names["p"].parent if command in WRITE_PROJECT else names["o"]
    elif kind == "missing_input":
        key = {"new": "photos", "auto": "video"}.get(command, "p")
        missing = {"photos": "no_photos", "video": "no_clip.mp4", "p": "nosuch.facestudio.json"}[key]
        names[key] = culprit = root / missing
    elif kind == "wrong_size_photo":
        if command == "auto":  # a clip, no project photo
            return None
        one = names["photos"] / "neutral_front.png"
        cv2.imwrite(str(one), np.zeros((1, 1, 3), np.uint8))
        cv2.imwrite(str(root / "james" / "photos" / "neutral_front.png"), np.zeros((1, 1, 3), np.uint8))
        culprit = "neutral_front"
    elif kind == "unknown_name":
        if command not in UNKNOWN:
            return None
        old, new = UNKNOWN[command]
        i = argv.index(old)
        argv[i : i + 1] = new.split()
        culprit = "nosuch"
    argv = [a.format(**{k: str(v) for k, v in names.items()}) for a in argv]
    return {"argv": argv, "env": env, "root": root, "culprit": culprit, "lock": lock}


def _run(command: str, case: dict) -> subprocess.CompletedProcess:
    if command == "studio":  # offscreen, quit after a while: whether it opened or refused is what counts
        code = (
            "import sys; from PySide6.QtCore import QTimer; from PySide6.QtWidgets import QApplication; "
            f"app = QApplication(sys.argv[:1]); QTimer.singleShot({STUDIO_S * 1000}, app.quit); "
            "from app.cli import main; sys.exit(main(sys.argv[1:]))"
        )
    else:
        code = "import sys; from app.cli import main; sys.exit(main(sys.argv[1:]))"
    try:
        return subprocess.run(
            [sys.executable, "-c", code, *case["argv"]],
            env=case["env"],
            capture_output=True,
            text=True,
            timeout=CASE_TIMEOUT_S,
            cwd=case["root"],
        )
    except subprocess.TimeoutExpired as exc:
        return subprocess.CompletedProcess(exc.cmd, -9, "", f"(timed out after {CASE_TIMEOUT_S} s)")


def _judge(kind: str, case: dict, proc, before: dict) -> dict:
    err = proc.stderr or ""
    failed = proc.returncode != 0
    culprit = case["culprit"]
    named = culprit is None or str(culprit) in err or Path(str(culprit)).name in err
    return {
        "exit": proc.returncode,
        "traceback": "Traceback" in err,
        "partial": failed and _listing(case["root"]) != before,
        "unnamed": failed and not named,
        "bad_exit": (failed and proc.returncode != 2) or (kind == "odd_path" and failed),
        "stderr": err[-600:],
    }


def commands_section(args, log) -> dict:
    """``{"commands": {"cases", "tracebacks", "partial_outputs", "unnamed", "exit_codes", "failures", "seconds"}}``."""
    t0 = time.perf_counter()
    only = set(args.commands.split(",")) if getattr(args, "commands", None) else set(COMMANDS)
    exits: Counter = Counter()
    totals: Counter = Counter()
    failures = []
    with tempfile.TemporaryDirectory(prefix="fuzz_commands") as tmp:
        work = Path(tmp)
        base = _base(work, log)
        for command in [c for c in COMMANDS if c in only]:
            for kind in KINDS:
                case = _case(command, kind, base, work)
                if case is None:
                    continue
                how = _read_only(case["lock"]) if kind == "read_only" else None
                if kind == "read_only" and how is None:
                    log(f"commands: {command} × {kind}: left out (no way to make a folder read-only here)")
                    continue
                before = _listing(case["root"])
                try:
                    proc = _run(command, case)
                finally:
                    if how is not None:
                        _writable_again(case["lock"], how)
                r = _judge(kind, case, proc, before)
                totals["cases"] += 1
                totals["tracebacks"] += r["traceback"]
                totals["partial_outputs"] += r["partial"]
                totals["unnamed"] += r["unnamed"]
                exits[str(r["exit"])] += 1
                bad = r["traceback"] or r["partial"] or r["unnamed"] or r["bad_exit"]
                log(f"commands: {command} × {kind}: exit {r['exit']}" + ("  ** MISSES A BAR **" if bad else ""))
                if bad:
                    failures.append({"command": command, "kind": kind, **r})
    for f in failures:
        log(f"commands: {f['command']} × {f['kind']}: {f['stderr']}")
    return {
        "commands": {
            "cases": totals["cases"],
            "tracebacks": totals["tracebacks"],
            "partial_outputs": totals["partial_outputs"],
            "unnamed": totals["unnamed"],
            "exit_codes": dict(sorted(exits.items())),
            "failures": failures,
            "seconds": round(time.perf_counter() - t0, 1),
        }
    }
