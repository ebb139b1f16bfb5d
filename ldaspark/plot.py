"""Plots of a Result with matplotlib's object-oriented API; the backend is never touched.

Each function draws on ``ax`` when given, else on a new ``matplotlib.figure.Figure`` (not
pyplot, so nothing is registered with a GUI and nothing changes the user's backend), and returns
the Axes (``ax.figure.savefig(...)`` writes it). Ensembles draw one line per member.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Optional

import numpy as np

from .core.errors import InputError
from .core.result import Result, float_array

if TYPE_CHECKING:
    from matplotlib.axes import Axes


def _check(result, ax, relative=True) -> None:
    """The plots' arguments: a Result, an Axes (or None), a bool ``relative``."""
    from .core.validate import _describe, flag
    if not isinstance(result, Result):
        raise InputError(f"result must be a Result (from ldaspark.integrate or load_result), got {_describe(result)}")
    if ax is not None and not callable(getattr(ax, "plot", None)):
        raise InputError(f"ax must be a matplotlib Axes (or None), got {_describe(ax)}")
    flag(relative, "relative")


def _axes(ax: Optional[Any]):
    if ax is not None:
        return ax
    from matplotlib.figure import Figure
    return Figure(figsize=(6, 4)).add_subplot(1, 1, 1)


def _rows(result: Result, name: str):
    """[(t, values)] for one run or per ensemble member (valid rows only)."""
    if result.members is not None:
        return [(float_array(r.t), float_array(getattr(r, name))) for r in result.members]
    return [(float_array(result.t), float_array(getattr(result, name)))]


def energy(result: Result, ax: Optional[Any] = None, relative: bool = True) -> "Axes":
    """Energy error E(t) - E(t0) of (8) (divided by |E(t0)| when ``relative`` and E(t0) != 0).

    Parameters
    ----------
    result : Result
        What `integrate` returned (one run or an ensemble: one line per member).
    relative : bool, optional
        Divide by |E(t0)| (when nonzero); default True.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: a new Figure, not pyplot).

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on; ``ax.figure.savefig(...)`` writes it.

    Examples
    --------
    >>> import ldaspark, ldaspark.plot
    >>> res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, engine="generic")
    >>> ax = ldaspark.plot.energy(res)
    >>> len(ax.lines) >= 1
    True
    """
    _check(result, ax, relative)
    ax = _axes(ax)
    for t, E in _rows(result, "energy"):
        scale = abs(E[0]) if relative and E[0] != 0 else 1.0
        ax.plot(t, (E - E[0]) / scale)
    ax.set_xlabel("t")
    ax.set_ylabel("(E - E(t0)) / |E(t0)|" if relative else "E - E(t0)")
    ax.set_title(f"{result.system} {result.method}: energy error")
    return ax


def constraint(result: Result, ax: Optional[Any] = None) -> "Axes":
    """|k(t, q, v)| of (1c) per constraint, log scale (zeros drawn at the smallest float).

    Parameters
    ----------
    result : Result
        What `integrate` returned (one run or an ensemble: one line per member).
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: a new Figure, not pyplot).

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on; ``ax.figure.savefig(...)`` writes it.

    Examples
    --------
    >>> import ldaspark, ldaspark.plot
    >>> res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, engine="generic")
    >>> ax = ldaspark.plot.constraint(res)
    >>> len(ax.lines) >= 1
    True
    """
    _check(result, ax)
    ax = _axes(ax)
    for t, K in _rows(result, "constraint"):
        for j in range(K.shape[1]):
            ax.semilogy(t, np.maximum(np.abs(K[:, j]), np.finfo(float).tiny), label=f"k{j + 1}")
    ax.set_xlabel("t")
    ax.set_ylabel("|k(t, q, v)|")
    ax.set_title(f"{result.system} {result.method}: constraint residual")
    return ax


def trajectory(result: Result, i: int, j: int, ax: Optional[Any] = None) -> "Axes":
    """q_j against q_i (0-based indices), with the dense output when the Result has one.

    Parameters
    ----------
    result : Result
        What `integrate` returned (one run or an ensemble: one line per member).
    i, j : int
        0-based coordinate indices: q_j is drawn against q_i.
    ax : matplotlib.axes.Axes, optional
        Where to draw (default: a new Figure, not pyplot).

    Returns
    -------
    matplotlib.axes.Axes
        The axes drawn on; ``ax.figure.savefig(...)`` writes it.

    Examples
    --------
    >>> import ldaspark, ldaspark.plot
    >>> res = ldaspark.integrate("skate", "gauss-2", t_span=(0, 1), h=0.1, engine="generic")
    >>> ax = ldaspark.plot.trajectory(res, 0, 1)
    >>> len(ax.lines) >= 1
    True
    """
    _check(result, ax)
    from .core.validate import index_list
    n = result.n
    i, j = index_list([i, j], n, "trajectory: the coordinate indices i, j", unique=False)
    ax = _axes(ax)
    for t, q in _rows(result, "q"):
        ax.plot(q[:, i], q[:, j], ".", markersize=2)
    if result.sol is not None:
        tt = np.linspace(result.sol.t_min, result.sol.t_max, 20 * len(result.sol.t))
        qd, _ = result.sol(tt)
        ax.plot(qd[:, i], qd[:, j], "-", linewidth=0.8)
    ax.set_xlabel(f"q{i + 1}")
    ax.set_ylabel(f"q{j + 1}")
    ax.set_title(f"{result.system} {result.method}")
    return ax
