"""The layers stay layers: no import circles between modules and no module importing another's
private (``_name``) names, in the Python package, the benchmarks and the Rust crates.

Python imports are read with ``ast`` (every ``import`` and ``from ... import``, also inside
functions); Rust modules by their ``crate::module`` paths (``use`` or written out).
"""

from __future__ import annotations

import ast
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from conftest import REPO

PACKAGE = REPO / "python" / "densepeds"
BENCHMARKS = REPO / "benchmarks"
CRATES = sorted(p.parent for p in (REPO / "crates").glob("*/Cargo.toml"))


@dataclass
class Graph:
    """Modules, the modules each imports, and the private names imported across modules."""

    edges: dict[str, set[str]] = field(default_factory=dict)
    private: list[str] = field(default_factory=list)


def python_modules(root: Path, package: str | None) -> dict[str, Path]:
    """Module name -> file: ``package.sub.mod`` under a package, the file's stem for scripts."""
    found = {}
    stubs = [p for p in root.rglob("*.pyi") if not p.with_suffix(".py").exists()]  # compiled ones
    for path in sorted([*root.rglob("*.py"), *stubs]):
        if package is None:
            if path.parent != root:
                continue
            found[path.stem] = path
            continue
        parts = [package, *path.relative_to(root).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def _absolute(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    """The absolute module a ``from`` import names (relative ones resolved)."""
    if not node.level:
        return node.module or ""
    base = module.split(".")
    base = base[: len(base) - node.level + (1 if is_package else 0)]
    return ".".join([*base, node.module] if node.module else base)


def python_graph(modules: Mapping[str, Path]) -> Graph:
    graph = Graph()
    for name, path in modules.items():
        is_package = path.name == "__init__.py"
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        targets: set[str] = set()
        module_names: dict[str, str] = {}  # a local name bound to one of the modules
        for node in _runtime_nodes(tree):
            if isinstance(node, ast.Import):
                for alias in node.names:
                    target = _known(alias.name, modules)
                    if target is not None:
                        targets.add(target)
                        if alias.asname or "." not in alias.name:
                            module_names[alias.asname or alias.name] = target
            elif isinstance(node, ast.ImportFrom):
                source = _absolute(name, is_package, node)
                for alias in node.names:
                    sub = f"{source}.{alias.name}"
                    if sub in modules:  # `from package import module`
                        targets.add(sub)
                        module_names[alias.asname or alias.name] = sub
                        continue
                    target = _known(source, modules)
                    if target is None:
                        continue
                    targets.add(target)
                    if _is_private(alias.name) and target != name:
                        graph.private.append(f"{name} imports {alias.name} from {target}")
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Name)
                and node.value.id in module_names
                and _is_private(node.attr)
                and f"{module_names[node.value.id]}.{node.attr}" not in modules
            ):
                graph.private.append(
                    f"{name} uses {module_names[node.value.id]}.{node.attr} (line {node.lineno})"
                )
        targets.discard(name)
        graph.edges[name] = targets
    return graph


def _runtime_nodes(tree: ast.AST) -> Iterable[ast.AST]:
    """Every node but those under ``if TYPE_CHECKING:`` (imports for annotations only)."""
    todo = [tree]
    while todo:
        node = todo.pop()
        yield node
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            todo.extend(node.orelse)
        else:
            todo.extend(ast.iter_child_nodes(node))


def _known(module: str, modules: Mapping[str, Path]) -> str | None:
    """The module itself where it is one of ours, else None (a library)."""
    return module if module in modules else None


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


_RUST_COMMENT = re.compile(r"//[^\n]*|/\*.*?\*/", re.S)
_CRATE_PATH = re.compile(r"\bcrate::(\w+)")
_USE_GROUP = re.compile(r"\buse\s+crate::\{([^;]*)\};", re.S)


def rust_graph(crate: Path) -> Graph:
    """The ``crate::module`` references between a crate's top-level modules (``src/X.rs`` or
    ``src/X/``; ``lib.rs`` is the root, not a module)."""
    src = crate / "src"
    modules: dict[str, list[Path]] = {}
    for path in sorted(src.rglob("*.rs")):
        top = path.relative_to(src).parts[0].removesuffix(".rs")
        if top not in ("lib", "main"):
            modules.setdefault(top, []).append(path)
    graph = Graph()
    for name, paths in modules.items():
        targets: set[str] = set()
        for path in paths:
            text = _RUST_COMMENT.sub("", path.read_text(encoding="utf-8"))
            used = _CRATE_PATH.findall(text)
            for group in _USE_GROUP.findall(text):
                used += re.findall(r"(?:^|,)\s*(\w+)", group)
            targets.update(u for u in used if u in modules and u != name)
        graph.edges[name] = targets
    return graph


def cycles(edges: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """Every strongly connected group of more than one module (each an import circle), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for nxt in edges.get(node, ()):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in on_stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            group = []
            while True:
                top = stack.pop()
                on_stack.discard(top)
                group.append(top)
                if top == node:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return sorted(found)


# --- the checker itself ------------------------------------------------------------------------


def test_cycles_finds_circles_and_only_them() -> None:
    assert cycles({"a": ["b"], "b": ["c"], "c": ["a"], "d": ["a"]}) == [["a", "b", "c"]]
    assert cycles({"a": ["b"], "b": [], "c": ["b"]}) == []


def test_the_reader_sees_every_kind_of_import(tmp_path: Path) -> None:
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("from .deep import thing\n")
    (pkg / "sub" / "deep.py").write_text("def f():\n    from pkg import helper\n    thing = 1\n")
    (pkg / "helper.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg import top\n"
    )
    (pkg / "top.py").write_text(
        "import pkg.sub\nfrom pkg import other as o\n\ndef g():\n    return o._hidden\n"
    )
    (pkg / "other.py").write_text("from pkg.top import _secret\n")
    graph = python_graph(python_modules(pkg, "pkg"))
    assert graph.edges["pkg.sub"] == {"pkg.sub.deep"}
    assert graph.edges["pkg.sub.deep"] == {"pkg.helper"}  # a function-level import counts
    assert graph.edges["pkg.helper"] == set()  # one for annotations only does not
    assert graph.edges["pkg.top"] == {"pkg.sub", "pkg.other"}
    assert cycles(graph.edges) == [["pkg.other", "pkg.top"]]
    assert sorted(graph.private) == [
        "pkg.other imports _secret from pkg.top",
        "pkg.top uses pkg.other._hidden (line 5)",
    ]


def test_the_rust_reader_sees_use_paths_and_groups(tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    (src / "lib.rs").write_text("pub mod a;\npub mod b;\npub mod c;\n")
    (src / "a.rs").write_text("use crate::{b::X, c};\n// crate::lib_only in a comment\n")
    (src / "b.rs").write_text("fn f() -> crate::c::Y { todo!() }\n")
    (src / "c.rs").write_text("use crate::a::Z;\n")
    graph = rust_graph(tmp_path)
    assert graph.edges == {"a": {"b", "c"}, "b": {"c"}, "c": {"a"}}
    assert cycles(graph.edges) == [["a", "b", "c"]]


# --- the project -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("root", "package"), [(PACKAGE, "densepeds"), (BENCHMARKS, None)], ids=["package", "benchmarks"]
)
def test_python_has_no_import_circles_or_private_imports(root: Path, package: str | None) -> None:
    graph = python_graph(python_modules(root, package))
    assert len(graph.edges) > 5
    assert cycles(graph.edges) == []
    assert graph.private == []


@pytest.mark.parametrize("crate", CRATES, ids=[c.name for c in CRATES])
def test_rust_modules_have_no_circles(crate: Path) -> None:
    graph = rust_graph(crate)
    assert cycles(graph.edges) == []
