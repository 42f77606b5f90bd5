"""onnxruntime sessions on the CPU or a GPU, and dynamic-batch copies of fixed-batch models.

Every session is made here, on the execution providers :func:`providers` picks for the device
asked for (``densepeds.detect.DEVICES``): ``cpu`` onnxruntime's CPU provider; ``cuda`` NVIDIA's
CUDA provider (TensorRT's first where TensorRT's library is installed), which needs the ``gpu``
extra (``onnxruntime-gpu`` in place of ``onnxruntime``, with NVIDIA's CUDA and cuDNN wheels, which
``onnxruntime.preload_dlls`` loads) and a usable GPU, else a
:class:`~densepeds.errors.ParameterError` saying so; ``auto`` the GPU where one is usable, else
the CPU (a :class:`DeviceWarning` where a GPU provider is installed but cannot run);
``openvino`` the CPU through OpenVINO's runtime (:class:`OpenVinoSession`; ``pip install
openvino``), whose outputs on the shipped models are onnxruntime's to float rounding
(``tests/test_runtime.py``).

Batching all tiles (or all crops) into one call saves the per-call overhead and lets onnxruntime
parallelise over the batch; a model exported with batch fixed to 1 is rewritten once, in memory.

:func:`batched_session` keeps the graph onnxruntime makes of each model (rewritten and
optimised for this CPU) in an on-disk cache, ``$DENSEPEDS_ORT_CACHE`` (default
``$XDG_CACHE_HOME/densepeds/ort``, ``off`` for none), so that later starts load it as it is
instead of loading, rewriting and optimising the model again; a cached file is named by the
model file's sha256, the rewriting asked for, this module's code, the onnxruntime version, the
thread count and the CPU, so that a change of any of them makes a new one. Its outputs are
bitwise those of a session made from the model (tests/test_ort_cache.py). The folder keeps the
``ORT_CACHE_KEEP`` graphs used last (a file's time stamp is set at each use); older ones, such as
those an upgrade left behind, are removed when a new one is written. ``onnx`` itself is imported
only where a model is rewritten.
"""

from __future__ import annotations

import contextlib
import ctypes
import hashlib
import os
import platform
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import onnxruntime as ort

from densepeds.errors import ModelError, ParameterError

# Where a model runs (``--device``): see the module docstring.
DEVICES = ("auto", "cpu", "cuda", "openvino")

if TYPE_CHECKING:
    import onnx

BATCH_DIM = "batch"

CPU_PROVIDER = "CPUExecutionProvider"
CUDA_PROVIDER = "CUDAExecutionProvider"
TENSORRT_PROVIDER = "TensorrtExecutionProvider"
OPENVINO_HINT = "device openvino needs OpenVINO: pip install 'densepeds[openvino]'"
GPU_HINT = (
    "install the gpu extra (pip uninstall onnxruntime; pip install 'densepeds[gpu]') on a "
    "machine with an NVIDIA GPU and its driver"
)


class DeviceWarning(UserWarning):
    """``device="auto"``: a GPU provider is installed but cannot run; the CPU runs instead."""


def check_device(device: str) -> str:
    if device not in DEVICES:
        raise ParameterError(f"device must be one of {', '.join(DEVICES)}, got {device!r}")
    return device


def providers(device: str) -> list[str]:
    """The execution providers a session on ``device`` asks for, best first (the CPU last:
    onnxruntime runs there what the GPU's providers cannot). ``cuda`` without onnxruntime's CUDA
    provider is a ParameterError; ``auto`` then gives the CPU alone."""
    check_device(device)
    if device in ("cpu", "openvino"):  # OpenVINO's sessions take no onnxruntime providers
        return [CPU_PROVIDER]
    available = ort.get_available_providers()
    if CUDA_PROVIDER not in available:
        if device == "cuda":
            raise ParameterError(
                f"device cuda: this onnxruntime ({ort.__version__}) has no CUDA provider; "
                + GPU_HINT
            )
        return [CPU_PROVIDER]
    # onnxruntime-gpu lists TensorRT's provider whether or not TensorRT is installed.
    trt = [TENSORRT_PROVIDER] if TENSORRT_PROVIDER in available and tensorrt_installed() else []
    return [*trt, CUDA_PROVIDER, CPU_PROVIDER]


@cache
def tensorrt_installed() -> bool:
    """Whether TensorRT's library can be found (the system's, or the ``tensorrt`` wheels')."""
    import ctypes.util
    import importlib.util

    if ctypes.util.find_library("nvinfer") is not None:
        return True
    return any(importlib.util.find_spec(m) is not None for m in ("tensorrt", "tensorrt_libs"))


@cache
def _preload_gpu_libraries() -> None:
    """Load the CUDA and cuDNN libraries of NVIDIA's wheels (the gpu extra), where this
    onnxruntime can (``onnxruntime.preload_dlls``, 1.21 on); else the system's are used."""
    preload = getattr(ort, "preload_dlls", None)
    if preload is not None:
        with contextlib.suppress(Exception):  # none there: the system's, or no GPU session
            preload()


def on_gpu(session: ort.InferenceSession | OpenVinoSession) -> bool:
    """Whether ``session`` runs on a GPU provider (the CPU's runs only what they cannot)."""
    return session.get_providers()[0] in (CUDA_PROVIDER, TENSORRT_PROVIDER)


def session_device(session: ort.InferenceSession | OpenVinoSession) -> str:
    """The device ``session`` runs on, as a later session of the same model should ask for it."""
    if isinstance(session, OpenVinoSession):
        return "openvino"
    return "cuda" if on_gpu(session) else "cpu"


def session_threads(threads: int | None, device: str) -> int | None:
    """The threads of a model's session where its batches are split one part per CPU when
    ``threads`` is None (:mod:`densepeds.detect.split_batch`: one thread each); OpenVINO runs
    each batch whole, on every CPU (None)."""
    return threads if threads is not None or device == "openvino" else 1


@dataclass(frozen=True)
class _Arg:
    name: str
    shape: tuple[int | str, ...]
    type: str


_OV_TYPES = {"f32": "tensor(float)", "u8": "tensor(uint8)", "i64": "tensor(int64)"}


class OpenVinoSession:
    """The part of onnxruntime's ``InferenceSession`` this package calls, run by OpenVINO on the
    CPU: ``run(None, feed)`` (from several threads at once: one request per call),
    ``get_inputs``, ``get_outputs`` and ``get_providers``. Precision is held at f32, so that
    the outputs are onnxruntime's to float rounding (OpenVINO would otherwise pick bf16 on CPUs
    that have it); ``threads`` None uses every CPU."""

    PROVIDER = "OpenVINO"

    def __init__(self, data: str | bytes, threads: int | None) -> None:
        try:
            import openvino as ov
        except ImportError as err:
            raise ParameterError(OPENVINO_HINT) from err
        self.threads = threads or available_cpus()
        config = {
            "INFERENCE_NUM_THREADS": self.threads,
            "PERFORMANCE_HINT": "LATENCY",
            "INFERENCE_PRECISION_HINT": "f32",
        }
        try:
            core = ov.Core()
            with _own_signal_stack():
                self._compiled = core.compile_model(core.read_model(data), "CPU", config)
        except Exception as exc:  # OpenVINO raises its own RuntimeError types
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise ModelError(f"OpenVINO cannot load the model: {first}") from exc
        self._inputs = [self._arg(p, k) for k, p in enumerate(self._compiled.inputs)]
        self._outputs = [self._arg(p, k) for k, p in enumerate(self._compiled.outputs)]

    @staticmethod
    def _arg(port: object, index: int) -> _Arg:
        shape = port.get_partial_shape()  # type: ignore[attr-defined]
        dims = tuple(
            d.get_length() if d.is_static else f"dim{index}_{k}" for k, d in enumerate(shape)
        )
        kind = port.get_element_type().get_type_name()  # type: ignore[attr-defined]
        return _Arg(port.get_any_name(), dims, _OV_TYPES.get(kind, kind))  # type: ignore[attr-defined]

    def get_inputs(self) -> list[_Arg]:
        return list(self._inputs)

    def get_outputs(self) -> list[_Arg]:
        return list(self._outputs)

    def get_providers(self) -> list[str]:
        return [self.PROVIDER]

    def run(
        self,
        names: list[str] | None,
        feed: Mapping[str, np.ndarray],
        run_options: object = None,  # onnxruntime's RunOptions: OpenVINO has its own logging
    ) -> list[np.ndarray]:
        request = self._compiled.create_infer_request()
        result = request.infer(dict(feed))
        wanted = [a.name for a in self._outputs] if names is None else names
        by_name = {a.name: k for k, a in enumerate(self._outputs)}
        return [np.array(result[self._compiled.outputs[by_name[n]]]) for n in wanted]


class _StackT(ctypes.Structure):
    _fields_ = (("sp", ctypes.c_void_p), ("flags", ctypes.c_int), ("size", ctypes.c_size_t))


@contextlib.contextmanager
def _own_signal_stack() -> Iterator[None]:
    """Put the calling thread's alternate signal stack back after the block. OpenVINO's CPU
    plugin gives the thread that compiles a model a stack of its own and frees it with the
    model; Python runs its signal handlers on the alternate stack, so a Ctrl-C after such a
    model is gone would crash the process (tests/test_runtime.py)."""
    before = _StackT()
    try:
        sigaltstack = ctypes.CDLL(None).sigaltstack
        saved = sigaltstack(None, ctypes.byref(before)) == 0
    except (OSError, AttributeError, TypeError):  # no C library to ask (not POSIX)
        saved = False
    try:
        yield
    finally:
        if saved:
            sigaltstack(ctypes.byref(before), None)


def _provider_options(names: list[str]) -> list[str | tuple[str, dict[str, str]]]:
    """TensorRT builds an engine per input shape: kept on disk beside the optimised graphs."""
    folder = ort_cache_dir()
    if TENSORRT_PROVIDER not in names or folder is None:
        return list(names)
    trt = {"trt_engine_cache_enable": "True", "trt_engine_cache_path": str(folder / "tensorrt")}
    return [(n, trt) if n == TENSORRT_PROVIDER else n for n in names]


def _new_session(
    data: str | bytes, options: ort.SessionOptions, device: str
) -> ort.InferenceSession:
    """A session on ``device``'s providers; where a GPU was asked for and onnxruntime could not
    start it (no driver, no CUDA libraries, no GPU), ``cuda`` is a ParameterError and ``auto``
    warns once per session and runs on the CPU."""
    names = providers(device)
    if names[0] != CPU_PROVIDER:
        _preload_gpu_libraries()
    session = ort.InferenceSession(data, sess_options=options, providers=_provider_options(names))
    if names[0] != CPU_PROVIDER and not on_gpu(session):
        message = (
            f"onnxruntime lists {names[0]} but could not start it (no usable GPU, driver or "
            f"CUDA libraries); {GPU_HINT}"
        )
        if device == "cuda":
            raise ParameterError(f"device cuda: {message}")
        warnings.warn(f"device auto runs on the CPU: {message}", DeviceWarning, stacklevel=3)
    return session


@dataclass(frozen=True)
class TensorSpec:
    name: str
    shape: tuple[int | str | None, ...]
    dtype: str  # onnxruntime type string, e.g. "tensor(float)"


def load_model(path: Path) -> onnx.ModelProto:
    import onnx

    try:
        return onnx.load(str(path))
    except Exception as exc:  # onnx raises several unrelated types for a corrupt file
        raise ModelError(f"{path} is not a readable ONNX model: {exc}") from exc


_cpu_limit: int | None = None  # limit_cpus: this process's share of the CPUs


def available_cpus() -> int:
    """CPUs this process may run on (``taskset``/cgroup affinity), not all the machine has; at
    most the share :func:`limit_cpus` gave it."""
    try:
        cpus = max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    return cpus if _cpu_limit is None else min(cpus, _cpu_limit)


def limit_cpus(cpus: int | None) -> None:
    """This process runs on ``cpus`` of the CPUs it may use (None: all of them), as a batch
    worker given that share: sessions then split their batches and size their thread counts
    for that many, as ``densepeds run`` does for a machine of that size."""
    global _cpu_limit
    if cpus is not None and cpus < 1:
        raise ParameterError(f"cpus must be >= 1 or None, got {cpus}")
    _cpu_limit = cpus


def session_options(threads: int | None) -> ort.SessionOptions:
    if threads is not None and threads < 1:
        raise ParameterError(f"threads must be >= 1 or None, got {threads}")
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = threads or available_cpus()
    opts.inter_op_num_threads = 1
    opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    opts.log_severity_level = 3  # the int8 export triggers harmless deprecation warnings
    # Idle worker threads sleep instead of spinning: on a CPU shared with decoding, the
    # tracker or other processes, spinning burned ~40% more CPU time and was slower in wall
    # time too (benchmarks/results/speed.md). Outputs are unchanged.
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    # No memory arena: batches change size from frame to frame (focus views, crops), and an
    # arena grows to each new size and keeps it, so a long run's memory would keep growing
    # (benchmarks/results/memory.md). The cost is a malloc per tensor: nothing measurable at
    # the defaults, about 7% of the frame with the int8 copy on a fixed grid.
    opts.enable_cpu_mem_arena = False
    return opts


def make_session(
    model: onnx.ModelProto | Path,
    threads: int | None,
    *,
    device: str = "auto",
    save_optimised: Path | None = None,
) -> ort.InferenceSession:
    """A session for ``model`` on ``device`` (see :func:`providers`); ``save_optimised`` (CPU
    sessions) also writes onnxruntime's optimised graph there (atomically; where it cannot be
    written the session is made without it)."""
    data = str(model) if isinstance(model, Path) else model.SerializeToString()
    if device == "openvino":
        return OpenVinoSession(data, threads)  # type: ignore[return-value]
    # The shipped int8 export makes onnxruntime's default logger warn about a deprecated
    # attribute at every load; that is noise to a user, so only errors are logged.
    ort.set_default_logger_severity(3)
    options = session_options(threads)
    if save_optimised is not None and providers(device) == [CPU_PROVIDER]:
        session = _session_saving(data, options, save_optimised)
        if session is not None:
            return session
        options = session_options(threads)
    try:
        return _new_session(data, options, device)
    except ParameterError:
        raise
    except Exception as exc:
        raise ModelError(f"onnxruntime cannot load the model: {exc}") from exc


def _session_saving(
    data: str | bytes, options: ort.SessionOptions, target: Path
) -> ort.InferenceSession | None:
    """A session that writes its optimised graph to ``target``; None where that fails."""
    tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        options.optimized_model_filepath = str(tmp)
        session = ort.InferenceSession(data, sess_options=options, providers=[CPU_PROVIDER])
        os.replace(tmp, target)
        prune_cache(target.parent, ORT_CACHE_KEEP)
        return session
    except Exception:  # an unwritable cache only costs the next start its optimisation
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        return None


ORT_CACHE_ENV = "DENSEPEDS_ORT_CACHE"
ORT_CACHE_KEEP = 16  # optimised graphs kept (a model, per recipe and thread count)
REWRITTEN_KEY = "densepeds.rewritten_for_batch"  # metadata of a cached graph: batch made dynamic


def ort_cache_dir() -> Path | None:
    """Where optimised graphs are cached (``$DENSEPEDS_ORT_CACHE``, ``off``: nowhere)."""
    value = os.environ.get(ORT_CACHE_ENV)
    if value is not None:
        return None if value.strip().lower() in ("", "off", "0") else Path(value).expanduser()
    from densepeds.models.files import cache_dir

    return cache_dir().parent / "ort"


@cache
def _cpu_identity() -> str:
    """The CPU model and instruction sets (the optimised graph may use this CPU's layouts)."""
    fields = {}
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                key = key.strip()
                if key in ("model name", "flags", "Features", "CPU part") and key not in fields:
                    fields[key] = value.strip()
                if not line.strip() and fields:
                    break
    except OSError:
        pass
    return f"{platform.machine()} {platform.processor()} {sorted(fields.items())}"


def optimised_file(path: Path, recipe: str, threads: int | None) -> Path | None:
    """The cache file of ``path``'s optimised graph made with ``recipe`` (the rewriting asked
    for) and ``threads``; None when caching is off."""
    folder = ort_cache_dir()
    if folder is None:
        return None
    from densepeds.models.files import sha256_of

    digest = hashlib.sha256()
    for part in (
        sha256_of(path),
        recipe,
        hashlib.sha256(Path(__file__).read_bytes()).hexdigest(),  # the rewriting code
        ort.__version__,
        str(session_options(threads).intra_op_num_threads),
        _cpu_identity(),
    ):
        digest.update(part.encode() + b"\0")
    return folder / f"{path.stem}-{digest.hexdigest()[:24]}.onnx"


def _cached_session(file: Path, threads: int | None) -> ort.InferenceSession | None:
    """A session of an optimised graph from the cache, run as it is; None where unusable."""
    if not file.is_file():
        return None
    ort.set_default_logger_severity(3)
    options = session_options(threads)
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_DISABLE_ALL
    try:
        session = ort.InferenceSession(str(file), sess_options=options, providers=[CPU_PROVIDER])
    except Exception:  # a damaged file (e.g. a full disk): made again
        return None
    with contextlib.suppress(OSError):
        os.utime(file)  # last used now: kept by prune_cache
    return session


def prune_cache(folder: Path, keep: int) -> None:
    """Remove all but the ``keep`` most recently used graphs (``*.onnx``) in ``folder``."""
    try:
        files = [(f.stat().st_mtime, f) for f in folder.glob("*.onnx")]
    except OSError:
        return
    for _, f in sorted(files, reverse=True)[keep:]:
        with contextlib.suppress(OSError):
            f.unlink()


def specs(values: list[ort.NodeArg]) -> list[TensorSpec]:
    return [TensorSpec(v.name, tuple(v.shape), v.type) for v in values]


def has_fixed_batch(model: onnx.ModelProto) -> bool:
    dims = model.graph.input[0].type.tensor_type.shape.dim
    return len(dims) > 0 and dims[0].HasField("dim_value")


def with_dynamic_batch(model: onnx.ModelProto) -> onnx.ModelProto:
    """A copy of ``model`` whose leading (batch) dimension is symbolic.

    Graph inputs/outputs get a symbolic first dim, stale intermediate shape annotations are
    dropped, and every Reshape whose constant target shape starts with 1 gets 0 there instead
    ("copy the input's dim"), so batch N flows through. Callers must check the copy against the
    original (tests do, on the shipped models).
    """
    import onnx
    from onnx import numpy_helper

    out = onnx.ModelProto()
    out.CopyFrom(model)
    graph = out.graph
    for value in list(graph.input) + list(graph.output):
        dims = value.type.tensor_type.shape.dim
        if len(dims) > 0:
            dims[0].Clear()
            dims[0].dim_param = BATCH_DIM
    del graph.value_info[:]
    inits = {init.name: init for init in graph.initializer}
    consumers: dict[str, int] = {}
    for node in graph.node:
        for name in node.input:
            consumers[name] = consumers.get(name, 0) + 1
    for node in graph.node:
        if node.op_type != "Reshape" or node.input[1] not in inits:
            continue
        target = numpy_helper.to_array(inits[node.input[1]])
        if target.ndim != 1 or len(target) < 2 or target[0] != 1:
            continue
        patched = target.copy()
        patched[0] = 0
        new_name = f"{node.input[1]}__dynamic_batch"
        if new_name not in inits:
            init = numpy_helper.from_array(patched, new_name)
            graph.initializer.append(init)
            inits[new_name] = init
        node.input[1] = new_name
    return out


def with_input_size(
    model: onnx.ModelProto, height: int, width: int, *, anchors: bool = False
) -> onnx.ModelProto:
    """A copy of an image model (NCHW or NHWC, fixed size) whose input is ``height`` x ``width``.

    For fully convolutional graphs: sizes flow from the input, except a YOLO head's anchor grid,
    which is rebuilt for the new size (:func:`densepeds.detect.anchor_grid.follow_input`).
    ``anchors=True`` (a detector) requires that grid: a model whose anchors are not found in a
    known form is a ModelError rather than a copy whose boxes could be silently wrong.
    onnxruntime rejects the copy at load time where another constant spatial shape is inside.
    """
    import onnx

    from densepeds.detect import anchor_grid

    out = onnx.ModelProto()
    out.CopyFrom(model)
    dims = out.graph.input[0].type.tensor_type.shape.dim
    channels = [i for i in (1, 3) if len(dims) == 4 and dims[i].dim_value == 3]
    if not channels or height < 1 or width < 1:
        raise ModelError(
            f"cannot give a {height}x{width} input to a model whose input is not NCHW or NHWC"
        )
    spatial = (2, 3) if channels[0] == 1 else (1, 2)
    before = (dims[spatial[0]].dim_value, dims[spatial[1]].dim_value)
    if not all(before):
        raise ModelError("cannot resize a model whose input size is not fixed")
    for i, v in zip(spatial, (height, width), strict=True):
        dims[i].Clear()
        dims[i].dim_value = v
    for value in out.graph.output:  # sizes follow the input: the rank stays, the sizes go
        for k, d in enumerate(value.type.tensor_type.shape.dim):
            if k > 0:
                d.Clear()
                d.dim_param = f"{value.name}_{k}"
    del out.graph.value_info[:]
    if (height, width) == before:
        return out
    rebuilt = anchor_grid.follow_input(out, before, (height, width))
    if anchors and not rebuilt:
        raise ModelError("no anchor grid this package knows how to rebuild for another input size")
    return out


def batched_session(
    path: Path,
    threads: int | None,
    *,
    dequantize: bool = False,
    input_size: tuple[int, int] | None = None,
    anchors: bool = False,
    device: str = "auto",
) -> tuple[ort.InferenceSession, bool]:
    """A session on ``device`` accepting any batch size, and whether the model had to be
    rewritten for it.

    ``dequantize`` runs a float copy of a QDQ-quantised model (see :func:`dequantized`);
    ``input_size`` (height, width) resizes the model's input (``anchors``: a detector whose
    anchor grid must follow; see :func:`with_input_size`). Only CPU sessions use the cache of
    optimised graphs (a GPU provider's optimised graph holds nodes only it runs).
    """
    anchors = anchors and input_size is not None
    recipe = f"batched dequantize={dequantize} input_size={input_size} anchors={anchors}"
    cpu = device != "openvino" and providers(device) == [CPU_PROVIDER]
    target = optimised_file(path, recipe, threads) if cpu else None
    if target is not None:
        session = _cached_session(target, threads)
        if session is not None:
            meta = session.get_modelmeta().custom_metadata_map
            return session, meta.get(REWRITTEN_KEY) == "1"
    model = load_model(path)
    if dequantize:
        model = dequantized(model)
    if input_size is not None:
        model = with_input_size(model, *input_size, anchors=anchors)
    rewritten = input_size is not None or has_fixed_batch(model)
    if rewritten:
        model = with_dynamic_batch(model)
    if target is None:
        unchanged = not (rewritten or dequantize)  # else the rewritten model, not the file
        return make_session(path if unchanged else model, threads, device=device), rewritten
    entry = model.metadata_props.add()
    entry.key, entry.value = REWRITTEN_KEY, str(int(rewritten))
    return make_session(model, threads, device=device, save_optimised=target), rewritten


METADATA_FIELD = (
    14  # onnx.ModelProto.metadata_props: repeated StringStringEntryProto (1 key, 2 value)
)


def model_metadata(path: Path) -> dict[str, str]:
    """An ONNX file's metadata properties, read without parsing its graph or importing onnx.

    Only the file's top-level protobuf fields are walked (the graph is skipped by its length);
    ``metadata_props`` entries are decoded. tests/test_ort_cache.py checks it against onnx.
    """
    try:
        data = memoryview(path.read_bytes())
        if not data:
            raise ValueError("empty file")
        out: dict[str, str] = {}
        for number, value in _fields(data):
            if number == METADATA_FIELD and isinstance(value, memoryview):
                entry = dict(_fields(value))
                key, text = entry.get(1, b""), entry.get(2, b"")
                if not isinstance(key, memoryview | bytes) or not isinstance(
                    text, memoryview | bytes
                ):
                    raise ValueError("a metadata entry is not a pair of strings")
                out[bytes(key).decode()] = bytes(text).decode()
        return out
    except (OSError, ValueError, IndexError) as exc:  # UnicodeDecodeError is a ValueError
        raise ModelError(f"{path} is not a readable ONNX model: {exc}") from exc


# The metadata key an int8 copy made by densepeds.models.quantize records its source model's
# sha256 in.
META_SOURCE = "densepeds.quantized_from_sha256"


def is_quantized_copy(path: Path) -> bool:
    """Whether ``path`` is a file written by densepeds.models.quantize.quantize_detector."""
    return META_SOURCE in model_metadata(path)


def _fields(data: memoryview) -> Iterator[tuple[int, int | memoryview]]:
    """(field number, varint or length-delimited bytes) of one protobuf message's fields."""
    pos, end = 0, len(data)
    while pos < end:
        tag, pos = _varint(data, pos)
        number, wire = tag >> 3, tag & 7
        if wire == 0:
            value, pos = _varint(data, pos)
            yield number, value
        elif wire == 2:
            size, pos = _varint(data, pos)
            if pos + size > end:
                raise ValueError("truncated field")
            yield number, data[pos : pos + size]
            pos += size
        elif wire in (1, 5):  # fixed 64 / 32 bits
            pos += 8 if wire == 1 else 4
        else:
            raise ValueError(f"field {number} has wire type {wire}, not used by ONNX")
    if pos != end:
        raise ValueError("truncated message")


def _varint(data: memoryview, pos: int) -> tuple[int, int]:
    result = shift = 0
    while True:
        byte = data[pos]
        pos += 1
        result |= (byte & 0x7F) << shift
        if byte < 0x80:
            return result, pos
        shift += 7
        if shift > 63:
            raise ValueError("malformed varint")


def as_float32(array: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(array, dtype=np.float32)


POOL_WEIGHTS = "pool_weights"


def with_weighted_final_pool(model: onnx.ModelProto) -> tuple[onnx.ModelProto, tuple[int, int]]:
    """A copy whose last GlobalAveragePool becomes a weighted average over a new input.

    The new input ``pool_weights`` [N, 1, h, w] (the pooled feature map's size, returned) lets
    the embedding average the person's cells more than the background's ("mask-weighted
    pooling"), instead of repainting pixels. Raises ModelError when the model has no such pool.
    """
    import onnx
    from onnx import numpy_helper

    pools = [i for i, n in enumerate(model.graph.node) if n.op_type == "GlobalAveragePool"]
    if not pools:
        raise ModelError("mask-weighted pooling needs a model ending in GlobalAveragePool")
    inferred = onnx.shape_inference.infer_shapes(model)
    target = model.graph.node[pools[-1]]
    shapes = {v.name: v.type.tensor_type.shape.dim for v in inferred.graph.value_info}
    dims = shapes.get(target.input[0])
    if dims is None or len(dims) != 4 or not all(d.HasField("dim_value") for d in dims[2:]):
        raise ModelError("cannot infer the size of the feature map before the final pooling")
    h, w = dims[2].dim_value, dims[3].dim_value
    out = onnx.ModelProto()
    out.CopyFrom(model)
    graph = out.graph
    feat, pooled = target.input[0], target.output[0]
    axes = numpy_helper.from_array(np.array([2, 3], np.int64), "pool_weights__axes")
    graph.initializer.append(axes)
    new_nodes = [
        onnx.helper.make_node("Mul", [feat, POOL_WEIGHTS], ["pool_weights__wf"]),
        onnx.helper.make_node(
            "ReduceSum", ["pool_weights__wf", axes.name], ["pool_weights__sum"], keepdims=1
        ),
        onnx.helper.make_node(
            "ReduceSum", [POOL_WEIGHTS, axes.name], ["pool_weights__total"], keepdims=1
        ),
        onnx.helper.make_node("Div", ["pool_weights__sum", "pool_weights__total"], [pooled]),
    ]
    nodes = list(graph.node)
    index = pools[-1]
    del graph.node[:]
    graph.node.extend(nodes[:index] + new_nodes + nodes[index + 1 :])
    graph.input.append(
        onnx.helper.make_tensor_value_info(POOL_WEIGHTS, onnx.TensorProto.FLOAT, ["N", 1, h, w])
    )
    return out, (h, w)


def dequantized(model: onnx.ModelProto) -> onnx.ModelProto:
    """A float copy of a QDQ-quantised model: int8 weights folded to float, activation
    Quantize/Dequantize pairs removed.

    onnxruntime cannot fuse this export's QDQ pattern (Conv -> SiLU -> Q) into integer kernels,
    so it runs float convolutions *plus* ~700 Q/DQ passes over the activations; without them the
    same convolutions run about twice as fast. Outputs differ (no activation rounding): check
    accuracy before relying on it (models/README.md has the figures).
    """
    import onnx

    out = onnx.ModelProto()
    out.CopyFrom(model)
    graph = out.graph
    inits = {init.name: init for init in graph.initializer}
    rename: dict[str, str] = {}
    kept: list[onnx.NodeProto] = []
    folded: list[onnx.TensorProto] = []
    for node in graph.node:
        if node.op_type == "DequantizeLinear" and node.input[0] in inits:
            folded.append(_fold_dequantize(node, inits))
        elif node.op_type in ("QuantizeLinear", "DequantizeLinear"):
            rename[node.output[0]] = node.input[0]
        else:
            kept.append(node)

    def source(name: str) -> str:
        while name in rename:
            name = rename[name]
        return name

    for node in kept:
        for i, name in enumerate(node.input):
            node.input[i] = source(name)
    for value in graph.output:
        if value.name in rename:
            kept.append(
                onnx.helper.make_node(
                    "Identity", [source(value.name)], [value.name], name=f"{value.name}/identity"
                )
            )
    used = {name for node in kept for name in node.input}
    initializers = [i for i in list(graph.initializer) + folded if i.name in used]
    del graph.node[:]
    graph.node.extend(kept)
    del graph.initializer[:]
    graph.initializer.extend(initializers)
    del graph.value_info[:]
    return out


def _fold_dequantize(node: onnx.NodeProto, inits: dict[str, onnx.TensorProto]) -> onnx.TensorProto:
    """(q - zero_point) * scale of a constant DequantizeLinear, per-tensor or per-axis."""
    from onnx import numpy_helper

    q = numpy_helper.to_array(inits[node.input[0]]).astype(np.float32)
    scale = numpy_helper.to_array(inits[node.input[1]]).astype(np.float32)
    has_zp = len(node.input) > 2 and node.input[2]
    zero = numpy_helper.to_array(inits[node.input[2]]).astype(np.float32) if has_zp else 0 * scale
    if scale.ndim == 1 and scale.size > 1:
        axis = next((a.i for a in node.attribute if a.name == "axis"), 1)
        shape = [1] * q.ndim
        shape[axis] = -1
        scale, zero = scale.reshape(shape), zero.reshape(shape)
    return numpy_helper.from_array(((q - zero) * scale).astype(np.float32), node.output[0])


def finite_rows(rows: np.ndarray, model: object, warned: set[object]) -> np.ndarray:
    """Boolean [N]: the rows of a detector's output [N, C] whose values are all finite.

    A model that outputs NaN or infinite boxes or scores (a broken export, an fp16 overflow)
    has those rows dropped, never silently: the first time for each ``model`` (a path; tracked
    in ``warned``) an :class:`~densepeds.errors.InputWarning` says how many.
    """
    from densepeds.errors import warn_input

    ok = np.isfinite(rows).all(axis=tuple(range(1, rows.ndim)))
    if not ok.all() and model not in warned:
        warned.add(model)
        warn_input(
            f"{model}: the detector output {int(np.count_nonzero(~ok))} of {len(rows)} "
            "detections with NaN or infinite values; such detections are dropped"
        )
    return ok
