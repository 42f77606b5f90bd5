"""The README and docs say what is true: the Python API example runs as written, the command
lines parse, the one-command scripts exist, and every figure matches its results file."""

from __future__ import annotations

import argparse
import io
import os
import re
import sys
from contextlib import redirect_stdout
from pathlib import Path

import pytest
from conftest import REPO
from densepeds.cli import build_parser

sys.path.insert(0, str(REPO / "scripts"))
import gen_docs  # noqa: E402

README = REPO / "README.md"
DOCS = sorted((REPO / "docs").glob("*.md"))


def _section(name: str, path: Path = README) -> str:
    text = path.read_text(encoding="utf-8")
    match = re.search(rf"^## {re.escape(name)}\n(.*?)(?=^## |\Z)", text, re.S | re.M)
    assert match, f"{path.name} has no '## {name}' section"
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


def _commands(text: str) -> list[list[str]]:
    lines = re.findall(r"^python -m densepeds (.*)$", text, re.M)
    return [line.split("#")[0].split() for line in lines]


@pytest.mark.parametrize(
    ("path", "section"),
    [(README, "Command line"), (REPO / "docs" / "usage.md", "Run, score, ablate")],
)
def test_command_lines_parse(path: Path, section: str) -> None:
    """Every `python -m densepeds ...` line is accepted by the argument parser."""
    parser = build_parser()
    commands = _commands(_section(section, path))
    assert len(commands) >= 5
    for argv in commands:
        if not argv or argv[0] not in ("run", "eval", "ablate", "scene", "models", "batch"):
            argv.insert(0, "run")
        parser.parse_args(argv)


def test_readme_is_short_and_names_the_one_commands() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 200
    for script, section in (("setup-and-run.sh", "Set up and run"), ("test.sh", "Run all tests")):
        assert f"./scripts/{script}" in _section(f"{section} (one command)")
        path = REPO / "scripts" / script
        assert path.is_file() and os.access(path, os.X_OK), path


def test_links_resolve() -> None:
    """Every relative link in the README and docs names a file that exists."""
    missing = []
    for path in [README, *DOCS, REPO / "benchmarks" / "README.md"]:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", path.read_text(encoding="utf-8")):
            if "://" in target:
                continue
            if not (path.parent / target).exists():
                missing.append(f"{path.relative_to(REPO)} -> {target}")
    assert not missing, missing


def test_docs_figures_match_the_results_files() -> None:
    """`scripts/gen_docs.py --check`: every generated block is what the results give."""
    stale = gen_docs.stale()
    assert not stale, f"run python scripts/gen_docs.py: {[str(p) for p in stale]}"


def test_a_changed_figure_is_caught() -> None:
    """The check compares the blocks' contents: a figure typed over is out of date."""
    text = README.read_text(encoding="utf-8")
    block = re.search(r"<!-- generated:readme-results -->\n(.*?)<!-- /generated -->", text, re.S)
    assert block and re.search(r"\d+\.\d\d", block.group(1))
    typed = text.replace(block.group(1), re.sub(r"\d+\.\d\d", "99.99", block.group(1)), 1)
    assert gen_docs.render(typed, "README.md") == text
    with pytest.raises(gen_docs.DocsError, match="unknown generated block"):
        gen_docs.render("<!-- generated:nothing -->\n<!-- /generated -->", "x.md")


def test_no_typed_figures_outside_generated_blocks() -> None:
    """Outside the generated blocks the README quotes no results (HOTA-like decimals, speed-up
    ratios; versions such as 3.10+ are not results)."""
    text = gen_docs.BLOCK.sub("", README.read_text(encoding="utf-8"))
    assert not re.findall(r"\b\d+\.\d\d\b(?!\+)|\b\d+(?:\.\d+)?x\b", text)


def _run_help_actions() -> list[argparse.Action]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return [a for a in sub.choices["run"]._actions if a.dest != "help"]


def test_run_help_shows_every_default_in_groups() -> None:
    """`run --help`: every option says its default, and sits in a named group."""
    actions = _run_help_actions()
    assert len(actions) > 15
    for action in actions:
        assert action.help and "default" in action.help, action.dest
    out = io.StringIO()
    with redirect_stdout(out), pytest.raises(SystemExit):
        build_parser().parse_args(["run", "--help"])
    for title in ("input:", "detection:", "appearance (re-ID):", "tracking:", "output:"):
        assert f"\n{title}\n" in out.getvalue(), title
    assert "examples:" in out.getvalue()


def test_run_help_focus_default_is_the_detectors() -> None:
    """The default `--focus-lost` names is YoloSegDetector's own focus_scale."""
    import inspect

    from densepeds.detect.yoloseg import YoloSegDetector

    (focus,) = (a for a in _run_help_actions() if a.dest == "focus_lost")
    default = inspect.signature(YoloSegDetector).parameters["focus_scale"].default
    assert f"default {default:g} " in str(focus.help)
