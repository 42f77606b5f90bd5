"""The README's Python API example runs as written (and its Usage names real CLI options)."""

from __future__ import annotations

import re

from conftest import REPO
from densepeds.cli import build_parser


def _section(name: str) -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    match = re.search(rf"^## {re.escape(name)}\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert match, f"README has no '## {name}' section"
    return match.group(1)


def test_python_api_example_runs(tmp_path, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    blocks = re.findall(r"```python\n(.*?)```", _section("Python API"), re.S)
    assert len(blocks) == 1
    monkeypatch.chdir(tmp_path)
    namespace: dict[str, object] = {}
    exec(compile(blocks[0], "README.md:Python API", "exec"), namespace)
    out = capsys.readouterr().out
    assert re.search(r"\d+ people tracked in frame 40; decode [\d.]+", out), out
    assert len(namespace["tracks"].ids) > 0  # type: ignore[attr-defined]


def test_usage_commands_parse() -> None:
    """Every `python -m densepeds ...` line in Usage is accepted by the argument parser."""
    parser = build_parser()
    commands = re.findall(r"^python -m densepeds (.*)$", _section("Usage"), re.M)
    assert len(commands) >= 5
    for line in commands:
        argv = line.split()
        if not argv or argv[0] not in ("run", "eval", "ablate", "scene"):
            argv.insert(0, "run")
        parser.parse_args(argv)
