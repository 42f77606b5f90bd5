"""The models DensePeds knows, and finding their files: an explicit path, ``$DENSEPEDS_MODEL_DIR``,
then the user cache (``$XDG_CACHE_HOME/densepeds/models``, by default
``~/.cache/densepeds/models``).

Nothing is downloaded at run time: a missing model raises ModelError that says where we looked
and names the command that puts the file in the cache (``densepeds models fetch`` or
``densepeds models install``, see :mod:`densepeds.models.fetch`).

``DEFAULT_SET`` is what ``densepeds models fetch`` gets with no names: the paper's detector
(the ONNX Model Zoo's Mask R-CNN, MIT) and OpenCV Zoo's YoutuReID (Apache-2.0), the only
published, permissively licensed ONNX files of the two roles. When several detectors or re-ID
models are present, :func:`default_detector` and :func:`default_reid_file` take the first found in
``DETECTOR_ORDER`` / ``REID_ORDER``: the yoloseg + OSNet pair first (every published figure was
measured with them, and yoloseg costs a fraction of Mask R-CNN on a CPU), then the float model
zoo files before their int8 copies (a user fetches the float ones only by name).
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from densepeds.errors import ModelError

ENV_VAR = "DENSEPEDS_MODEL_DIR"
URL_ENV_VAR = "DENSEPEDS_MODEL_URL"  # a mirror's base URL: BASE/<file> is fetched
# A base replacing every published host: https://HOST/PATH is fetched from BASE/HOST/PATH (a
# mirror laid out like the hosts, e.g. a local server for tests or an offline site).
HOSTS_ENV_VAR = "DENSEPEDS_MODEL_HOSTS"


@dataclass(frozen=True)
class ModelInfo:
    """A model the package knows by name.

    ``sha256``/``size`` pin the exact file (None where the file is made locally, e.g. by an export
    script, so its bytes are not fixed); ``urls`` are where that exact file is published, tried in
    order (empty where it is not published as ONNX: then ``source`` says where the weights come
    from and how to make the ONNX file). ``detector`` is the detector kind that reads it (None for
    a re-ID model).
    """

    name: str
    file: str
    role: str
    licence: str
    contract: str
    source: str
    sha256: str | None = None
    size: int | None = None
    urls: tuple[str, ...] = ()
    detector: str | None = None

    @property
    def url(self) -> str | None:
        """The first published URL, or None."""
        return self.urls[0] if self.urls else None


ONNX_ZOO_DIR = "validated/vision/object_detection_segmentation/mask-rcnn/model"
OPENCV_ZOO_DIR = "models/person_reid_youtureid"


def _onnx_zoo(file: str) -> tuple[str, ...]:
    """The ONNX Model Zoo's Hugging Face mirror first (the zoo moved its downloads there; GitHub's
    LFS bandwidth quota has blocked them before), then the GitHub repository's LFS media URL."""
    return (
        f"https://huggingface.co/onnxmodelzoo/legacy_models/resolve/main/{ONNX_ZOO_DIR}/{file}",
        f"https://media.githubusercontent.com/media/onnx/models/main/{ONNX_ZOO_DIR}/{file}",
    )


def _opencv_zoo(file: str) -> tuple[str, ...]:
    """OpenCV Zoo's GitHub LFS media URL, then its Hugging Face mirror."""
    return (
        f"https://media.githubusercontent.com/media/opencv/opencv_zoo/main/{OPENCV_ZOO_DIR}/{file}",
        f"https://huggingface.co/opencv/opencv_zoo/resolve/main/{OPENCV_ZOO_DIR}/{file}",
    )


MASKRCNN_ZOO_CONTRACT = (
    "input image float [3,H,W] BGR 0-255 minus the mean (102.9801, 115.9465, 122.7717), short "
    "side about 800, sides padded to multiples of 32; outputs boxes [N,4] (x1,y1,x2,y2), "
    "labels [N] (COCO, person = 1), scores [N], masks [N,1,28,28] (probabilities in the box)"
)
YOUTU_CONTRACT = (
    "input [1,3,256,128] RGB float, /255 then ImageNet mean/std; output [1,768] (cosine)"
)
MASKRCNN_ZOO_SOURCE = (
    "ONNX Model Zoo (github.com/onnx/models, " + ONNX_ZOO_DIR + "; mirror "
    "huggingface.co/onnxmodelzoo/legacy_models): Mask R-CNN R-50-FPN trained on COCO, the "
    "detector network the DensePeds paper uses"
)
YOUTU_SOURCE = (
    "OpenCV Zoo (github.com/opencv/opencv_zoo, " + OPENCV_ZOO_DIR + "; mirror "
    "huggingface.co/opencv/opencv_zoo): YoutuReID person re-ID"
)

MODELS: dict[str, ModelInfo] = {
    m.name: m
    for m in (
        ModelInfo(
            name="maskrcnn-zoo-int8",
            file="MaskRCNN-12-int8.onnx",
            role="detector (--detector maskrcnn), fetched by default: Mask R-CNN R-50-FPN (the "
            "paper's detector network), int8 weights",
            licence="MIT (ONNX Model Zoo)",
            contract=MASKRCNN_ZOO_CONTRACT,
            source=MASKRCNN_ZOO_SOURCE + ", quantised to int8 by the zoo",
            sha256="4409935e855719fd6cd986f7ec2a3de840d0bd9c9cf7a0cba84ce95377f5b476",
            size=45769352,
            urls=_onnx_zoo("MaskRCNN-12-int8.onnx"),
            detector="maskrcnn",
        ),
        ModelInfo(
            name="maskrcnn-zoo",
            file="MaskRCNN-12.onnx",
            role="detector (--detector maskrcnn): Mask R-CNN R-50-FPN (the paper's detector "
            "network), float weights; used in place of the int8 copy where present",
            licence="MIT (ONNX Model Zoo)",
            contract=MASKRCNN_ZOO_CONTRACT,
            source=MASKRCNN_ZOO_SOURCE,
            sha256="5bf940c124d9117f6fae350c4e0d46df180cbb01981832b35fdbed148078b946",
            size=177970010,
            urls=_onnx_zoo("MaskRCNN-12.onnx"),
            detector="maskrcnn",
        ),
        ModelInfo(
            name="youtureid-int8",
            file="person_reid_youtu_2021nov_int8.onnx",
            role="re-ID (--reid-model), fetched by default: YoutuReID, int8 weights",
            licence="Apache-2.0 (OpenCV Zoo)",
            contract=YOUTU_CONTRACT,
            source=YOUTU_SOURCE + ", quantised to int8 by the zoo",
            sha256="4757c4cb759b79030a9870abf29c064c2ee51e079a05700690800c81b16cf245",
            size=26763574,
            urls=_opencv_zoo("person_reid_youtu_2021nov_int8.onnx"),
        ),
        ModelInfo(
            name="youtureid",
            file="person_reid_youtu_2021nov.onnx",
            role="re-ID (--reid-model): YoutuReID, float weights; used in place of the int8 "
            "copy where present",
            licence="Apache-2.0 (OpenCV Zoo)",
            contract=YOUTU_CONTRACT,
            source=YOUTU_SOURCE,
            sha256="0579683334d4b9440221606dcb461656dd0dc64143b18f48faedaced9b4f580d",
            size=106878407,
            urls=_opencv_zoo("person_reid_youtu_2021nov.onnx"),
        ),
        ModelInfo(
            name="yoloseg",
            file="yolov8n-seg-320-int8.onnx",
            role="detector (--detector yoloseg, the default where there are frames)",
            licence="AGPL-3.0 (Ultralytics YOLOv8n-seg weights, quantised by STMicroelectronics: "
            "a program or service that uses them must publish its source under the AGPL)",
            contract="input [1,320,320,3] NHWC RGB float in [0,1], letterboxed; outputs "
            "[1,116,2100] (cx,cy,w,h normalised, 80 COCO class scores, 32 mask coefficients) and "
            "[1,80,80,32] mask prototypes",
            source="no published ONNX: STMicroelectronics publish this int8 model as TFLite "
            "only (github.com/stm32-hotspot/ultralytics, examples/YOLOv8-STEdgeAI/"
            "stedgeai_models/segmentation/yolov8n_320_quant_pc_uf_seg_coco-st.tflite) and this "
            "file is its tf2onnx conversion",
            sha256="22ba5adca763b8f0741efdf66d95836e90222bb09f33a266ad99663b112f9257",
            size=3660283,
            detector="yoloseg",
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
            role="detector (--detector maskrcnn): torchvision's Mask R-CNN, exported by you",
            licence="BSD-3-Clause (torchvision code and COCO weights)",
            contract="input image [3,H,W] RGB float in [0,1]; outputs boxes [N,4], labels [N], "
            "scores [N], masks [N,1,H,W]",
            source="made locally: pip install 'densepeds[export]' then "
            "python models/export_maskrcnn.py --weights coco (from a source checkout), then "
            "densepeds models install maskrcnn_resnet50_fpn.onnx",
            detector="maskrcnn",
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
MODELS["yoloseg-export"] = ModelInfo(
    name="yoloseg-export",
    file="yolov8n-seg-320.onnx",
    role="detector (--detector yoloseg): YOLOv8n-seg exported by `densepeds models export "
    "yoloseg`; used where the shipped int8 file is absent",
    licence="AGPL-3.0 (Ultralytics YOLOv8n-seg weights: a program or service that uses them "
    "must publish its source under the AGPL)",
    contract="input [1,3,320,320] NCHW RGB float in [0,1], letterboxed; outputs [1,116,2100] "
    "(cx,cy,w,h in input pixels, 80 COCO class scores, 32 mask coefficients) and [1,32,80,80] "
    "mask prototypes",
    source="made locally: pip install 'densepeds[export]' ultralytics, then densepeds models "
    "export yoloseg (Ultralytics downloads yolov8n-seg.pt from github.com/ultralytics/assets)",
    detector="yoloseg",
)
MODELS["osnet-export"] = ModelInfo(
    name="osnet-export",
    file="osnet_x0_25_msmt17-export.onnx",
    role="re-ID (--reid-model): OSNet x0.25 exported by `densepeds models export osnet`; used "
    "where the shipped osnet file is absent",
    licence=MODELS["osnet"].licence,
    contract="input [N,3,256,128] RGB float, /255 then ImageNet mean/std; output [N,512]",
    source="made locally: pip install 'densepeds[export]' torchreid, download torchreid's "
    "osnet_x0_25 MSMT17 weights (its model zoo page), then densepeds models export osnet "
    "--weights FILE.pth",
)
BY_FILE: dict[str, ModelInfo] = {m.file: m for m in MODELS.values()}

# What `densepeds models fetch` gets with no names, and the order in which `densepeds run` takes
# a detector / re-ID model when several are present (see the module docstring).
DEFAULT_SET = ("maskrcnn-zoo-int8", "youtureid-int8")
DETECTOR_ORDER = ("yoloseg", "yoloseg-export", "maskrcnn-zoo", "maskrcnn-zoo-int8", "maskrcnn")
REID_ORDER = ("osnet", "osnet-export", "youtureid", "youtureid-int8")


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
    """The first ``file`` found in :func:`search_dirs`, or None. A folder that cannot be read
    (no permission, a name too long, ...) is passed over: later folders are still searched."""
    for folder in search_dirs():
        candidate = folder / file
        if _is_file(candidate):
            return candidate
    return None


def _is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except OSError:
        return False


def folder_state(folder: Path) -> str:
    """'' for a readable folder, else why it is not searched: ' (missing)', ' (unreadable: ...)'."""
    try:
        if not folder.is_dir():
            return " (missing)"
        os.listdir(folder)
    except OSError as err:
        return f" (unreadable: {err.strerror or err})"
    return ""


def _present(name: str) -> bool:
    return locate(MODELS[name].file) is not None


def default_detector(model: str | os.PathLike[str] | None = None) -> str:
    """The detector kind ``densepeds run`` uses when none is asked for: for a given ``model``
    file, the kind of the known model of that name (else yoloseg); otherwise that of the first
    model of DETECTOR_ORDER present, else the default set's (whose missing file then names the
    fetch command)."""
    if model is not None:
        known = BY_FILE.get(Path(model).name)
        return known.detector if known is not None and known.detector else "yoloseg"
    for name in DETECTOR_ORDER:
        if _present(name):
            return MODELS[name].detector or "yoloseg"
    return next(MODELS[n].detector for n in DEFAULT_SET if MODELS[n].detector) or "maskrcnn"


def default_model_file(kind: str) -> str:
    """The model file a detector of ``kind`` loads when given none: the first present of its
    models in DETECTOR_ORDER, else its first in the default set (else in the order)."""
    names = [n for n in DETECTOR_ORDER if MODELS[n].detector == kind]
    for name in names:
        if _present(name):
            return MODELS[name].file
    fallback = [n for n in DEFAULT_SET if n in names] + names
    if not fallback:
        raise ModelError(f"no model is known for detector kind {kind!r}")
    return MODELS[fallback[0]].file


def default_reid_file() -> str:
    """The re-ID model file used when none is given: the first present of REID_ORDER, else the
    default set's."""
    for name in REID_ORDER:
        if _present(name):
            return MODELS[name].file
    return next(MODELS[n].file for n in DEFAULT_SET if n in REID_ORDER)


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
    if info.name in DEFAULT_SET:
        return (
            f"run `densepeds models fetch` (downloads {', '.join(DEFAULT_SET)}; or "
            f"`densepeds models install FILE` with a copy you have)"
        )
    if info.urls or os.environ.get(URL_ENV_VAR):
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
        if not _is_file(path):
            raise ModelError(f"model file {path} does not exist ({how_to_get(path.name)})")
        return path
    direct = Path(name).expanduser()
    if _is_file(direct):
        return direct
    if os.sep in name or (os.altsep and os.altsep in name):
        raise ModelError(f"model file {direct} does not exist ({how_to_get(direct.name)})")
    found = locate(name)
    if found is not None:
        return found
    where = ", ".join(f"{d}{folder_state(d)}" for d in search_dirs())
    raise ModelError(
        f"model {name} not found (looked in {where}; `densepeds models` lists what is where). "
        f"To get it: {how_to_get(name)}"
    )
