#!/usr/bin/env bash
# Creates .venv, builds the manylinux wheel (Rust extension included, scripts/build-wheel.sh) and
# installs it with the dev, eval and ray extras. Prints each step as it goes.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
step() { echo "setup: $*" >&2; }
if ! command -v cargo >/dev/null 2>&1; then
  echo "cargo not found: install Rust from https://rustup.rs first" >&2
  exit 1
fi
if [ ! -d .venv ]; then
  step "creating .venv"
  "$PY" -m venv .venv
fi
. .venv/bin/activate
step "upgrading pip"
python -m pip install -q --upgrade pip
WHEEL=$(./scripts/build-wheel.sh target/wheels)
step "installing $(basename "$WHEEL") with the dev, eval and ray extras (numpy, onnxruntime, OpenCV, Ray, ...)"
python -m pip install -q --force-reinstall --no-deps "$WHEEL"
python -m pip install -q "$WHEEL[dev,eval,ray]"
# trackeval declares opencv-python (a second cv2 beside opencv-python-headless): installed with
# metadata that requires the headless one instead (densepeds.install_trackeval).
step "installing trackeval (requiring opencv-python-headless, not a second OpenCV)"
python -m densepeds.install_trackeval -q
# The peers (pip install '.[peers]', benchmarks/) pull opencv-python; keep only the headless one.
if python -m pip show opencv-python >/dev/null 2>&1; then
  step "removing opencv-python (a second cv2 beside opencv-python-headless)"
  python -m pip uninstall -q -y opencv-python
  python -m pip install -q --force-reinstall --no-deps opencv-python-headless
fi
step "pip check: every installed requirement met"
python -m pip check
step "done: . .venv/bin/activate, then densepeds --help"
