"""``facestudio auto``: a phone clip to an ARKit-animated, textured face (glb + Live Link CSV) in one command.

    facestudio auto CLIP [--out DIR] [--glb out.glb] [--csv out.csv] [--stills N] [--frames N] [--json]

The stages (:mod:`tracking.auto_pipeline`): stills picked from the clip, cameras and mesh fitted,
textured, rigged (ICT-FaceKit's 51 ARKit shapes), the whole clip tracked in ARKit terms, exported.
The project and every intermediate result are written in ``DIR`` (default ``<clip stem>_auto``
beside the clip) so that the studio opens it and each stage can be redone by hand; a second run
resumes what is there. One progress display names the stage. Ctrl-C while tracking stops after
the frame (a second one at once) and saves the track; at any point the project opens and
``auto`` run again goes on. A clip with no usable face exits with status 2 and says what was tried.
"""

from __future__ import annotations

import json
import signal
import sys
from pathlib import Path

from app.cli.common import check_file_writable, check_writable
from app.cli.progress import command_progress
from photomodel.errors import FaceStudioError
from tracking.auto_pipeline import run_auto

NAME = "auto"

__all__ = ["NAME", "add_parser", "run"]


def add_parser(subparsers) -> None:
    """The ``auto`` sub-command."""
    a = subparsers.add_parser(
        NAME,
        help="one command from a clip to an ARKit-animated textured face: stills, fit, texture, rig, "
        "track in ARKit terms, glb + Live Link CSV",
    )
    a.add_argument("clip", type=Path, help="the video (a phone clip of one face; anything OpenCV decodes)")
    a.add_argument(
        "--out", type=Path, help="folder of the project and every intermediate result (default: <clip>_auto)"
    )
    a.add_argument("--glb", type=Path, help="the animated binary glTF to write (default: DIR/<clip>.glb)")
    a.add_argument("--csv", type=Path, help="the Live Link Face CSV to write (default: DIR/<clip>.csv)")
    a.add_argument("--stills", type=int, default=5, help="frames picked from the clip for the fit (default 5)")
    a.add_argument("--frames", type=int, help="track only the first N frames (default: the whole clip)")
    a.add_argument("--no-validate", action="store_true", help="skip the Khronos glTF validator on the glb")
    a.add_argument("--json", action="store_true", help="print one JSON object (each stage's time and figures)")


def run(args) -> int:
    """Run :func:`tracking.auto_pipeline.run_auto` with a progress display and Ctrl-C handling."""
    if args.frames is not None and args.frames < 1:
        raise FaceStudioError(f"--frames {args.frames}: track at least one frame")
    if args.stills < 2:
        raise FaceStudioError(f"--stills {args.stills}: the fit needs at least two stills of the face")
    if not args.clip.exists():
        raise FaceStudioError(f"{args.clip}: no such video (a clip file, or a folder of its frames)")
    # every folder written, before the long work (the default folder is beside the clip)
    check_writable(args.out if args.out is not None else args.clip.absolute().parent)
    check_file_writable(args.glb, args.csv)
    show = command_progress(args, NAME)
    stop = []

    def on_sigint(signum, frame):  # first Ctrl-C: the track stops after this frame; a second one at once
        stop.append(signum)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("\nfacestudio: stopping after this step (Ctrl-C again to stop at once)", file=sys.stderr)

    out = args.out
    previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        result = run_auto(
            args.clip,
            args.out,
            glb=args.glb,
            csv=args.csv,
            stills=args.stills,
            max_frames=args.frames,
            validate=not args.no_validate,
            progress=show,
            cancel=lambda: bool(stop),
        )
    except KeyboardInterrupt:
        show.close()
        where = out or f"{args.clip.stem}_auto"
        print(
            f"facestudio: cancelled; what is done is saved in {where} (the studio opens the project there); "
            f"run `facestudio auto {args.clip}{' --out ' + str(out) if out else ''}` again to go on",
            file=sys.stderr,
        )
        return 130
    finally:
        signal.signal(signal.SIGINT, previous)
        show.close()
    summary = result.as_dict()
    if args.json:
        print(json.dumps({"auto": summary}, indent=1))
        return 0
    st = summary["stages"]
    print(
        f"auto: {result.frames} frames tracked in ARKit terms in {summary['total_s']:.1f} s ("
        + ", ".join(f"{k.removesuffix('_s')} {v:.1f} s" for k, v in st.items())
        + ")"
    )
    print(
        f"  fit RMS {summary['fit_rms_px']} px, depth {summary['depth_ratio']} x the generic head's; "
        f"landmarks {summary['landmark_err_px']} px from the detector; lost {result.lost}, recovered {result.recovered}"
    )
    g = summary["glb"]
    print(
        f"  {result.glb}: {g['targets']} morph targets, {g['frames']} frames, {g['arkit_channels_moving']} ARKit "
        f"channels moving, validator errors {g['validator_errors']}"
    )
    print(f"  {result.csv}: Live Link Face CSV")
    print(f"  project {result.project} (open it in the studio), track {result.track_dir}")
    for note in result.notes:
        print(f"facestudio: warning: {note}", file=sys.stderr)
    return 0
