"""Finding model files: explicit path, $DENSEPEDS_MODEL_DIR, the user cache, then ../shared/models.

Nothing is ever downloaded: a missing model raises ModelError that says where we looked and how to
get the file.
"""

from __future__ import annotations

import os
from pathlib import Path

from densepeds.errors import ModelError

ENV_VAR = "DENSEPEDS_MODEL_DIR"
CACHE_DIR = Path("~/.cache/densepeds/models")

# How a user obtains each model we know by name (see models/README.md for the contracts).
HOW_TO_GET: dict[str, str] = {
    "yolov8n-seg-320-int8.onnx": (
        "a YOLOv8n-seg ONNX export (Ultralytics output contract, e.g. STMicroelectronics' "
        "stm32ai-modelzoo yolov8n_320_quant_pc_uf_seg_coco-st.onnx); see models/README.md"
    ),
    "osnet_x0_25_msmt17.onnx": (
        "torchreid's osnet_x0_25 MSMT17 weights exported to ONNX "
        "(input [N,3,256,128], output [N,512]); see models/README.md"
    ),
    "maskrcnn_resnet50_fpn.onnx": (
        "run `python models/export_maskrcnn.py` where torch and torchvision are installed "
        "(pip install 'densepeds[export]')"
    ),
    "mars-small128.onnx": (
        "DeepSORT's mars-small128.pb converted with tf2onnx; see models/README.md"
    ),
}


def search_dirs() -> list[Path]:
    """Directories searched for a model given by bare name, in order."""
    dirs: list[Path] = []
    env = os.environ.get(ENV_VAR)
    if env:
        dirs.extend(Path(p).expanduser() for p in env.split(os.pathsep) if p)
    dirs.append(CACHE_DIR.expanduser())
    # Development: the shared models beside the checkout, whether the package runs from the source
    # tree (<repo>/python/densepeds) or is installed as a wheel and run from the repo root.
    candidates = [Path(__file__).resolve().parents[3] / "shared" / "models"]
    candidates.append(Path.cwd().resolve().parent / "shared" / "models")
    for d in candidates:
        if d not in dirs:
            dirs.append(d)
    return dirs


def find_model(name: str, explicit: str | os.PathLike[str] | None = None) -> Path:
    """The path of model ``name``; ``explicit`` (a file path) wins when given.

    A ``name`` that contains a directory separator or names an existing file is used as a path.
    """
    if explicit is not None:
        path = Path(explicit).expanduser()
        if not path.is_file():
            raise ModelError(f"model file {path} does not exist ({_how_to_get(path.name)})")
        return path
    direct = Path(name).expanduser()
    if direct.is_file():
        return direct
    if os.sep in name or (os.altsep and os.altsep in name):
        raise ModelError(f"model file {direct} does not exist ({_how_to_get(direct.name)})")
    tried = search_dirs()
    for folder in tried:
        candidate = folder / name
        if candidate.is_file():
            return candidate
    where = ", ".join(str(d) for d in tried)
    raise ModelError(
        f"model {name!r} not found (looked in {where}; set {ENV_VAR} or pass a path). "
        f"To get it: {_how_to_get(name)}"
    )


def _how_to_get(name: str) -> str:
    return HOW_TO_GET.get(name, "see models/README.md for the supported models and how to get them")
