"""``densepeds models export yoloseg|osnet``: the official exporters, checked and installed.

- ``yoloseg``: Ultralytics' own ONNX export of YOLOv8n-seg at 320 px (``ultralytics``, installed
  by you: its code and weights are AGPL-3.0, and it brings ``opencv-python`` beside our
  ``opencv-python-headless``; a separate environment avoids that, then ``densepeds models
  install`` the file). ``--weights`` defaults to ``yolov8n-seg.pt``, which Ultralytics downloads.
- ``osnet``: torchreid's OSNet x0.25 (the ``export`` extra: torch, torchreid), the MSMT17 weights
  given as a file (torchreid publishes them on its model zoo page, behind Google Drive), exported
  with ``torch.onnx.export`` at [N,3,256,128] with a dynamic batch.

``random=True`` builds the architecture from the exporter's own config with random weights (no
download): the contract is the same, for testing the path. Each file is checked with the
detector / re-ID class that will read it (and OSNet's embeddings against torch's own on the same
crops) before it is copied into the cache under the name ``densepeds models`` lists
(``yoloseg-export``, ``osnet-export``).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from densepeds.errors import ModelError
from densepeds.models.files import MODELS, cache_dir

IMAGE_SIZE = 320  # yoloseg's input side, as the shipped model's
REID_HW = (256, 128)
EXTRA = "pip install 'densepeds[export]'"


def export(
    model: str,
    weights: str | None = None,
    *,
    random: bool = False,
    dest_dir: str | os.PathLike[str] | None = None,
) -> Path:
    """Export ``model`` ('yoloseg' | 'osnet'), check it, install it; returns the installed path."""
    from densepeds.models.fetch import copy_into, make_dir

    dest = Path(dest_dir).expanduser() if dest_dir is not None else cache_dir()
    with tempfile.TemporaryDirectory(prefix="densepeds-export-") as tmp:
        if model == "yoloseg":
            made = _export_yoloseg(Path(tmp), weights, random)
            _check_yoloseg(made)
            name = "yoloseg-export"
        elif model == "osnet":
            made = _export_osnet(Path(tmp), weights, random)
            name = "osnet-export"
        else:
            raise ModelError(f"can export yoloseg or osnet, not {model!r}")
        make_dir(dest)
        try:
            return copy_into(made, dest / MODELS[name].file)
        except OSError as err:
            raise ModelError(f"cannot install {made.name} into {dest}: {err}") from err


def _require(module: str, how: str) -> Any:
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as err:
        raise ModelError(f"the export needs {module} ({err}); {how}") from None


def _export_yoloseg(tmp: Path, weights: str | None, random: bool) -> Path:
    ultralytics = _require(
        "ultralytics",
        "pip install ultralytics (AGPL-3.0; best in an environment of its own, see "
        "models/README.md)",
    )
    if random:
        source = "yolov8n-seg.yaml"  # the architecture from Ultralytics' own config
    elif weights is None:
        source = "yolov8n-seg.pt"
    else:
        given = Path(weights).expanduser()
        source = str(given.resolve()) if given.exists() else weights
    here = Path.cwd()
    os.chdir(tmp)  # Ultralytics writes downloads and exports beside the weights / in the cwd
    try:
        net = ultralytics.YOLO(source)
        out = net.export(format="onnx", imgsz=IMAGE_SIZE, opset=17, dynamic=False, simplify=False)
    except Exception as err:  # noqa: BLE001 (the exporter's own failures, in one line)
        raise ModelError(f"Ultralytics' export of {source} failed: {err}") from None
    finally:
        os.chdir(here)
    made = Path(str(out))
    if not made.is_absolute():
        made = tmp / made
    if not made.is_file():
        raise ModelError(f"Ultralytics' export of {source} wrote no file ({out})")
    return made


def _check_yoloseg(path: Path) -> None:
    """Loads as a yoloseg detector and runs a grey frame (ModelError otherwise)."""
    from densepeds.detect.yoloseg import YoloSegDetector

    detector = YoloSegDetector(path, tiles=None, threads=1)
    detector(np.full((IMAGE_SIZE, IMAGE_SIZE, 3), 114, np.uint8))


def _export_osnet(tmp: Path, weights: str | None, random: bool) -> Path:
    torch = _require("torch", EXTRA)
    torchreid = _require("torchreid", EXTRA)
    if weights is None and not random:
        raise ModelError(
            "osnet: give torchreid's osnet_x0_25 MSMT17 weights with --weights FILE.pth (its "
            "model zoo page), or --random for the untrained architecture"
        )
    net = torchreid.models.build_model("osnet_x0_25", num_classes=1000, pretrained=False)
    if weights is not None:
        _load_backbone(torch, net, Path(weights).expanduser())
    net.eval()
    crops = torch.rand(3, 3, *REID_HW)
    made = tmp / MODELS["osnet-export"].file
    try:
        torch.onnx.export(
            net,
            crops[:1],
            str(made),
            opset_version=17,
            dynamo=False,
            input_names=["input"],
            output_names=["embedding"],
            dynamic_axes={"input": {0: "batch"}, "embedding": {0: "batch"}},
        )
    except Exception as err:  # noqa: BLE001
        raise ModelError(f"torch's ONNX export of OSNet failed: {err}") from None
    with torch.no_grad():
        want = net(crops).numpy()
    _check_osnet(made, crops.numpy(), want)
    return made


def _load_backbone(torch: Any, net: Any, path: Path) -> None:
    """torchreid's weights into ``net``: every layer but the classifier must match."""
    if not path.is_file():
        raise ModelError(f"{path}: no such weights file")
    try:
        state = torch.load(str(path), map_location="cpu", weights_only=True)
    except Exception as err:  # noqa: BLE001
        raise ModelError(f"{path}: not a torch weights file ({err})") from None
    state = state.get("state_dict", state)
    state = {k.removeprefix("module."): v for k, v in state.items()}
    own = net.state_dict()
    backbone = [k for k in own if not k.startswith("classifier.")]
    missing = [k for k in backbone if k not in state or state[k].shape != own[k].shape]
    if missing:
        raise ModelError(
            f"{path}: not osnet_x0_25 weights ({len(missing)} of its {len(backbone)} layers "
            f"missing or of another shape, e.g. {missing[0]})"
        )
    net.load_state_dict({k: state[k] for k in backbone}, strict=False)


def _check_osnet(path: Path, crops_rgb01: np.ndarray, want: np.ndarray) -> None:
    """Reads as a re-ID model of width 512, and onnxruntime matches torch on the same crops."""
    import onnxruntime as ort

    from densepeds.reid import ReID

    reid = ReID(path, threads=1)
    if reid.dim != 512:
        raise ModelError(f"{path}: embedding width {reid.dim}, expected 512")
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    got = session.run(None, {"input": crops_rgb01.astype(np.float32)})[0]
    if got.shape != want.shape or not np.allclose(got, want, rtol=1e-3, atol=1e-4):
        raise ModelError(f"{path}: onnxruntime's embeddings differ from torch's")
