"""Render the james sample scan from the front, textured, and time it (a look at the renderer).

``python benchmarks/bench_render.py [out.png] [--size N] [--azimuth DEG]``: writes the picture
and prints the time of one :meth:`photomodel.rendering.renderer.Renderer.render` call (texture
uploaded in the call).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from photomodel.camera import orbit_camera  # noqa: E402
from photomodel.exchange.files import atomic_write_bytes, encode_png  # noqa: E402
from photomodel.rendering.renderer import get_renderer  # noqa: E402
from photomodel.samples.sample_data import load_james_scan  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default="render_check.png")
    parser.add_argument("--size", type=int, default=1000)
    parser.add_argument("--azimuth", type=float, default=0.0, help="degrees, + towards subject's left")
    args = parser.parse_args(argv)
    scan = load_james_scan()
    cam = orbit_camera(args.azimuth, args.size, args.size, distance_mm=900.0, target=(0.0, 10.0, 0.0))
    renderer = get_renderer()
    t0 = time.perf_counter()
    res = renderer.render(cam, scan.vertices, scan.faces, uv=scan.uv, texture=scan.texture, background=1.0)
    dt = time.perf_counter() - t0
    path = atomic_write_bytes(args.out, encode_png(res.color))
    print(f"{path}  ({args.size}×{args.size} in {dt * 1000:.0f} ms)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
