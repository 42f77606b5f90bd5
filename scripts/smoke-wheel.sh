#!/usr/bin/env bash
# Installs the wheel into a fresh venv outside the repo and uses it as a pip user would: the
# built-in scene, the models put into that venv's user cache (fetched from a mirror served on
# 127.0.0.1, and installed from a file), a real clip (PETS09 frames 1-20 from the video, detector
# and re-ID) with an annotated video, and `eval --frames` on it. Needs ../shared (or
# $DENSEPEDS_SHARED) and a package index for the dependencies.
# Usage: scripts/smoke-wheel.sh [WHEEL] (default: the manylinux wheel in target/wheels)
set -euo pipefail
REPO=$(cd "$(dirname "$0")/.." && pwd)
WHEEL=${1:-$(ls "$REPO"/target/wheels/densepeds-*manylinux*.whl 2>/dev/null | head -1)}
[ -n "$WHEEL" ] && [ -f "$WHEEL" ] || { echo "smoke: no wheel (run scripts/build-wheel.sh)" >&2; exit 1; }
WHEEL=$(cd "$(dirname "$WHEEL")" && pwd)/$(basename "$WHEEL")
SHARED=$(cd "${DENSEPEDS_SHARED:-$REPO/../shared}" && pwd)
PY=${PYTHON:-python3}
WORK=$(mktemp -d "${TMPDIR:-/tmp}/densepeds-smoke.XXXXXX")
SERVER=""
cleanup() {
  if [ -n "$SERVER" ]; then kill "$SERVER" 2>/dev/null || true; fi
  rm -rf "$WORK"
}
trap cleanup EXIT
step() { echo "smoke: $*" >&2; }

step "fresh venv in $WORK, installing $(basename "$WHEEL") with the eval extra"
"$PY" -m venv "$WORK/venv"
. "$WORK/venv/bin/activate"
python -m pip install -q --upgrade pip
python -m pip install -q "$WHEEL[eval]"
python -m pip install -q --no-deps "trackeval>=1.3"
cd "$WORK"
unset DENSEPEDS_MODEL_DIR DENSEPEDS_MODEL_URL PYTHONPATH
export XDG_CACHE_HOME="$WORK/cache"
opencvs=$(python -m pip list 2>/dev/null | grep -c -E '^opencv-(contrib-)?python(-headless)? ' || true)
[ "$opencvs" = 1 ] || { echo "smoke: $opencvs OpenCV distributions installed, expected 1" >&2; exit 1; }

step "densepeds --version; the built-in scene"
densepeds --version
densepeds run --scene-frames 40 -q | tail -n 1

step "models: fetch the detector from a mirror on 127.0.0.1, install the re-ID model from a file"
PORT=$(python -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
python -m http.server "$PORT" --bind 127.0.0.1 --directory "$SHARED/models" >/dev/null 2>&1 &
SERVER=$!
python - "$PORT" <<'PY'
import socket, sys, time
for _ in range(100):
    try:
        socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=1).close()
        break
    except OSError:
        time.sleep(0.1)
PY
densepeds models fetch yoloseg --url "http://127.0.0.1:$PORT" -q
densepeds models install "$SHARED/models/osnet_x0_25_msmt17.onnx"
densepeds models >models.txt
grep -q "found: $XDG_CACHE_HOME/densepeds/models/osnet_x0_25_msmt17.onnx" models.txt || {
  echo "smoke: densepeds models does not list the installed re-ID model:" >&2
  cat models.txt >&2
  exit 1
}

step "a real clip: PETS09-S2L1 frames 1-20 from the video, detector + re-ID, annotated video"
densepeds run "$SHARED/data/PETS09-S2L1-dev/vtest.avi" --frames 1:20 --out pets.txt --video pets.mp4 -q
python - <<'PY'
import cv2
cap = cv2.VideoCapture("pets.mp4")
n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode("ascii", "replace")
cap.release()
assert n == 20, f"pets.mp4 has {n} frames, expected 20"
print(f"pets.mp4: {n} frames, codec {fourcc}")
PY
densepeds eval --gt "$SHARED/data/PETS09-S2L1-dev" --tracks pets.txt --frames 1:20 --format csv
step "ok"
