"""Every committed report renders: each Markdown table row has as many cells as its header (a
renderer cuts a row at every unescaped '|', so a note holding '|k|' would lose its tail), and no
report speaks of how it was made (issues, sessions). Also the shared writer helper itself.
Cost: ~1 s (parses the committed reports once)."""
import pathlib
import re

import pytest
from markdown_it import MarkdownIt
from markdown_it.rules_block.table import escapedSplit

from ldaspark.lab.reports.markdown import cell, jsonable, num, table

REPORTS = pathlib.Path(__file__).resolve().parents[3] / "reports"
MD_FILES = sorted(REPORTS.glob("*.md"))


def row_cells(line):
    """Cells of one table line, split as markdown-it (GFM) splits them."""
    cols = escapedSplit(line.strip())
    if cols and cols[0].strip() == "":
        cols.pop(0)
    if cols and cols[-1].strip() == "":
        cols.pop()
    return cols


def table_problems(text):
    """(line number, cells, header cells) of every table row whose cell count differs from its
    header; tables are found by markdown-it's GFM table rule (token.map = source lines)."""
    md = MarkdownIt("commonmark").enable("table")
    lines = text.split("\n")
    bad = []
    for tok in md.parse(text):
        if tok.type != "table_open":
            continue
        start, end = tok.map
        n_head = len(row_cells(lines[start]))
        for i in range(start + 2, end):          # skip header and delimiter rows
            if lines[i].strip() == "":
                continue
            n = len(row_cells(lines[i]))
            if n != n_head:
                bad.append((i + 1, n, n_head))
    return bad


def test_reports_exist():
    assert {p.name for p in MD_FILES} >= {"claims.md", "convergence.md", "energy.md", "stability.md",
                                          "work_precision.md"}


@pytest.mark.parametrize("path", MD_FILES, ids=[p.name for p in MD_FILES])
def test_every_table_row_has_the_header_cell_count(path):
    text = path.read_text()
    assert "|---" in text or path.name.startswith("claims-quick")
    assert table_problems(text) == []


@pytest.mark.parametrize("path", MD_FILES, ids=[p.name for p in MD_FILES])
def test_reports_speak_of_the_project_only(path):
    text = path.read_text()
    assert not re.search(r"\b(issue|session|helper)s?\b", text, re.I), path.name


def test_checker_catches_an_unescaped_pipe():
    # negative control: the 5.1 notes contained |k| unescaped -> the row had too many cells
    text = "| claim | note |\n|---|---|\n| 5.1 | tangential |k| small |\n"
    assert table_problems(text) == [(3, 4, 2)]
    fixed = "\n".join(table(["claim", "note"], [["5.1", "tangential |k| small"]])) + "\n"
    assert table_problems(fixed) == []
    html = MarkdownIt("commonmark").enable("table").render(fixed)
    assert "<td>tangential |k| small</td>" in html


def test_table_helper_rejects_a_row_of_the_wrong_length():
    with pytest.raises(ValueError):
        table(["a", "b"], [["1"]])


def test_cell_and_number_formatting():
    assert cell(None) == "-" and cell("a|b") == "a\\|b" and cell("a\\|b") == "a\\|b" and cell("x\ny") == "x y"
    assert num(0.052560069877837824) == "0.0526" and num(3.0) == "3" and num(2e-7) == "2.00e-07"
    assert num(123456.7) == "1.23e+05" and num(None) == "-" and num(7) == "7"
    assert jsonable({"a": float("nan"), "b": (1, float("inf"))}) == {"a": None, "b": [1, None]}
