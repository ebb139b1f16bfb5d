"""Data of the paper's Fig. 4 (section 8.4): McLachlan-Perlmutter particles, m = 3 (n = 7).

For the J + 1 initial conditions j = 0..J of ``scenes.mp_particles(m=3, J=J, j=j)`` (all on the
energy surface E0 = 3.06) and three methods,

* ``lobatto-iiia-iiib-2``          the 2-stage Lobatto IIIA-B SPARK method (25),
* ``lobatto-iiia-iiib-2-modified`` (K1 + K2)/2 = 0 replaced by k(t0 + h/2, q0 + h/2 V1, V1) = 0,
* ``mp-lobatto-iiib-a-2``          McLachlan-Perlmutter's Lobatto IIIB-A LDA method (26),

it computes mu((E_.k - E0)^2) / h^4 = (1/(J+1)) sum_j (E_jk - E0)^2 / h^4 at t_k = t0 + every k h,
and fits the growth exponent p of mu ~ t^p on a late window (random walk: p ~ 1, i.e.
sqrt(mu) ~ h^2 sqrt(t)). Runs on the compiled fast path, all (method, j) runs in one executor.
"""
from __future__ import annotations

import math
import time

import numpy as np

from ...ensemble import RunSpec, run_many
from ...core.errors import InputError

FIG4_METHODS = ("lobatto-iiia-iiib-2", "lobatto-iiia-iiib-2-modified", "mp-lobatto-iiib-a-2")


def fit_growth(t, mu, window):
    """Least-squares slope of log mu against log t for t in [t_a, t_b] (samples with mu > 0)."""
    t = np.asarray(t, float)
    mu = np.asarray(mu, float)
    sel = (t >= window[0]) & (t <= window[1]) & (mu > 0)
    if sel.sum() < 3:
        raise InputError(f"growth fit window {window} holds fewer than 3 samples")
    p, _ = np.polyfit(np.log(t[sel]), np.log(mu[sel]), 1)
    return float(p)


def figure4_data(t_end=50000.0, h=0.05, J=9, every=100, executor=None, methods=FIG4_METHODS,
                 window=None, compensated=True, constraint="printed") -> dict:
    """Fig. 4 data. Returns {"t": sample times, "methods": names, "mu_over_h4": {name: list},
    "E0": energy of the initial data, "E0_spread": max |E_j0 - E0|, "fit": {name: {"exponent",
    "window"}}, "seconds": wall time, "n_steps", "h", "J", "every", "newton": {name: mean
    iterations}}. ``window`` defaults to [t_end / 100, t_end]. ``constraint`` picks the scene
    variant of ``scenes.mp_particles``: "printed" (as in 8.4; integrable) or "nonholonomic"."""
    from ...models.scenes import mp_particles
    t0_wall = time.perf_counter()
    from ...core.spark import MAX_STEPS
    if not all(isinstance(x, (int, float)) and math.isfinite(x) and x > 0 for x in (t_end, h)):
        raise InputError(f"t_end and h must be finite positive numbers, got t_end = {t_end}, h = {h}")
    if t_end / h > MAX_STEPS:
        raise InputError(f"t_end / h = {t_end / h:.3g} steps, more than the limit {MAX_STEPS:.0e}")
    if isinstance(every, bool) or not isinstance(every, int) or every <= 0:
        raise InputError(f"every must be a positive integer, got {every!r}")
    n_steps = int(round(t_end / h))
    if n_steps <= 0 or abs(n_steps * h - t_end) > 1e-9 * max(1.0, t_end):
        raise InputError(f"t_end = {t_end} must be a positive multiple of h = {h}")
    if n_steps % every:
        raise InputError(f"n_steps = {n_steps} must be a multiple of every = {every}")
    scenes = [mp_particles(m=3, J=J, j=j, constraint=constraint) for j in range(J + 1)]
    system = scenes[0].system          # the system does not depend on j, only the data do
    ics = [sc.initial() for sc in scenes]
    t0 = ics[0][0]
    Q0 = np.array([ic[1] for ic in ics])
    V0 = np.array([ic[2] for ic in ics])
    specs = [RunSpec(system, name, t0, Q0, V0, h, n_steps, every, compensated) for name in methods]
    results = run_many(specs, executor=executor)
    window = list(window) if window is not None else [t_end / 100.0, t_end]
    E_init = results[0].energy[:, 0]
    E0 = float(np.mean(E_init))
    out = {"t": results[0].t.tolist(), "methods": list(methods), "mu_over_h4": {}, "fit": {},
           "E0": E0, "E0_spread": float(np.max(np.abs(E_init - E0))), "n_steps": n_steps, "h": h,
           "J": J, "every": every, "newton": {}, "constraint": constraint, "scene": system.name}
    for name, res in zip(methods, results):
        mu = np.mean((res.energy - E0) ** 2, axis=0) / h ** 4
        out["mu_over_h4"][name] = mu.tolist()
        out["fit"][name] = {"exponent": fit_growth(res.t, mu, window), "window": window}
        out["newton"][name] = float(np.mean([s["mean_iterations"] for s in res.stats]))
    out["seconds"] = time.perf_counter() - t0_wall
    return out
