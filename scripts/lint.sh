#!/usr/bin/env bash
# Static checks: rustfmt, clippy (warnings are errors), ruff (lint + format) and mypy.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -d .venv ] && . .venv/bin/activate
cargo fmt --all --check
cargo clippy --workspace --all-targets --release -- -D warnings
ruff check python tests benchmarks models/*.py
ruff format --check python tests benchmarks models/*.py
mypy
