"""A YOLO detection head's anchor grid, rebuilt for another input size.

An export with a fixed input size (a TFLite-converted graph, an ONNX export without dynamic
axes) keeps its head's anchor grid as constants: the anchor centres, the strides that scale the
box distances, and the shapes that flatten each level's cells. Giving such a model another input
size (:func:`densepeds.detect.onnxutil.with_input_size`) must rebuild them, or its boxes land in
the wrong places. :func:`follow_input` does that for the forms YOLOv8/YOLO11 exports use:

- centres ``[..., 2, A]``: (cell + 0.5) in cells, pixels or fractions of the input;
- scales ``[..., 4, A]`` (x, y, x, y) or ``[..., 1, A]``: the stride in pixels or as a fraction
  of the input;
- Reshape targets whose last entry is a level's cell count or A,

with A the cells of the strides ``STRIDES`` at the model's own size, row-major per level. A
constant of A entries in any other form is a ModelError, never left stale.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from densepeds.errors import ModelError

if TYPE_CHECKING:
    import onnx

STRIDES = (8, 16, 32)  # the head's levels: pixels of input per cell
# A constant matches a form when its largest deviation is below this share of its largest value
# (the shipped int8 export stores its centres rounded to about 0.2% of the input).
TOLERANCE = 0.01
UNITS = ("cell", "pixel", "fraction")
Array = npt.NDArray[np.float64]


def level_cells(height: int, width: int) -> list[tuple[int, int]]:
    """(rows, columns) of cells per level for an input of ``height`` x ``width``."""
    return [(height // s, width // s) for s in STRIDES]


def anchor_count(height: int, width: int) -> int:
    return sum(r * c for r, c in level_cells(height, width))


def _per_anchor(height: int, width: int, unit: str) -> tuple[Array, Array, Array, Array]:
    """Per anchor: column and row index (+ 0.5), and the x and y size of a cell in ``unit``."""
    cols, rows, ux, uy = [], [], [], []
    for s, (r, c) in zip(STRIDES, level_cells(height, width), strict=True):
        yy, xx = np.meshgrid(np.arange(r) + 0.5, np.arange(c) + 0.5, indexing="ij")
        cols.append(xx.ravel())
        rows.append(yy.ravel())
        size = {"cell": (1.0, 1.0), "pixel": (s, s), "fraction": (s / width, s / height)}[unit]
        ux.append(np.full(r * c, size[0]))
        uy.append(np.full(r * c, size[1]))
    return tuple(np.concatenate(v) for v in (cols, rows, ux, uy))  # type: ignore[return-value]


def _form(kind: int, height: int, width: int, unit: str) -> Array | None:
    """The constant of ``kind`` rows (2 centres, 4 or 1 scales) in ``unit``; None if none."""
    col, row, ux, uy = _per_anchor(height, width, unit)
    if kind == 2:
        return np.stack([col * ux, row * uy])
    if kind == 4 and unit != "cell":
        return np.stack([ux, uy, ux, uy])
    if kind == 1 and unit == "pixel":
        return ux[None]
    return None


def _rebuilt(old: Array, before: tuple[int, int], after: tuple[int, int]) -> Array | None:
    """``old`` (an anchor-grid constant at ``before``) at ``after``; None if not recognised."""
    lead, kind = old.shape[:-2], old.shape[-2]
    if any(d != 1 for d in lead) or kind not in (1, 2, 4):
        return None
    flat = old.reshape(kind, -1).astype(np.float64)
    for unit in UNITS:
        form = _form(kind, *before, unit)
        if form is None:
            continue
        if np.max(np.abs(form - flat)) <= TOLERANCE * max(float(np.max(np.abs(form))), 1e-12):
            new = _form(kind, *after, unit)
            assert new is not None
            return new.reshape(*lead, kind, -1).astype(old.dtype)
    return None


def follow_input(model: onnx.ModelProto, before: tuple[int, int], after: tuple[int, int]) -> int:
    """Rebuild, in place, ``model``'s anchor-grid constants for input size ``after`` (height,
    width) from ``before``; returns how many constants changed (0: the model has no anchor
    grid). Raises ModelError for a constant of the anchor count in no known form, and when
    ``after`` is not a whole number of cells of the coarsest level."""
    from onnx import numpy_helper

    coarsest = STRIDES[-1]
    if after[0] % coarsest or after[1] % coarsest or after[0] < 1 or after[1] < 1:
        raise ModelError(f"an input of {after[0]}x{after[1]} is not a multiple of {coarsest}")
    count = anchor_count(*before)
    levels = zip(level_cells(*before), level_cells(*after), strict=True)
    counts = {a * b: x * y for (a, b), (x, y) in levels}
    counts[count] = anchor_count(*after)
    graph = model.graph
    grids = [i for i in graph.initializer if len(i.dims) >= 2 and i.dims[-1] == count]
    if not grids:  # no head with an anchor grid: nothing to rebuild (its shapes are not ours)
        return 0
    for init in grids:
        value = numpy_helper.to_array(init)
        rebuilt = (
            _rebuilt(value, before, after) if np.issubdtype(value.dtype, np.floating) else None
        )
        if rebuilt is None:
            raise ModelError(
                f"constant {init.name!r} {list(value.shape)} has one entry per anchor but is not "
                "an anchor grid this package knows how to rebuild for another input size"
            )
        init.CopyFrom(numpy_helper.from_array(rebuilt, init.name))
    reshape_targets = {n.input[1] for n in graph.node if n.op_type == "Reshape"}
    changed = len(grids)
    for init in graph.initializer:
        if init.name not in reshape_targets or len(init.dims) != 1:
            continue
        value = numpy_helper.to_array(init)
        if value.dtype == np.int64 and len(value) >= 2 and int(value[-1]) in counts:
            target = value.copy()
            target[-1] = counts[int(value[-1])]
            init.CopyFrom(numpy_helper.from_array(target, init.name))
            changed += 1
    return changed
