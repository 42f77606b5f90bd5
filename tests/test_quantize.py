"""The int8 copy of the segmenter (`densepeds models quantize`, densepeds.models.quantize): really
integer, recorded, reproducible, agreeing with the float copy on frames it was not calibrated
on, and picked by the detector only where it belongs to the model."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import onnx
import pytest
from conftest import shared_path
from densepeds.boxes import iou_matrix
from densepeds.cli import main
from densepeds.detect.yoloseg import YoloSegDetector, choose_model
from densepeds.errors import ModelError, ParameterError
from densepeds.io.video import open_source, parse_frame_range
from densepeds.models import quantize
from densepeds.models.files import ENV_VAR, MODELS, quantized_file_name, sha256_of
from densepeds.pipeline import suppress_duplicates
from densepeds.presets import get_preset

YOLO = MODELS["yoloseg"]
INT8 = MODELS["yoloseg-int8"]
# PETS09-S2L1 frames after the dev range (1-397) the accuracy grid scores.
CALIBRATION = "@700:712/6"  # frames 700, 706, 712; the check runs on 701, 707


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(model folder holding the shipped model and its int8 copy, the CLI's output folder)."""
    model = shared_path("models", YOLO.file)
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    out = tmp_path_factory.mktemp("quantized")
    rc = main(["models", "quantize", "--calibrate", f"{video}{CALIBRATION}", "--dir", str(out)])
    assert rc == 0
    folder = tmp_path_factory.mktemp("models")
    shutil.copyfile(model, folder / model.name)
    name = quantized_file_name(model)
    shutil.copyfile(out / name, folder / name)
    return folder, out


def _frame(number: int) -> np.ndarray:
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    return next(img for _, img in open_source(video).frames(parse_frame_range(str(number))))


def test_the_copy_runs_integer_convolutions_and_records_its_source(
    made: tuple[Path, Path],
) -> None:
    folder, _ = made
    path = folder / quantized_file_name(YOLO.file)
    model = onnx.load(str(path))
    inits = {i.name: i for i in model.graph.initializer}
    producer = {o: n for n in model.graph.node for o in n.output}

    def int8_weight(conv: onnx.NodeProto) -> bool:
        dq = producer.get(conv.input[1])
        return (
            dq is not None
            and dq.op_type == "DequantizeLinear"
            and inits[dq.input[0]].data_type == onnx.TensorProto.INT8
        )

    convs = [n for n in model.graph.node if n.op_type == "Conv"]
    integer = {n.name for n in convs if int8_weight(n)}
    # The body's convolutions have int8 weights; the head's and the first one stay float.
    float_copy = quantize.float_copy(shared_path("models", YOLO.file))
    by_name = {n.name: n for n in float_copy.graph.node}
    left = {n for n in quantize.float_nodes(float_copy) if by_name[n].op_type == "Conv"}
    assert len(convs) == sum(n.op_type == "Conv" for n in float_copy.graph.node)
    assert integer == {n.name for n in convs} - left and len(integer) > 50
    meta = quantize.metadata(path)
    assert meta[quantize.META_SOURCE] == sha256_of(shared_path("models", YOLO.file))
    assert "vtest.avi frames 700:712 every 6; 3 frames" in meta[quantize.META_CALIBRATION]


def test_float_nodes_are_the_head_and_the_first_convolution() -> None:
    model = quantize.float_copy(shared_path("models", YOLO.file))
    kept = quantize.float_nodes(model)
    by_name = {n.name: n for n in model.graph.node}
    producer = {o: n for n in model.graph.node for o in n.output}
    convs = [n for n in model.graph.node if n.op_type == "Conv"]
    assert convs[0].name in kept
    # Every output is computed from float nodes back to a convolution fed by an activation.
    stack = [o.name for o in model.graph.output]
    while stack:
        node = producer.get(stack.pop())
        if node is None:
            continue
        assert node.name in kept, node.name
        if node.op_type == "Conv" and producer[node.input[0]].op_type == "Mul":
            continue
        stack.extend(node.input)
    kinds = {by_name[n].op_type for n in kept}
    assert {"Softmax", "Concat", "Sigmoid", "Conv"} <= kinds
    # The body stays integer: few of the convolutions are left out.
    assert sum(by_name[n].op_type == "Conv" for n in kept) < len(convs) // 4


def test_the_copy_finds_the_float_copys_people(made: tuple[Path, Path]) -> None:
    folder, _ = made
    model = folder / YOLO.file
    ref = YoloSegDetector(model, quantized=False)
    low = YoloSegDetector(model)  # finds the copy beside the model
    assert low.quantized and low.path.name == quantized_file_name(model)
    assert not ref.quantized
    # The float copy's confident detections that the yoloseg preset hands the tracker: a part
    # of a person it reports too (shorter than min_height, or a duplicate) is nobody to find,
    # and whether the int8 copy reports it as well depends on the CPU's integer kernels.
    opt = get_preset("yoloseg").detection
    for number in (50, 300, 701):  # none of them calibrated on
        frame = _frame(number)
        a, b = ref(frame), low(frame)
        kept = a.subset(
            suppress_duplicates(a, opt["nms_iou"], opt["nms_containment"], opt["nms_mask_overlap"])
        )
        tall = kept.boxes[:, 3] - kept.boxes[:, 1] >= opt["min_height"]
        a_boxes = kept.boxes[(kept.scores >= 0.3) & tall]
        assert len(a_boxes) >= 3
        found = iou_matrix(a_boxes, b.boxes).max(axis=1) >= 0.5
        assert found.mean() >= 0.9, (number, found)
        assert b.masks is not None and len(b.masks) == len(b)


def test_same_inputs_give_the_same_file(made: tuple[Path, Path], tmp_path: Path) -> None:
    _, out = made
    model = shared_path("models", YOLO.file)
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    again = quantize.quantize_detector(
        model, tmp_path / "again.onnx", [quantize.parse_calibration(f"{video}{CALIBRATION}")]
    )
    assert sha256_of(again) == sha256_of(out / quantized_file_name(model))


def test_choice_of_model(
    made: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder, out = made
    model = shared_path("models", YOLO.file)
    copy = quantized_file_name(model)
    lonely = tmp_path / "alone"
    lonely.mkdir()
    shutil.copyfile(model, lonely / model.name)
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "none"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert choose_model(lonely / model.name, None) == lonely / model.name
    assert choose_model(lonely / model.name, False) == lonely / model.name
    with pytest.raises(ModelError, match="densepeds models quantize"):
        choose_model(lonely / model.name, True)
    # Found in the model folders as well as beside the model.
    monkeypatch.setenv(ENV_VAR, str(out))
    assert choose_model(lonely / model.name, True) == out / copy
    assert choose_model(folder / model.name, None) == folder / copy
    # The copy given directly is run as it is.
    assert choose_model(out / copy, None) == out / copy
    # A copy of another model under this model's name is refused, never used silently.
    other = tmp_path / "other"
    other.mkdir()
    changed = onnx.load(str(model))
    onnx.helper.set_model_props(changed, {"note": "another model"})
    onnx.save(changed, str(other / "yolo.onnx"))
    shutil.copyfile(out / copy, other / quantized_file_name("yolo.onnx"))
    with pytest.raises(ModelError, match="not made from"):
        choose_model(other / "yolo.onnx", None)


def test_the_listing_finds_the_copy(
    made: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    _, out = made
    monkeypatch.setenv(ENV_VAR, str(out))
    assert main(["models"]) == 0
    listing = capsys.readouterr().out
    assert f"{INT8.name}: {INT8.file}" in listing
    assert f"found: {out / quantized_file_name(YOLO.file)}" in listing
    assert "densepeds models quantize --calibrate VIDEO" in listing


def test_failed_check_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    argv = ["models", "quantize", "--calibrate", f"{video}@700:701", "--dir", str(tmp_path)]
    rc = main([*argv, "--min-agreement", "1.01"])
    err = capsys.readouterr().err
    assert rc == 2 and "nothing was written" in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_integer_dot_product_is_read_from_the_cpu_flags() -> None:
    assert quantize.integer_dot_product("flags\t: fpu sse avx2 avx512f avx512_vnni\n") is True
    assert quantize.integer_dot_product("flags\t: fpu sse avx2 fma\nflags : avx\n") is False
    assert quantize.integer_dot_product("Features\t: fp asimd asimddp\n") is True
    assert quantize.integer_dot_product("processor : 0\n") is None


@pytest.mark.parametrize("dot_product", [False, True, None])
def test_quantize_says_when_the_cpu_lacks_integer_dot_products(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    dot_product: bool | None,
) -> None:
    monkeypatch.setattr(quantize, "integer_dot_product", lambda: dot_product)
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    rc = main(
        ["models", "quantize", "--calibrate", f"{video}{CALIBRATION}", "--dir", str(tmp_path)]
    )
    out = capsys.readouterr().out
    assert rc == 0
    assert ("no integer dot-product instructions" in out) is (dot_product is False)


def test_bad_calibration_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    for spec in (f"{tmp_path}/missing.mp4", f"{tmp_path}@1:2/0"):
        rc = main(["models", "quantize", "--calibrate", spec, "--dir", str(tmp_path)])
        err = capsys.readouterr().err
        assert rc == 2 and len(err.strip().splitlines()) == 1, err


def test_the_run_summary_names_the_int8_copy(
    made: tuple[Path, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    folder, _ = made
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    argv = ["run", str(video), "--detector", "yoloseg", "--frames", "1:2", "-q"]
    copy = folder / quantized_file_name(YOLO.file)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    shared = shared_path("models", YOLO.file).parent  # the re-ID model; no int8 copy there
    monkeypatch.setenv(ENV_VAR, f"{folder}:{shared}")  # the model and its copy: picked up unasked
    assert main([*argv, "--out", str(tmp_path / "a.txt")]) == 0
    assert f"; detector: int8 copy {copy}" in capsys.readouterr().out
    alone = tmp_path / "alone"
    alone.mkdir()
    shutil.copyfile(folder / YOLO.file, alone / YOLO.file)
    monkeypatch.setenv(ENV_VAR, f"{alone}:{shared}")  # no copy: the float copy runs, unsaid
    assert main([*argv, "--out", str(tmp_path / "b.txt")]) == 0
    assert "int8 copy" not in capsys.readouterr().out


def test_options_are_checked_recorded_and_cached_ranges_reused(tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match="calibration must be one of"):
        quantize.QuantOptions(calibration="entropy")
    assert quantize.QuantOptions().describe() == "qdq U8S8 per-channel minmax"
    model = shared_path("models", YOLO.file)
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    inputs = [quantize.parse_calibration(f"{video}{CALIBRATION}")]
    options = quantize.QuantOptions(calibration="percentile", per_channel=False)
    cache = tmp_path / "ranges.json"
    first = quantize.quantize_detector(
        model, tmp_path / "a.onnx", inputs, options=options, calibration_cache=cache
    )
    assert cache.is_file()
    meta = quantize.metadata(first)
    assert meta[quantize.META_FORMAT] == f"qdq U8S8 per-tensor percentile-{quantize.PERCENTILE}"
    assert "3 frames" in meta[quantize.META_CALIBRATION]
    # The ranges come from the cache the second time: the same file.
    again = quantize.quantize_detector(
        model, tmp_path / "b.onnx", inputs, options=options, calibration_cache=cache
    )
    assert sha256_of(again) == sha256_of(first)
    assert quantize.metadata(again)[quantize.META_CALIBRATION] == meta[quantize.META_CALIBRATION]
