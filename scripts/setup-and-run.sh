#!/usr/bin/env bash
# One command on a fresh machine: set up, then track the built-in dense-crowd scene.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/setup.sh
. .venv/bin/activate
python -m densepeds run "$@"
