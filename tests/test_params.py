"""The tracker's parameters: declared once in Rust, the same in the Python docs and the stub."""

from __future__ import annotations

import ast
import importlib.util
import math
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from densepeds import _core
from densepeds.errors import ParameterError
from densepeds.tracking import Tracker

REPO = Path(__file__).resolve().parent.parent


def gen_params() -> ModuleType:
    spec = importlib.util.spec_from_file_location("gen_params", REPO / "scripts/gen_params.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_docs_and_stub_are_generated_from_the_rust_table() -> None:
    stale = gen_params().stale(list(_core.PARAMS))
    assert stale == [], "out of date: run scripts/gen_params.py"


def stub_init_defaults() -> dict[str, tuple[str, Any]]:
    """The stub's Tracker.__init__ keyword arguments: name -> (type, default), read with ast."""
    tree = ast.parse((REPO / "python/densepeds/_core.pyi").read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Tracker")
    init = next(n for n in cls.body if isinstance(n, ast.FunctionDef) and n.name == "__init__")
    args = init.args
    out = {}
    pairs = [*zip(args.args[1:], args.defaults, strict=True)]
    pairs += [*zip(args.kwonlyargs, args.kw_defaults, strict=True)]
    for arg, default in pairs:
        assert arg.annotation is not None and default is not None
        out[arg.arg] = (ast.unparse(arg.annotation), ast.literal_eval(default))
    return out


def docs_rows() -> dict[str, list[str]]:
    """The tracking.py docstring tables (the core parameters, then one per block, each under its
    title line): name -> [type, default, range, meaning, group]."""
    import densepeds.tracking

    doc = densepeds.tracking.__doc__ or ""
    lines = doc.split("\n")
    rules = [i for i, line in enumerate(lines) if line.startswith("=====")]
    assert rules and len(rules) % 3 == 0, "tables with a header"
    rows: dict[str, list[str]] = {}
    for t in range(0, len(rules), 3):
        title = lines[rules[t] - 2].rstrip(":")
        group = "core" if title == "Core parameters" else title.removeprefix("Block: ")
        widths = [len(c) for c in lines[rules[t]].split("  ")]
        for line in lines[rules[t + 1] + 1 : rules[t + 2]]:
            cells, start = [], 0
            for w in widths:
                cells.append(line[start : start + w].strip())
                start += w + 2
            if cells[0]:
                rows[cells[0]] = [*cells[1:], group]
            else:  # a wrapped meaning
                last = rows[next(reversed(rows))]
                last[3] = f"{last[3]} {cells[4]}"
    return rows


def test_every_name_type_default_and_doc_agree() -> None:
    """Read independently of the generator: Rust's table, the running tracker, docs and stub."""
    table = {row["name"]: row for row in _core.PARAMS}
    assert Tracker().params == {name: row["default"] for name, row in table.items()}
    stub = stub_init_defaults()
    docs = docs_rows()
    assert list(stub) == list(table) and sorted(docs) == sorted(table)
    for name, row in table.items():
        assert stub[name] == (row["type"], row["default"]), name
        assert type(row["default"]).__name__ == row["type"], name
        kind, default, range_, meaning, group = docs[name]
        assert kind == row["type"] and range_ == row["range"] and meaning == row["doc"], name
        assert default == repr(row["default"]) and group == row["group"], name
    # At most 15 core parameters; every other one in a named block.
    assert sum(row["group"] == "core" for row in table.values()) <= 15


@pytest.mark.parametrize(
    ("name", "value"),
    [
        # Values the motion model used to replace silently (echoed back by .params).
        ("time_horizon", math.inf),
        ("max_speed", math.inf),
        ("polygon_sides", 1000),
        ("neighbor_radius", math.inf),
        ("threads", -1),
        ("threads", 10**30),
        ("n_init", 0),
        ("iou_threshold", 1.5),
        ("det_threshold", math.nan),
        ("size_smoothing", 1.0),
        ("n_init", 2.0),
        ("recovery", 1),
        ("iou_threshold", True),
        ("iou_threshold", 0.5 + 1j),
        ("motion", "magic"),
        ("nope", 1),
    ],
)
def test_values_not_honoured_are_rejected(name: str, value: object) -> None:
    with pytest.raises(ParameterError, match=name):
        Tracker(**{name: value})  # type: ignore[arg-type]


def test_every_value_in_range_is_used_as_given() -> None:
    t = Tracker(time_horizon=1e300, max_speed=1e9, polygon_sides=32, gate_radius=math.inf)
    assert t.params["time_horizon"] == 1e300 and t.params["polygon_sides"] == 32
    assert t.params["max_speed"] == 1e9 and t.params["gate_radius"] == math.inf


@pytest.mark.parametrize(
    ("name", "value"),
    [("threads", -1), ("threads", 2.5), ("time_horizon", math.inf), ("polygon_sides", 1000)],
)
def test_step_crowd_checks_parameters_against_the_same_table(name: str, value: object) -> None:
    pts = np.zeros((2, 2))
    with pytest.raises(ParameterError, match=name):
        _core.step_crowd(pts, pts, pts, np.ones((2, 2)), **{name: value})
