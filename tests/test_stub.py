"""The type stub `_core.pyi` matches the compiled extension: names, signatures and defaults."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path
from typing import Any

from densepeds import _core

STUB = Path(__file__).resolve().parent.parent / "python/densepeds/_core.pyi"
TREE = ast.parse(STUB.read_text())


def _is_typing_only(node: ast.ClassDef) -> bool:
    """TypedDicts describe data (rows, keyword sets): they have no runtime object."""
    return any(isinstance(b, ast.Name) and b.id == "TypedDict" for b in node.bases)


def _stub_params(fn: ast.FunctionDef) -> list[tuple[str, str, Any]]:
    """(name, kind, default) per parameter, as inspect names the kinds; ``self`` left out."""
    a = fn.args
    positional = [*a.posonlyargs, *a.args]
    defaults: list[Any] = [inspect.Parameter.empty] * (len(positional) - len(a.defaults))
    defaults += [ast.literal_eval(d) for d in a.defaults]
    out = []
    for arg, default in zip(positional, defaults, strict=True):
        kind = "POSITIONAL_ONLY" if arg in a.posonlyargs else "POSITIONAL_OR_KEYWORD"
        out.append((arg.arg, kind, default))
    if a.vararg:
        out.append((a.vararg.arg, "VAR_POSITIONAL", inspect.Parameter.empty))
    for arg, d in zip(a.kwonlyargs, a.kw_defaults, strict=True):
        default = inspect.Parameter.empty if d is None else ast.literal_eval(d)
        out.append((arg.arg, "KEYWORD_ONLY", default))
    if a.kwarg:
        out.append((a.kwarg.arg, "VAR_KEYWORD", inspect.Parameter.empty))
    return [p for p in out if p[0] != "self"]


def _runtime_params(obj: Any) -> list[tuple[str, str, Any]]:
    sig = inspect.signature(obj)
    return [(p.name, p.kind.name, p.default) for p in sig.parameters.values() if p.name != "self"]


def test_module_names_match() -> None:
    stub = set()
    for node in TREE.body:
        is_class = isinstance(node, ast.ClassDef) and not _is_typing_only(node)
        if isinstance(node, ast.FunctionDef) or is_class:
            stub.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            stub.add(node.target.id)
    runtime = {n for n in dir(_core) if not n.startswith("__")} | {"__version__"}
    assert stub == runtime


def test_function_signatures_match() -> None:
    for node in TREE.body:
        if isinstance(node, ast.FunctionDef):
            assert _stub_params(node) == _runtime_params(getattr(_core, node.name)), node.name


def test_tracker_methods_properties_and_keywords_match() -> None:
    cls = next(n for n in TREE.body if isinstance(n, ast.ClassDef) and n.name == "Tracker")
    methods = {n.name: n for n in cls.body if isinstance(n, ast.FunctionDef)}
    properties = {
        name
        for name, n in methods.items()
        if any(isinstance(d, ast.Name) and d.id == "property" for d in n.decorator_list)
    }
    runtime = {n: v for n, v in vars(_core.Tracker).items() if not n.startswith("_")}
    assert properties == {n for n, v in runtime.items() if inspect.isgetsetdescriptor(v)}
    plain = {n for n, v in runtime.items() if inspect.ismethoddescriptor(v)}
    assert set(methods) - properties - {"__init__"} == plain
    for name in plain:
        assert _stub_params(methods[name]) == _runtime_params(runtime[name]), name
    # __init__: the runtime takes (motion="frvo", **params); the stub names every keyword, and
    # the extension accepts exactly those (with the stub's defaults).
    init = _stub_params(methods["__init__"])
    runtime_init = _runtime_params(_core.Tracker)
    assert runtime_init[-1][1] == "VAR_KEYWORD"
    assert runtime_init[:-1] == [p for p in init if p[1] != "KEYWORD_ONLY"]
    keywords = {name: default for name, kind, default in init if kind == "KEYWORD_ONLY"}
    assert set(keywords) == {row["name"] for row in _core.PARAMS} - {"motion"}
    assert _core.Tracker(**keywords).params == {"motion": "frvo", **keywords}
