"""The bicycle section of ``reports/systems.md``: the benchmark's linearised eigenvalues from the
SPARK flow (``ldaspark.lab.theory.bicycle_flow``) beside the benchmark's (Meijaard et al. 2007,
``ldaspark.models.bicycle_benchmark``), the weave and capsize speeds, and one nonlinear run.

``bicycle_section(outdir) -> (markdown, json)`` writes the figure ``figures/systems_bicycle.png``
into ``outdir`` and returns the Markdown section and its numbers; the integrator's
``lab/reports/systems.py`` places it. Cost (loaded 2-core machine; the JSON's ``cpu_s``): building the
model (sympy derives the Whipple Lagrangian's partials once, 8-9 s CPU), the generic engine's first
stage evaluation (lambdify, ~6 s), then ~0.12-0.17 s CPU per flow Jacobian (~60 of them) and the
nonlinear run (200 generic steps): 21.6 s CPU in all, measured (6 s of it deriving the model). The compiled engine is not used here: its first call alone (code
generation and numba for this model) is 36 s CPU.
"""
from __future__ import annotations

import os
import time

import numpy as np

from .markdown import jsonable, num, sci, table

#: the speed grid of the table and figure (m/s) and the step of the flow Jacobians
SPEEDS = tuple(float(v) for v in range(0, 11))
FIG_SPEEDS = tuple(np.round(np.arange(0.0, 10.01, 0.5), 2))
#: the nonlinear run: speed, lean rate, t_end, h (gauss-2; h |lambda_castor| = 0.28 at 5 m/s)
NL_SPEED, NL_LEAN_RATE, NL_T, NL_H = 5.0, 0.5, 4.0, 0.02
METHOD, H = "gauss-3", 0.01
ORDER_METHOD, ORDER_H = "gauss-2", (0.04, 0.02, 0.01)
ORDER_SPEED = 5.0


def _fmt(z):
    z = complex(z)
    if abs(z.imag) < 1e-9:
        return f"{z.real:.7f}"
    return f"{z.real:.7f} {'+' if z.imag >= 0 else '-'} {abs(z.imag):.7f}i"


def compiled_cost(model=None, n_steps=1000, h=0.01, method="gauss-2"):
    """CPU seconds of the compiled engine on the scene ``bicycle``: the first call in a process (code
    generation, which runs even when numba's on-disk cache is warm because the source is the cache
    key: 21 s CPU measured with a warm cache, 36 s cold) and per step of a second run of ``n_steps``
    steps, beside the generic engine's per step (20 steps, after its lambdify)."""
    from ...models import bicycle as bc
    from ...solve import integrate
    model = model or bc.build()
    sc = model.scene(5, 0.5)
    c0 = time.process_time()
    integrate(sc, method, n_steps=1, h=h, engine="compiled", raise_on_failure=True)
    first = time.process_time() - c0
    c0 = time.process_time()
    res = integrate(sc, method, n_steps=n_steps, h=h, engine="compiled", raise_on_failure=True)
    per_step = (time.process_time() - c0) / n_steps
    integrate(sc, method, n_steps=1, h=h, engine="generic", raise_on_failure=True)   # lambdify first
    c0 = time.process_time()
    integrate(sc, method, n_steps=20, h=h, engine="generic", raise_on_failure=True)
    generic = (time.process_time() - c0) / 20
    return {"first_call_cpu_s": first, "compiled_step_cpu_s": per_step, "generic_step_cpu_s": generic,
            "max_abs_k": float(np.abs(np.asarray(res.constraint, float)).max()), "method": method, "h": h}


def bicycle_data(fig_speeds=FIG_SPEEDS, speeds=SPEEDS, nonlinear_t=NL_T, measure_compiled=False):
    """All numbers of the section (a dict); ``measure_compiled``: add ``compiled_cost`` (36 s CPU
    with a cold cache, measured: off by default, the main job's budget)."""
    from ...models import bicycle as bc
    from ...models import bicycle_benchmark as bb
    from ..theory import bicycle_flow as bf
    cpu0 = time.process_time()
    model = bc.build()
    cpu_build = time.process_time() - cpu0
    fig = {"v": [], "spark": [], "benchmark": []}
    rows = []
    for v in sorted(set(map(float, fig_speeds)) | set(map(float, speeds))):   # one flow Jacobian per speed
        got = bf.spark_eigenvalues(v, METHOD, H, model=model)
        ref = bf.reference_eigenvalues(v)
        if v in set(map(float, fig_speeds)):
            fig["v"].append(v)
            fig["spark"].append(got)
            fig["benchmark"].append(ref)
        if v in set(map(float, speeds)):
            rows.append({"v": v, "spark": got, "benchmark": ref, "error": bf.match_error(got, ref)})
    ref5 = bf.reference_eigenvalues(ORDER_SPEED)
    errs = [bf.match_error(bf.spark_eigenvalues(ORDER_SPEED, ORDER_METHOD, h, model=model), ref5) for h in ORDER_H]
    orders = [float(np.log2(errs[i] / errs[i + 1])) for i in range(len(errs) - 1)]
    vw, vc = bf.critical_speeds(METHOD, H, model=model)
    pub_vw, pub_vc = float(bb.PUBLISHED["v_weave"]), float(bb.PUBLISHED["v_capsize"])
    run = bf.nonlinear_run(NL_SPEED, NL_LEAN_RATE, nonlinear_t, NL_H, "gauss-2", engine="generic", model=model)
    quarter = max(1, len(run["t"]) // 4)
    nl = {"speed": NL_SPEED, "lean_rate0": NL_LEAN_RATE, "t_end": nonlinear_t, "h": NL_H, "method": "gauss-2",
          "max_abs_k": float(run["k"].max()), "energy_rel_spread": float(np.ptp(run["energy"]) / abs(run["energy"][0])),
          "max_abs_f": float(np.abs(run["f"]).max()),
          "lean_max_first_quarter": float(np.abs(run["lean"][:quarter]).max()),
          "lean_max_last_quarter": float(np.abs(run["lean"][-quarter:]).max()),
          "t": run["t"][::5], "lean": run["lean"][::5], "steer": run["steer"][::5]}
    return {"method": METHOD, "h": H, "rows": rows, "figure": fig,
            "order": {"method": ORDER_METHOD, "v": ORDER_SPEED, "h": list(ORDER_H), "errors": errs, "observed": orders},
            "critical_speeds": {"spark": [vw, vc], "published": [pub_vw, pub_vc],
                                "error": [abs(vw - pub_vw), abs(vc - pub_vc)]},
            "nonlinear": nl, "cpu_build_s": cpu_build,
            "compiled": compiled_cost(model) if measure_compiled else None,
            "cpu_s": time.process_time() - cpu0}


def _figure(data, path):
    from ...core.io import atomic_save_figure
    from .plotting import colours, figure
    fig, axes = figure(1, 2, figsize=(11, 4.2))
    ax, ax2 = axes[0]
    f = data["figure"]
    c = colours(2)
    from ...models import bicycle_benchmark as bb
    fine = np.linspace(0, 10, 201)         # the benchmark's real parts as points on a fine grid (cheap)
    for v in fine:
        ev = np.linalg.eigvals(np.array(bb.state_matrix(v, 15).tolist(), dtype=float))
        ax.plot([v] * 4, ev.real, ".", color=c[0], ms=1.5,
                label="benchmark (Meijaard et al. 2007, App. A)" if v == 0 else None)
    for j in range(4):
        re = [sorted(e, key=lambda z: (z.real, z.imag))[j].real for e in f["spark"]]
        ax.plot(f["v"], re, "o", mfc="none", color=c[1], ms=5,
                label=f"SPARK flow ({METHOD}, h = {H})" if j == 0 else None)
    ax.axhline(0, color="0.5", lw=0.6)
    for v, name in zip(data["critical_speeds"]["spark"], ("v_w", "v_c")):   # the flow's weave / capsize speeds
        ax.axvline(v, color="0.6", lw=0.8, ls="--")
        ax.text(v, -9.3, f" {name}", fontsize=8, color="0.3")
    ax.set_ylim(-10, 10)
    ax.set_xlabel("forward speed v [m/s]")
    ax.set_ylabel("Re lambda [1/s]")
    ax.set_title("Whipple bicycle: real parts of the eigenvalues")
    ax.legend(fontsize=8)
    nl = data["nonlinear"]
    ax2.plot(nl["t"], nl["lean"], label="lean phi")
    ax2.plot(nl["t"], nl["steer"], label="steer delta")
    ax2.set_xlabel("t [s]")
    ax2.set_ylabel("rad")
    ax2.set_title(f"nonlinear run at {num(nl['speed'])} m/s ({nl['method']}, h = {nl['h']})")
    ax2.legend(fontsize=8)
    atomic_save_figure(fig, path)


def bicycle_section(outdir, data=None):
    """(Markdown section, JSON dict); writes ``figures/systems_bicycle.png`` under ``outdir``."""
    data = data or bicycle_data()
    figdir = os.path.join(outdir, "figures")
    os.makedirs(figdir, exist_ok=True)
    _figure(data, os.path.join(figdir, "systems_bicycle.png"))
    rows = [[num(r["v"]), "<br>".join(_fmt(z) for z in r["spark"]), "<br>".join(_fmt(z) for z in r["benchmark"]),
             sci(r["error"])] for r in data["rows"]]
    cs, od, nl = data["critical_speeds"], data["order"], data["nonlinear"]
    lines = [
        "The benchmark of Meijaard, Papadopoulos, Ruina and Schwab (2007).",
        "",
        "Scene `bicycle` (`ldaspark/models/bicycle.py`): four rigid bodies written with `sympy.physics.mechanics`, "
        "n = 8 coordinates, m = 5 constraints (front contact height in its velocity form, rolling of both wheels), "
        "Table 1 parameters. Linearised dynamics about upright straight running from the SPARK flow itself: "
        f"eigenvalues log(mu)/h of the step map's Jacobian (`ldaspark.flow_jacobian`, implicit function theorem) "
        f"restricted to lean, steer and their rates, {METHOD}, h = {H}, beside the benchmark's (its Appendix A "
        "formulas, which reproduce its eq. 5.4 matrices and Table 2 eigenvalues to 1e-14).",
        "",
        *table(["v [m/s]", f"SPARK flow ({METHOD}, h = {H})", "benchmark", "max error"], rows),
        "",
        f"Convergence at v = {num(od['v'])} m/s with {od['method']}: errors "
        + ", ".join(f"{sci(e)} (h = {h})" for e, h in zip(od["errors"], od["h"]))
        + "; observed orders " + ", ".join(f"{o:.2f}" for o in od["observed"]) + " (claimed 2s = 4).",
        "",
        f"Weave and capsize speeds from the SPARK flow ({METHOD}, h = {H}): v_w = {cs['spark'][0]:.10f}, "
        f"v_c = {cs['spark'][1]:.10f} m/s; published (Table 2) {cs['published'][0]:.11f} and "
        f"{cs['published'][1]:.11f} m/s (differences {sci(cs['error'][0])}, {sci(cs['error'][1])}: far below the "
        "eigenvalue errors, as expected of the Gauss methods, whose stability function maps Re lambda = 0 onto "
        "|mu| = 1, so that a crossing of the imaginary axis is not moved by the step size).",
        "",
        f"Nonlinear run from upright at {num(nl['speed'])} m/s with lean rate {num(nl['lean_rate0'])} rad/s "
        f"({nl['method']}, h = {nl['h']}, "
        f"t = 0..{num(nl['t_end'])} s, generic engine): max |k| = {sci(nl['max_abs_k'])}, energy spread "
        f"{sci(nl['energy_rel_spread'])} relative, front contact height |f| <= {sci(nl['max_abs_f'])} m "
        "(the holonomic constraint is imposed in its velocity form only), max |lean| "
        f"{num(nl['lean_max_first_quarter'])} rad in the first quarter, {sci(nl['lean_max_last_quarter'])} rad "
        "in the last (self-stable: the weave decays).",
        "",
        *([f"Compiled engine ({data['compiled']['method']}, h = {data['compiled']['h']}): first call "
           f"{data['compiled']['first_call_cpu_s']:.1f} s CPU (code generation and numba, or the disk cache), then "
           f"{data['compiled']['compiled_step_cpu_s'] * 1e6:.0f} us CPU per step against "
           f"{data['compiled']['generic_step_cpu_s'] * 1e3:.0f} ms on the generic engine.", ""]
          if data.get("compiled") else []),
        "![bicycle eigenvalues vs speed](figures/systems_bicycle.png)",
        "",
        f"_Bicycle section: {data['cpu_s']:.0f} s CPU ({data['cpu_build_s']:.0f} s of it deriving the model)._",
    ]
    out = {k: v for k, v in data.items() if k != "figure"}
    out["rows"] = [{"v": r["v"], "spark": [[z.real, z.imag] for z in r["spark"]],
                    "benchmark": [[z.real, z.imag] for z in r["benchmark"]], "error": r["error"]}
                   for r in data["rows"]]
    return "\n".join(lines) + "\n", jsonable(out)
