#!/usr/bin/env python3
"""Rewrites the figures in README.md, docs/*.md and crates/*/README.md from the results files.

Every figure the README and the docs show sits in a marked block::

    <!-- generated:NAME -->
    ...
    <!-- /generated -->

and this script rewrites each block from ``benchmarks/results/*.md`` (the files the benchmark
scripts write), so that no figure is typed by hand. ``BLOCKS`` names each block's source.
``--check`` writes nothing and exits 1 when a file is out of date (``tests/test_readme.py``
runs the same check); an unknown block name, a missing results file or a results file whose
table moved is an error.

    python scripts/gen_docs.py [--check]
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results"
FILES = (
    ROOT / "README.md",
    *sorted((ROOT / "docs").glob("*.md")),
    *sorted((ROOT / "crates").glob("*/README.md")),
)
BLOCK = re.compile(r"(<!-- generated:([\w-]+) -->\n)(.*?)(<!-- /generated -->)", re.S)
VIDEO_CELLS = ("MOT20-01-dev/float", "PETS09-S2L1-dev/float")


class DocsError(Exception):
    """A block that cannot be generated: its results file or table is missing."""


def _read(name: str) -> list[str]:
    path = RESULTS / name
    if not path.is_file():
        raise DocsError(f"{path.relative_to(ROOT)}: missing")
    return path.read_text(encoding="utf-8").splitlines()


def table_after(name: str, marker: str) -> list[str]:
    """The first Markdown table after the first line of results file ``name`` that contains
    ``marker`` (an empty marker: the file's first table)."""
    lines = _read(name)
    start = next((i for i, line in enumerate(lines) if marker in line), None)
    if start is None:
        raise DocsError(f"{name}: no line contains {marker!r}")
    rows: list[str] = []
    for line in lines[start:]:
        if line.startswith("|"):
            rows.append(line)
        elif rows:
            break
    if len(rows) < 3:
        raise DocsError(f"{name}: no table after {marker!r}")
    return rows


def line_starting(name: str, prefix: str) -> str:
    """The first line of results file ``name`` that starts with ``prefix``."""
    for line in _read(name):
        if line.startswith(prefix):
            return line
    raise DocsError(f"{name}: no line starts with {prefix!r}")


def _cells(row: str) -> list[str]:
    return [c.strip() for c in row.strip().strip("|").split("|")]


def _rows(table: list[str]) -> dict[str, list[str]]:
    """A table's body rows by their first cell."""
    return {_cells(r)[0]: _cells(r) for r in table[2:]}


def speedups(name: str = "speed.md") -> dict[str, dict[str, str]]:
    """``Speed-up, reference / SETTING: **Nx wall**`` per sequence section of speed.md."""
    out: dict[str, dict[str, str]] = {}
    seq = ""
    for line in _read(name):
        head = re.match(r"### (\S+), frames", line)
        if head:
            seq = head.group(1)
        m = re.match(r"Speed-up, reference / (.+): \*\*([\d.]+x) wall\*\*", line)
        if m and seq:
            out.setdefault(m.group(1), {})[seq] = m.group(2)
    if not out:
        raise DocsError(f"{name}: no speed-up lines")
    return out


COMMAND = re.compile(r"((?:[A-Z_]+=\S+ )*(?:python benchmarks/|scripts/fuzz\.sh)[^`]*)")


def command(name: str) -> list[str]:
    """The command that wrote results file ``name``, as its header gives it (an indented code
    line first, with a continued previous line; else the first one in backquotes)."""
    lines = _read(name)
    for indented in (True, False):
        for i, line in enumerate(lines):
            if indented != line.startswith("    "):
                continue
            m = COMMAND.search(line)
            if m:
                text = m.group(1).strip().rstrip(".")
                if i and lines[i - 1].rstrip().endswith("\\"):
                    text = lines[i - 1].strip()[:-1].strip() + " " + text
                return ["```bash", text, "```"]
    raise DocsError(f"{name}: no command line")


def readme_results() -> list[str]:
    """The README's one table: the video cells and the grid's mean against the best peer, and
    the speed of the defaults against the reference pipeline."""
    best = _rows(table_after("accuracy.md", "## Ours (package defaults) against the best peer"))
    means = _rows(table_after("accuracy.md", "Mean HOTA per detection source"))
    speed = speedups()["ours"]
    head = "| | HOTA | IDF1 | best peer (HOTA) | wall time, reference / ours |"
    lines = [head, "|---|---:|---:|---|---:|"]
    for cell in VIDEO_CELLS:
        row = best[cell]
        seq = cell.split("/")[0]
        lines.append(
            f"| {seq} | {row[1]} | {row[2]} | {row[3]} ({row[4]}) | {speed.get(seq, '-')} |"
        )
    ours = means["densepeds (defaults)"][-1]
    # Only the peers that ran on every cell (those needing embeddings ran on the videos only).
    peer_means = {
        k: v[-1] for k, v in means.items() if k != "densepeds (defaults)" and "-" not in v[1:]
    }
    top = max(peer_means, key=lambda k: float(peer_means[k]))
    lines.append(
        f"| mean over the {len(best)} dev-grid cells | {ours} | | {top} ({peer_means[top]}) | |"
    )
    return lines


def speed_table() -> list[str]:
    """Every timed setting's wall-time speed-up over the reference, per sequence."""
    ups = speedups()
    seqs = list(dict.fromkeys(s for per in ups.values() for s in per))
    lines = ["| setting | " + " | ".join(seqs) + " |", "|---|" + "---:|" * len(seqs)]
    for setting, per in ups.items():
        lines.append(f"| {setting} | " + " | ".join(per.get(s, "-") for s in seqs) + " |")
    return lines


def _fast_hota() -> list[str]:
    table = table_after("fast.md", "| setting |")
    head = _cells(table[0])
    keep = [0] + [i for i, h in enumerate(head) if h.endswith(" HOTA") or h.endswith(" IDF1")]
    out = ["| " + " | ".join(head[i] for i in keep) + " |", "|---|" + "---:|" * (len(keep) - 1)]
    for row in table[2:]:
        cells = _cells(row)
        out.append("| " + " | ".join(cells[i] for i in keep) + " |")
    return out


BLOCKS: dict[str, Callable[[], list[str]]] = {
    "readme-results": readme_results,
    "accuracy-means": lambda: table_after("accuracy.md", "Mean HOTA per detection source"),
    "accuracy-best-peer": lambda: table_after("accuracy.md", "## Ours (package defaults)"),
    "loo": lambda: table_after("accuracy-loo.md", "Tuned on all"),
    "claims-motion": lambda: table_after("accuracy-claims.md", "## Motion model"),
    "claims-features": lambda: table_after("accuracy-claims.md", "## Appearance features"),
    "ablation-mot20": lambda: table_after("realvideo.md", "**MOT20-01-dev**"),
    "ablation-pets09": lambda: table_after("realvideo.md", "**PETS09-S2L1-dev**"),
    "visibility": lambda: table_after("accuracy-visibility.md", ""),
    "speed": speed_table,
    "fast": _fast_hota,
    "detector-recall": lambda: table_after("detector-recall.md", ""),
    "int8": lambda: table_after("int8.md", "| setting | wall ms/view"),
    "tracker": lambda: table_after("tracker.md", "## Motion only"),
    "tracker-appearance": lambda: table_after("tracker.md", "## With appearance embeddings"),
    "memory": lambda: [line_starting("memory.md", "Peak RSS after")],
    "batch": lambda: [line_starting("batch.md", "Goals")],
    "fuzz": lambda: table_after("fuzz.md", ""),
    "frvo-threads": lambda: table_after("frvo-threads.md", "| agents"),
}
# The command that wrote each results file: block ``command-NAME`` for ``NAME.md``.
BLOCKS.update(
    {
        f"command-{name}": (lambda name=name: command(f"{name}.md"))
        for name in (
            "accuracy",
            "realvideo",
            "fast",
            "speed",
            "detector-recall",
            "int8",
            "tracker",
            "memory",
            "batch",
            "fuzz",
        )
    }
)


def render(text: str, where: str) -> str:
    """``text`` with every generated block rewritten."""

    def one(m: re.Match[str]) -> str:
        name = m.group(2)
        if name not in BLOCKS:
            known = ", ".join(BLOCKS)
            raise DocsError(f"{where}: unknown generated block {name!r} (known: {known})")
        body = "\n".join(BLOCKS[name]()) + "\n"
        return m.group(1) + body + m.group(4)

    return BLOCK.sub(one, text)


def stale() -> list[Path]:
    """The files whose generated blocks differ from what the results files give."""
    out = []
    for path in FILES:
        text = path.read_text(encoding="utf-8")
        if render(text, str(path.relative_to(ROOT))) != text:
            out.append(path)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="only report files out of date")
    args = ap.parse_args(argv)
    try:
        if args.check:
            old = stale()
            for path in old:
                print(f"{path.relative_to(ROOT)} is out of date: run scripts/gen_docs.py")
            return 1 if old else 0
        for path in FILES:
            text = path.read_text(encoding="utf-8")
            new = render(text, str(path.relative_to(ROOT)))
            if new != text:
                path.write_text(new, encoding="utf-8")
                print(f"wrote {path.relative_to(ROOT)}")
    except DocsError as e:
        print(f"gen_docs: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
