#!/usr/bin/env bash
# Installs the wheel into a fresh venv outside the repo and uses it as a pip user would: the
# built-in scene; `densepeds models fetch` with no options from a server on 127.0.0.1 laid out
# like the published hosts ($DENSEPEDS_MODEL_HOSTS; the first host of one model missing, so its
# mirror is used), serving stand-in graphs with the published contracts (tests/contract_models.py:
# the real weights are not here, so their pins are swapped for the stand-ins' in that one
# process), then `densepeds run` on a real clip with what was fetched (Mask R-CNN + YoutuReID);
# then the shipped yoloseg/OSNet models (fetched with --url from a flat mirror, and installed
# from a file), which `run` prefers, on PETS09 frames 1-20 with an annotated video that must be
# browser-playable (H.264, yuv420p, moov first), and `eval --frames` on it. Needs ../shared (or
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
python -m densepeds.install_trackeval -q
python -m pip check
cd "$WORK"
unset DENSEPEDS_MODEL_DIR DENSEPEDS_MODEL_URL PYTHONPATH
export XDG_CACHE_HOME="$WORK/cache"
opencvs=$(python -m pip list 2>/dev/null | grep -c -E '^opencv-(contrib-)?python(-headless)? ' || true)
[ "$opencvs" = 1 ] || { echo "smoke: $opencvs OpenCV distributions installed, expected 1" >&2; exit 1; }

step "densepeds --version; the built-in scene"
densepeds --version
densepeds run --scene-frames 40 -q | tail -n 1

PORT=$(python -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
wait_for_port() {
  python - "$PORT" <<'PY'
import socket, sys, time
for _ in range(100):
    try:
        socket.create_connection(("127.0.0.1", int(sys.argv[1])), timeout=1).close()
        break
    except OSError:
        time.sleep(0.1)
PY
}

step "models: \`densepeds models fetch\` (no options) from 127.0.0.1 laid out like the published hosts"
mkdir hosts stand-ins
PYTHONPATH="$REPO/tests" python - "$WORK/hosts" "$WORK/stand-ins" <<'PY'
import sys
from pathlib import Path
from urllib.parse import urlsplit
from contract_models import youtu_reid, zoo_maskrcnn
from densepeds.models.files import DEFAULT_SET, MODELS
hosts, made = Path(sys.argv[1]), Path(sys.argv[2])
graphs = {"maskrcnn-zoo-int8": zoo_maskrcnn(made / "zoo.onnx"),
          "youtureid-int8": youtu_reid(made / "youtu.onnx")}
assert set(graphs) == set(DEFAULT_SET), DEFAULT_SET
for name, path in graphs.items():
    urls = MODELS[name].urls
    # YoutuReID only on its mirror: the first host answers 404 and the mirror is tried.
    for url in urls[1:] if name == "youtureid-int8" else urls[:1]:
        parts = urlsplit(url)
        target = hosts / parts.netloc / parts.path.lstrip("/")
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(path.read_bytes())
PY
python -m http.server "$PORT" --bind 127.0.0.1 --directory "$WORK/hosts" >/dev/null 2>&1 &
SERVER=$!
wait_for_port
DENSEPEDS_MODEL_HOSTS="http://127.0.0.1:$PORT" python - "$WORK/stand-ins" <<'PY'
import dataclasses, sys
from pathlib import Path
from densepeds.models import files as modelfiles
from densepeds.cli import main
made = Path(sys.argv[1])
# The stand-ins' pins in place of the real files' (this process only); names, URLs and
# layout stay the published ones.
for name, file in (("maskrcnn-zoo-int8", "zoo.onnx"), ("youtureid-int8", "youtu.onnx")):
    path = made / file
    info = dataclasses.replace(modelfiles.MODELS[name], sha256=modelfiles.sha256_of(path),
                               size=path.stat().st_size)
    modelfiles.MODELS[name] = modelfiles.BY_FILE[info.file] = info
sys.exit(main(["models", "fetch", "-q"]))
PY
kill "$SERVER"; wait "$SERVER" 2>/dev/null || true; SERVER=""
for f in MaskRCNN-12-int8.onnx person_reid_youtu_2021nov_int8.onnx; do
  [ -f "$XDG_CACHE_HOME/densepeds/models/$f" ] || { echo "smoke: fetch did not install $f" >&2; exit 1; }
done
[ -z "$(ls "$XDG_CACHE_HOME/densepeds/models" | grep -v -x -e MaskRCNN-12-int8.onnx -e person_reid_youtu_2021nov_int8.onnx)" ] ||
  { echo "smoke: unexpected files in the cache:" >&2; ls -la "$XDG_CACHE_HOME/densepeds/models" >&2; exit 1; }

step "densepeds run with the fetched Mask R-CNN + YoutuReID graphs (PETS09 frames 1-5)"
densepeds run "$SHARED/data/PETS09-S2L1-dev/vtest.avi" --frames 1:5 --out fetched.txt >fetched.out 2>fetched.err ||
  { cat fetched.err >&2; exit 1; }
cat fetched.out fetched.err >&2
grep -q "(preset maskrcnn)" fetched.out || { echo "smoke: run did not use the fetched Mask R-CNN" >&2; exit 1; }
[ -s fetched.txt ] || { echo "smoke: no tracks from the fetched models" >&2; exit 1; }
densepeds models >models.txt
grep -q "re-ID person_reid_youtu_2021nov_int8.onnx" models.txt || {
  echo "smoke: densepeds models does not pick the fetched re-ID model:" >&2; cat models.txt >&2; exit 1; }

step "models: the shipped detector from a flat mirror (--url), the re-ID model installed from a file"
python -m http.server "$PORT" --bind 127.0.0.1 --directory "$SHARED/models" >/dev/null 2>&1 &
SERVER=$!
wait_for_port
densepeds models fetch yoloseg --url "http://127.0.0.1:$PORT" -q
densepeds models install "$SHARED/models/osnet_x0_25_msmt17.onnx"
densepeds models >models.txt
grep -q "found: $XDG_CACHE_HOME/densepeds/models/osnet_x0_25_msmt17.onnx" models.txt || {
  echo "smoke: densepeds models does not list the installed re-ID model:" >&2
  cat models.txt >&2
  exit 1
}
grep -q "uses now: detector yoloseg (yolov8n-seg-320-int8.onnx), re-ID osnet_x0_25_msmt17.onnx" models.txt || {
  echo "smoke: densepeds run would not prefer the shipped yoloseg + OSNet:" >&2; cat models.txt >&2; exit 1; }

step "a real clip: PETS09-S2L1 frames 1-20, yoloseg + OSNet (preferred where present), annotated video"
densepeds run "$SHARED/data/PETS09-S2L1-dev/vtest.avi" --frames 1:20 --out pets.txt --video pets.mp4 -q 2>run.err ||
  { cat run.err >&2; exit 1; }
cat run.err >&2
grep -q "video codec: H.264 (libx264 through FFmpeg)" run.err || {
  echo "smoke: the run did not report an H.264 video from FFmpeg" >&2
  exit 1
}
# Browser-playable: H.264 in yuv420p, the index (moov) before the data (mdat), every frame there;
# checked with OpenCV and with FFmpeg's own description of the stream.
python - <<'PY'
import re, subprocess
import cv2, imageio_ffmpeg
cap = cv2.VideoCapture("pets.mp4")
n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
fourcc = int(cap.get(cv2.CAP_PROP_FOURCC)).to_bytes(4, "little").decode("ascii", "replace")
decoded = 0
while cap.read()[0]:
    decoded += 1
cap.release()
assert n == decoded == 20, f"pets.mp4 has {n} frames ({decoded} decoded), expected 20"
assert fourcc.lower() in ("avc1", "h264"), f"pets.mp4 codec {fourcc}, expected H.264"
info = subprocess.run([imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", "pets.mp4"],
                      capture_output=True, text=True).stderr
stream = re.search(r"Video: (.*)", info).group(1)
assert stream.startswith("h264") and "yuv420p" in stream, f"pets.mp4 stream: {stream}"
data = open("pets.mp4", "rb").read()
assert 0 <= data.find(b"moov") < data.find(b"mdat"), "pets.mp4: moov after mdat (no faststart)"
print(f"pets.mp4: {n} frames, FOURCC {fourcc}; FFmpeg: {stream}")
PY
densepeds eval --gt "$SHARED/data/PETS09-S2L1-dev" --tracks pets.txt --frames 1:20 --format csv
step "ok"
