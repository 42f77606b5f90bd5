#!/usr/bin/env bash
# Runs every test: the Rust workspace, then pytest against the installed package.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -d .venv ] && . .venv/bin/activate
cargo test --workspace --release
python -m pytest -q tests
