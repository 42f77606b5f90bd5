#!/usr/bin/env bash
# Runs every test: the Rust workspace, then pytest against the installed package; says how long
# each took. The Rust tests build with the fast-test profile (Cargo.toml: optimised as release,
# without its whole-program LTO, which would give each of the twenty-odd test binaries a
# single-unit LTO link of its own), in target/fast-test, so a second run rebuilds only what
# changed.
set -euo pipefail
cd "$(dirname "$0")/.."
[ -d .venv ] && . .venv/bin/activate
took() { echo "test: $1 took $(($2 / 60)) min $(($2 % 60)) s" >&2; }
start=$SECONDS
cargo test --workspace --profile fast-test
took "cargo test (build and run)" $((SECONDS - start))
start=$SECONDS
python -m pytest -q tests
took "pytest" $((SECONDS - start))
