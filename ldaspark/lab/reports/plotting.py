"""Figure helpers shared by the report writers (matplotlib's object-oriented API, no pyplot
state, no global backend switch).

* ``figure``: a ``matplotlib.figure.Figure`` with constrained layout, so that a suptitle never
  overlaps the panel titles and legends stay inside the canvas.
* ``colours``: n distinct colours (tab10 up to 10 series, tab20 up to 20, then a sampled
  colormap): a figure never shows two series in the same colour.
"""
from __future__ import annotations


def figure(nrows=1, ncols=1, figsize=(8, 4.5), **subplot_kw):
    """(fig, axes) with constrained layout; axes as from ``Figure.subplots`` (squeeze=False)."""
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, **subplot_kw)
    return fig, axes


def colours(n):
    """n distinct colours."""
    from matplotlib import colormaps
    if n <= 10:
        return [colormaps["tab10"](i) for i in range(n)]
    if n <= 20:
        return [colormaps["tab20"](i) for i in range(n)]
    cmap = colormaps["turbo"]
    return [cmap(i / max(n - 1, 1)) for i in range(n)]
