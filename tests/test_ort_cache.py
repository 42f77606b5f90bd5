"""The on-disk cache of optimised onnxruntime graphs, and reading model metadata without onnx."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import onnx
import onnxruntime as ort
import pytest
from conftest import REPO, shared_path
from densepeds.detect import onnxutil
from densepeds.detect.yoloseg import YoloSegDetector
from densepeds.errors import ModelError
from densepeds.reid import ReID
from onnx import TensorProto, helper
from test_detect import video_frames

YOLO = "yolov8n-seg-320-int8.onnx"
OSNET = "osnet_x0_25_msmt17.onnx"


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "ort"
    monkeypatch.setenv(onnxutil.ORT_CACHE_ENV, str(folder))
    return folder


def tiny_model(path: Path, props: dict[str, str] | None = None, scale: float = 2.0) -> Path:
    """y = x * scale, batch fixed to 1, with metadata ``props``."""
    const = helper.make_tensor("k", TensorProto.FLOAT, [1], [scale])
    graph = helper.make_graph(
        [helper.make_node("Mul", ["x", "k"], ["y"])],
        "tiny",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, [1, 4])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, [1, 4])],
        initializer=[const],
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    helper.set_model_props(model, props or {})
    onnx.save(model, str(path))
    return path


def test_metadata_read_without_onnx_matches_onnx(tmp_path: Path) -> None:
    props = {"densepeds.quantized_from_sha256": "ab" * 32, "note": "ünïcode, commas, = signs"}
    files = [
        tiny_model(tmp_path / "m.onnx", props),
        tiny_model(tmp_path / "empty-entry.onnx", {"": ""}),
        shared_path("models", OSNET),
        shared_path("models", YOLO),
    ]
    for path in files:
        expected = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
        assert onnxutil.model_metadata(path) == expected
    assert onnxutil.model_metadata(files[0]) == props
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"\xff\xff\xff not protobuf")
    with pytest.raises(ModelError, match="not a readable ONNX model"):
        onnxutil.model_metadata(bad)
    for truncated in (b"", files[0].read_bytes()[:-3]):
        bad.write_bytes(truncated)
        with pytest.raises(ModelError, match="not a readable ONNX model"):
            onnxutil.model_metadata(bad)
    with pytest.raises(ModelError, match="not a readable ONNX model"):
        onnxutil.model_metadata(tmp_path / "missing.onnx")


def test_cached_session_is_reused_and_rebuilt_when_model_or_ort_changes(
    tmp_path: Path, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model = tiny_model(tmp_path / "m.onnx")
    x = np.arange(4, dtype=np.float32)[None]
    session, rewritten = onnxutil.batched_session(model, 1)
    files = sorted(cache.glob("*.onnx"))
    assert rewritten and len(files) == 1  # batch 1 -> dynamic, saved once
    assert np.array_equal(session.run(None, {"x": x})[0], 2 * x)

    def no_load(path: Path) -> None:
        raise AssertionError("the model was loaded again instead of the cached graph")

    with monkeypatch.context() as m:
        m.setattr(onnxutil, "load_model", no_load)
        again, rewritten_again = onnxutil.batched_session(model, 1)
    assert rewritten_again  # the flag travels in the cached graph's metadata
    both = np.concatenate([x, x + 1])  # the cached graph still takes any batch
    assert np.array_equal(again.run(None, {"x": both})[0], 2 * both)

    tiny_model(model, scale=3.0)  # same file name, new bytes: a new graph, not the stale one
    changed, _ = onnxutil.batched_session(model, 1)
    assert np.array_equal(changed.run(None, {"x": x})[0], 3 * x)
    assert len(list(cache.glob("*.onnx"))) == 2

    monkeypatch.setattr(ort, "__version__", "0.0.0-other")
    onnxutil.batched_session(model, 1)
    assert len(list(cache.glob("*.onnx"))) == 3
    onnxutil.batched_session(model, 1, dequantize=True)  # another rewriting: another graph
    assert len(list(cache.glob("*.onnx"))) == 4
    assert not list(cache.glob(".*.tmp"))


def test_cache_keeps_the_graphs_used_last(
    tmp_path: Path, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(onnxutil, "ORT_CACHE_KEEP", 2)
    models = [tiny_model(tmp_path / f"m{k}.onnx", scale=float(k + 2)) for k in range(3)]
    x = np.ones((1, 4), np.float32)
    onnxutil.batched_session(models[0], 1)
    first = sorted(cache.glob("*.onnx"))
    os.utime(first[0], (1, 1))  # made long ago...
    onnxutil.batched_session(models[0], 1)  # ...but used now: its time stamp moves
    assert first[0].stat().st_mtime > 1
    onnxutil.batched_session(models[1], 1)
    (stale,) = [f for f in cache.glob("*.onnx") if f not in first]
    os.utime(stale, (2, 2))  # the least recently used of the two
    onnxutil.batched_session(models[2], 1)  # a third graph: the stale one goes
    kept = sorted(cache.glob("*.onnx"))
    assert len(kept) == 2 and stale not in kept and first[0] in kept
    session, _ = onnxutil.batched_session(models[1], 1)  # made again when asked for
    assert np.array_equal(session.run(None, {"x": x})[0], 3 * x)


def test_damaged_or_unwritable_cache_still_gives_a_session(
    tmp_path: Path, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model = tiny_model(tmp_path / "m.onnx")
    x = np.ones((1, 4), np.float32)
    onnxutil.batched_session(model, 1)
    (entry,) = cache.glob("*.onnx")
    entry.write_bytes(entry.read_bytes()[:100])  # e.g. a full disk
    session, _ = onnxutil.batched_session(model, 1)
    assert np.array_equal(session.run(None, {"x": x})[0], 2 * x)
    assert onnxutil._cached_session(entry, 1) is not None  # written again, whole
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv(onnxutil.ORT_CACHE_ENV, str(blocker / "ort"))  # cannot be made
    session, _ = onnxutil.batched_session(model, 1)
    assert np.array_equal(session.run(None, {"x": x})[0], 2 * x)
    monkeypatch.setenv(onnxutil.ORT_CACHE_ENV, "off")
    assert onnxutil.optimised_file(model, "", 1) is None


def _outputs(det: YoloSegDetector, reid: ReID, frames: list[np.ndarray]) -> list[np.ndarray]:
    """Per frame: boxes, scores, mask boxes, all mask pixels, embeddings."""
    out = []
    for frame in frames:
        d = det(frame)
        masks = [np.ravel(m) for m in d.masks or []]
        out += [d.boxes, d.scores, np.asarray(d.mask_boxes), np.concatenate(masks)]
        out.append(reid.embed(frame, d))
    return out


def test_cached_graphs_give_bitwise_the_same_detections_and_embeddings(
    cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    video = shared_path("data", "PETS09-S2L1-dev", "vtest.avi")
    frames = list(video_frames(video, [1, 2, 3]).values())
    yolo, osnet = shared_path("models", YOLO), shared_path("models", OSNET)
    results = {}
    for mode in ("off", "cold", "warm"):
        monkeypatch.setenv(onnxutil.ORT_CACHE_ENV, "off" if mode == "off" else str(cache))
        det = YoloSegDetector(yolo, tiles=(2, 2), threads=2, quantized=False)
        # The int8 graph as shipped (QDQ), which onnxruntime fuses into integer kernels.
        qdq = YoloSegDetector(yolo, tiles=(2, 2), threads=2, quantized=False, dequantize=False)
        reid = ReID(osnet, threads=2)
        outputs = _outputs(det, reid, frames) + _outputs(qdq, reid, frames)
        results[mode] = (outputs, det.rewritten, qdq.rewritten, reid.rewritten)
        if mode == "cold":  # the float copy at its own size and cut to the tiles' shape,
            # the graph as shipped (its int8 anchors stay: its own size), OSNet
            assert len(list(cache.glob("*.onnx"))) == 4
    base, *flags = results["off"]
    assert sum(len(a) for a in base[::5]) > 20  # people found: the comparison means something
    for mode in ("cold", "warm"):
        outputs, *mode_flags = results[mode]
        assert mode_flags == flags
        assert all(np.array_equal(a, b) for a, b in zip(outputs, base, strict=True))


def _imported(code: str, env: dict[str, str]) -> set[str]:
    out = subprocess.run(
        [sys.executable, "-c", code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
        capture_output=True,
        text=True,
        check=True,
        env=env,
        cwd=REPO,
    ).stdout
    return {name.split(".")[0] for name in json.loads(out.splitlines()[-1])}


def test_imports_stay_light(cache: Path) -> None:
    env = {**os.environ, onnxutil.ORT_CACHE_ENV: str(cache)}
    heavy = {"onnx", "onnxruntime", "cv2", "numpy", "scipy", "trackeval", "matplotlib", "torch"}
    assert not _imported("import densepeds", env) & heavy
    # A start with the optimised graphs cached does not import onnx (nor scoring's modules).
    yolo, osnet = shared_path("models", YOLO), shared_path("models", OSNET)
    make = (
        "from pathlib import Path\n"
        "from densepeds.detect.yoloseg import YoloSegDetector\n"
        "from densepeds.reid import ReID\n"
        f"YoloSegDetector(Path({str(yolo)!r}), quantized=False)\n"
        f"ReID(Path({str(osnet)!r}))\n"
    )
    assert "onnx" in _imported(make, env)  # cold: the models are rewritten
    warm = _imported(make, env)
    assert "onnxruntime" in warm and not warm & {"onnx", "scipy", "trackeval", "matplotlib"}


def test_a_run_without_a_terminal_imports_no_progress_bar(tmp_path: Path) -> None:
    seq = shared_path("data", "TUD-Stadtmitte")
    out = tmp_path / "t.txt"
    args = ["run", str(seq), "--frames", "1:5", "--out", str(out)]
    run = f"from densepeds.cli import main\nmain({args!r})"
    modules = _imported(run, dict(os.environ))
    assert out.stat().st_size > 0 and "densepeds" in modules
    assert not modules & {"tqdm", "onnx", "multiprocessing"}


@pytest.mark.parametrize("caching", ["off", "on"])
def test_dequantize_applies_to_a_model_with_a_dynamic_batch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, caching: str
) -> None:
    """``dequantize`` runs the float copy (no activation rounding) also when the model needs no
    batch rewrite, with the cache off or on."""
    scale = helper.make_tensor("s", TensorProto.FLOAT, [], [0.1])
    zero = helper.make_tensor("z", TensorProto.INT8, [], [0])
    graph = helper.make_graph(
        [
            helper.make_node("QuantizeLinear", ["x", "s", "z"], ["q"]),
            helper.make_node("DequantizeLinear", ["q", "s", "z"], ["y"]),
        ],
        "qdq",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["batch", 4])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["batch", 4])],
        [scale, zero],
    )
    path = tmp_path / "qdq.onnx"
    onnx.save(helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)]), path)
    monkeypatch.setenv(onnxutil.ORT_CACHE_ENV, "off" if caching == "off" else str(tmp_path / "c"))
    x = np.full((2, 4), 0.123, np.float32)
    rounded, _ = onnxutil.batched_session(path, 1)
    assert np.allclose(rounded.run(None, {"x": x})[0], 0.1)  # the QDQ graph as it is
    plain, rewritten = onnxutil.batched_session(path, 1, dequantize=True)
    assert not rewritten
    np.testing.assert_array_equal(plain.run(None, {"x": x})[0], x)
