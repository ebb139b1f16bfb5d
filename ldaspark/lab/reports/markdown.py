"""Markdown helpers shared by every report writer: tables with escaped cells, numbers to their
meaningful digits, and the run-time line each report carries.

A GitHub-flavoured Markdown table splits a row at every unescaped ``|``, also inside code spans,
so a cell holding ``|k|`` or ``a | b`` must escape it (``\\|``) or the row is cut (the renderer
drops the cells beyond the header's count). ``table`` is the only place reports build table
rows; ``tests/lab/reports/test_reports_markdown.py`` renders every committed report and checks the counts.
"""
from __future__ import annotations

import math

__all__ = ["cell", "table", "num", "sci", "fixed", "timing_line", "jsonable"]


def cell(x) -> str:
    """One table cell: ``None`` -> "-", numbers via ``num``, ``|`` escaped, newlines folded."""
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, float):
        x = num(x)
    s = str(x).replace("\r", " ").replace("\n", " ")
    # escape pipes that are not escaped already (idempotent for pre-escaped text)
    out, prev = [], ""
    for ch in s:
        if ch == "|" and prev != "\\":
            out.append("\\|")
        else:
            out.append(ch)
        prev = ch
    return "".join(out)


def table(header, rows) -> list[str]:
    """Lines of a Markdown table: header row, delimiter row, one line per row.

    Every row must have as many cells as the header (a ``ValueError`` otherwise: a report that
    would render with a cut row is a bug in its writer, not something to paper over)."""
    header = [cell(h) for h in header]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        r = list(r)
        if len(r) != len(header):
            raise ValueError(f"table row has {len(r)} cells, header has {len(header)}: {r!r}")
        lines.append("| " + " | ".join(cell(x) for x in r) + " |")
    return lines


def num(x, digits=3) -> str:
    """A number to ``digits`` significant digits (integers as integers, no trailing zeros,
    scientific notation outside [1e-3, 1e5)); ``None`` -> "-", non-finite as inf/nan."""
    if x is None:
        return "-"
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if not math.isfinite(x):
        return str(x)
    if x == 0:
        return "0"
    if x == int(x) and abs(x) < 1e5:
        return str(int(x))
    a = abs(x)
    if 1e-3 <= a < 1e5:
        return f"{x:.{digits}g}"
    return sci(x, digits - 1)


def sci(x, decimals=1) -> str:
    """Scientific notation with ``decimals`` digits after the point; ``None`` -> "-"."""
    if x is None:
        return "-"
    return f"{float(x):.{decimals}e}"


def fixed(x, decimals=2) -> str:
    """Fixed-point with ``decimals`` digits; ``None`` -> "-"."""
    if x is None:
        return "-"
    return f"{float(x):.{decimals}f}"


def timing_line(command, clock) -> str:
    """The line every report ends with: the numbers of the run that wrote it (``clock``: a
    ``timing.Clock`` or anything with ``wall`` and ``cpu``; ``shared`` set when the section ran as
    jobs of the main job, next to the other sections' jobs)."""
    wall, cpu = clock.wall, clock.cpu
    if getattr(clock, "shared", False):
        return (f"_Written by `{command}` (all sections' jobs shared the worker processes): this section's "
                f"jobs used {cpu:.0f} s CPU and were done {wall:.0f} s after the start of the run._")
    return f"_Written by `{command}`: {wall:.0f} s wall, {cpu:.0f} s CPU (this process and its workers)._"


def jsonable(x):
    """``x`` with every non-finite float replaced by ``None`` (the JSON writer refuses NaN/inf),
    tuples as lists and numpy scalars as Python numbers."""
    if isinstance(x, dict):
        return {str(k) if not isinstance(k, str) else k: jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if hasattr(x, "item") and not isinstance(x, (str, bytes)) and getattr(x, "ndim", 1) == 0:
        x = x.item()
    if hasattr(x, "tolist") and not isinstance(x, (str, bytes)):
        return jsonable(x.tolist())
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x
