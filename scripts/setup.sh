#!/usr/bin/env bash
# Creates .venv, installs the Python dependencies and builds the package (Rust extension included).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if ! command -v cargo >/dev/null 2>&1; then
  echo "cargo not found: install Rust from https://rustup.rs first" >&2
  exit 1
fi
[ -d .venv ] || "$PY" -m venv .venv
. .venv/bin/activate
python -m pip install -q --upgrade pip
python -m pip install -q "maturin>=1.7,<2"
# Build the wheel and install it with its dependencies, the dev extra and ray (`densepeds batch`;
# its tests run in CI). peers: see benchmarks/.
maturin build --release -q -o target/wheels-local >/dev/null
python -m pip install -q --force-reinstall --no-deps target/wheels-local/densepeds-*.whl
python -m pip install -q "$(ls target/wheels-local/densepeds-*.whl | head -1)[dev,ray]"
# The peers pull opencv-python (GUI build); keep only the headless one we depend on.
if python -m pip show opencv-python >/dev/null 2>&1; then
  python -m pip uninstall -q -y opencv-python
  python -m pip install -q --force-reinstall --no-deps opencv-python-headless
fi
