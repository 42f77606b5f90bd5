#!/usr/bin/env bash
# Builds the release wheel: CPython abi3 (3.10+), tagged manylinux_2_17 (glibc 2.17 and later:
# manylinux2014), linked with zig so that no newer glibc symbol slips in, and checked by maturin's
# auditwheel. Usage: scripts/build-wheel.sh [OUT_DIR] (default target/wheels); prints the path.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-target/wheels}
if [ -z "${VIRTUAL_ENV:-}" ] && [ -d .venv ]; then . .venv/bin/activate; fi
echo "build-wheel: installing the build tools (maturin, ziglang)" >&2
python -m pip install -q "maturin>=1.7,<2" "ziglang>=0.11"
mkdir -p "$OUT"
rm -f "$OUT"/densepeds-*.whl
echo "build-wheel: compiling the Rust extension and packing the wheel (a few minutes)" >&2
maturin build --release --compatibility manylinux_2_17 --zig --auditwheel check -o "$OUT" >&2
WHEEL=$(ls "$OUT"/densepeds-*-cp310-abi3-manylinux*_x86_64.whl "$OUT"/densepeds-*-abi3-manylinux*.whl 2>/dev/null | head -1)
if [ -z "$WHEEL" ]; then
  echo "build-wheel: no manylinux abi3 wheel in $OUT" >&2
  exit 1
fi
echo "$WHEEL"
