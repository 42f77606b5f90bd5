"""The models DensePeds knows, and finding their files: an explicit path, ``$DENSEPEDS_MODEL_DIR``,
then the user cache (``$XDG_CACHE_HOME/densepeds/models``, by default
``~/.cache/densepeds/models``).

Nothing is downloaded at run time: a missing model raises ModelError that says where we looked
and names the command that puts the file in the cache (``densepeds models fetch`` or
``densepeds models install``, see :mod:`densepeds.modelfetch`).
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from densepeds.errors import ModelError

ENV_VAR = "DENSEPEDS_MODEL_DIR"
URL_ENV_VAR = "DENSEPEDS_MODEL_URL"  # a mirror's base URL: BASE/<file> is fetched


@dataclass(frozen=True)
class ModelInfo:
    """A model the package knows by name.

    ``sha256``/``size`` pin the exact file (None where the file is made locally, e.g. by an export
    script, so its bytes are not fixed); ``url`` is where that exact file is published (None where
    it is not published as ONNX: then ``source`` says where the weights come from and how to make
    the ONNX file).
    """

    name: str
    file: str
    role: str
    licence: str
    contract: str
    source: str
    sha256: str | None = None
    size: int | None = None
    url: str | None = None


MODELS: dict[str, ModelInfo] = {
    m.name: m
    for m in (
        ModelInfo(
            name="yoloseg",
            file="yolov8n-seg-320-int8.onnx",
            role="detector (--detector yoloseg, the default where there are frames)",
            licence="AGPL-3.0 (Ultralytics YOLOv8n-seg weights, quantised by STMicroelectronics)",
            contract="input [1,320,320,3] NHWC RGB float in [0,1], letterboxed; outputs "
            "[1,116,2100] (cx,cy,w,h normalised, 80 COCO class scores, 32 mask coefficients) and "
            "[1,80,80,32] mask prototypes",
            source="no published ONNX: STMicroelectronics publish this int8 model as TFLite "
            "only (github.com/stm32-hotspot/ultralytics, examples/YOLOv8-STEdgeAI/"
            "stedgeai_models/segmentation/yolov8n_320_quant_pc_uf_seg_coco-st.tflite) and this "
            "file is its tf2onnx conversion",
            sha256="22ba5adca763b8f0741efdf66d95836e90222bb09f33a266ad99663b112f9257",
            size=3660283,
        ),
        ModelInfo(
            name="osnet",
            file="osnet_x0_25_msmt17.onnx",
            role="re-ID (--reid-model; used by --features other than none)",
            licence="MIT (torchreid OSNet architecture and MSMT17 weights)",
            contract="input [N,3,256,128] RGB float, /255 then ImageNet mean/std; output [N,512]",
            source="no published ONNX: torchreid publishes the osnet_x0_25 MSMT17 weights as "
            "PyTorch only and this file is their ONNX export (torch.onnx.export of torchreid's "
            "osnet_x0_25 in eval mode at [1,3,256,128] with a dynamic batch; an export of your "
            "own has the contract but not these bytes: pass it with --reid-model PATH)",
            sha256="6cb2ff28786b0bd371c039765c20e642f34dc3c72cbda5d99592f00b519e4fa5",
            size=891579,
        ),
        ModelInfo(
            name="maskrcnn",
            file="maskrcnn_resnet50_fpn.onnx",
            role="detector (--detector maskrcnn)",
            licence="BSD-3-Clause (torchvision code and COCO weights)",
            contract="input image [3,H,W] RGB float in [0,1]; outputs boxes [N,4], labels [N], "
            "scores [N], masks [N,1,H,W]",
            source="made locally: pip install 'densepeds[export]' then "
            "python models/export_maskrcnn.py --weights coco (from a source checkout), then "
            "densepeds models install maskrcnn_resnet50_fpn.onnx",
        ),
        ModelInfo(
            name="mars-small128",
            file="mars-small128.onnx",
            role="re-ID (--reid-model mars-small128.onnx)",
            licence="GPL-3.0 (nwojke/deep_sort)",
            contract="input [N,128,64,3] uint8 BGR; output [N,128]",
            source="made locally: python -m tf2onnx.convert --graphdef mars-small128.pb "
            "--inputs images:0 --outputs features:0 --opset 17 --output mars-small128.onnx "
            "(DeepSORT's graph), then densepeds models install mars-small128.onnx",
        ),
    )
}
QUANTIZED_SUFFIX = "-ortq"


def quantized_file_name(model: Path | str) -> str:
    """The file name of a model's int8 copy (``densepeds models quantize``): <stem>-ortq.onnx."""
    return f"{Path(model).stem}{QUANTIZED_SUFFIX}.onnx"


MODELS["yoloseg-int8"] = ModelInfo(
    name="yoloseg-int8",
    file=quantized_file_name(MODELS["yoloseg"].file),
    role="detector: yoloseg's int8 copy for this CPU, run in its place where present",
    licence=MODELS["yoloseg"].licence,
    contract=f"as yoloseg's, any batch: {MODELS['yoloseg'].contract}",
    source="made locally from yoloseg: densepeds models quantize --calibrate VIDEO "
    "(models/README.md)",
)
BY_FILE: dict[str, ModelInfo] = {m.file: m for m in MODELS.values()}


def model_info(name_or_file: str) -> ModelInfo:
    """The known model with this short name (``osnet``) or file name; ModelError if unknown."""
    info = MODELS.get(name_or_file) or BY_FILE.get(Path(name_or_file).name)
    if info is None:
        known = ", ".join(f"{m.name} ({m.file})" for m in MODELS.values())
        raise ModelError(f"unknown model {name_or_file!r}; known: {known}")
    return info


def cache_dir() -> Path:
    """The user cache that ``densepeds models fetch|install`` fills."""
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path("~/.cache").expanduser()
    return base / "densepeds" / "models"


def search_dirs() -> list[Path]:
    """Directories searched for a model given by bare name, in order."""
    dirs: list[Path] = []
    env = os.environ.get(ENV_VAR)
    if env:
        dirs.extend(Path(p).expanduser() for p in env.split(os.pathsep) if p)
    cache = cache_dir()
    if cache not in dirs:
        dirs.append(cache)
    return dirs


def locate(file: str) -> Path | None:
    """The first ``file`` found in :func:`search_dirs`, or None."""
    for folder in search_dirs():
        candidate = folder / file
        if candidate.is_file():
            return candidate
    return None


def sha256_of(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def how_to_get(file: str) -> str:
    """The command(s) that put a model in the cache, for error messages."""
    info = BY_FILE.get(Path(file).name)
    if info is None:
        known = ", ".join(m.file for m in MODELS.values())
        return (
            f"it is not a model densepeds knows ({known}); pass the file's path, or put it in "
            f"{cache_dir()} with `densepeds models install FILE`"
        )
    if info.sha256 is None:
        return info.source
    if info.url or os.environ.get(URL_ENV_VAR):
        return f"run `densepeds models fetch {info.name}` (or `densepeds models install FILE`)"
    return (
        f"run `densepeds models install PATH/TO/{info.file}` with a copy you have, or "
        f"`densepeds models fetch {info.name} --url MIRROR` from a mirror serving MIRROR/"
        f"{info.file} ({info.source})"
    )


def find_model(name: str, explicit: str | os.PathLike[str] | None = None) -> Path:
    """The path of model ``name``; ``explicit`` (a file path) wins when given.

    A ``name`` that contains a directory separator or names an existing file is used as a path.
    """
    if explicit is not None:
        path = Path(explicit).expanduser()
        if not path.is_file():
            raise ModelError(f"model file {path} does not exist ({how_to_get(path.name)})")
        return path
    direct = Path(name).expanduser()
    if direct.is_file():
        return direct
    if os.sep in name or (os.altsep and os.altsep in name):
        raise ModelError(f"model file {direct} does not exist ({how_to_get(direct.name)})")
    found = locate(name)
    if found is not None:
        return found
    where = ", ".join(str(d) for d in search_dirs())
    raise ModelError(
        f"model {name} not found (looked in {where}; `densepeds models` lists what is where). "
        f"To get it: {how_to_get(name)}"
    )
