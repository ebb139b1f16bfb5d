"""Full vs simplified vs auto Newton on the generic path: steps/s and the difference of the
trajectories, on every named scene and a few methods per family, float64 and 30 digits.

For each (scene, method, precision) the three variants of ``SparkMethod(newton=...)`` run the
same N steps of h = 0.05 from the scene's initial data (CPU time, ``time.process_time``);
the table gives steps/s of each and max over the N steps of |q_x - q_full|, |v_x - v_full|
in units of the Newton tolerance tol = 10 eps (the default of ``SparkMethod``), so "<= 10"
means the variants agree to within what the Newton stopping rule promises.

    python benchmarks/newton_variants.py [--steps 200] [--dps 30] [--repeat 3] [--methods-mp gauss-2,...]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import mpmath
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from ldaspark.core.backend import Backend                 # noqa: E402
from ldaspark.core.errors import LdasparkError            # noqa: E402
from ldaspark.core.families import get_method             # noqa: E402
from ldaspark.models.scenes import SCENES, get_scene        # noqa: E402
from ldaspark.core.spark import integrate                 # noqa: E402

METHODS_F64 = ("gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3",
               "lobatto-iiia-iiib-iiid-2", "lobatto-iiia-iiib-iiid-3")
METHODS_MP = ("gauss-2", "lobatto-iiia-iiib-3")
VARIANTS = ("full", "simplified", "auto")


def run(scene, method, dps, steps, newton, h="0.05"):
    sc, tab = get_scene(scene), get_method(method)
    t0, q0, v0 = sc.initial(dps)
    hh = float(h) if dps is None else mpmath.mpf(h)
    if dps is not None:
        with mpmath.workdps(dps):
            hh = mpmath.mpf(h)
    c = time.process_time()
    try:
        sol = integrate(sc.system, tab, t0, q0, v0, hh, n_steps=steps, dps=dps, newton=newton)
    except LdasparkError as exc:
        return time.process_time() - c, None, f"{type(exc).__name__}: {str(exc)[:60]}"
    return time.process_time() - c, sol, ""


def max_diff(a, b, dps):
    with mpmath.workdps(dps or 15):
        return float(max(abs(x - y) for x, y in zip(a.reshape(-1), b.reshape(-1))))


def table(dps, steps, methods, scenes, repeat=1):
    tol = 10 * Backend(dps).eps            # SparkMethod's default tolerance
    print(f"\nprecision {dps or 'float64'}: {steps} steps of h = 0.05, tol = {tol:.1e}; "
          "difference to full Newton in units of tol (max over the steps, q | v)")
    print(f"{'scene':>16} {'method':>24} {'full st/s':>9} {'simp st/s':>9} {'auto st/s':>9} "
          f"{'simp dq|dv':>15} {'auto dq|dv':>15} {'LU full/auto':>12}")
    worst, ratios = 0.0, []
    for scene in scenes:
        for method in methods:
            out = {}
            for _ in range(repeat):       # interleaved repeats, the least CPU time of each variant
                for nw in VARIANTS:
                    r = run(scene, method, dps, steps, nw)
                    out[nw] = r if nw not in out or r[0] < out[nw][0] else out[nw]
            tf, full, why = out["full"]
            if full is None:
                print(f"{scene:>16} {method:>24} full Newton fails: {why}")
                continue
            cols = []
            for nw in ("simplified", "auto"):
                _, sol, why = out[nw]
                if sol is None:
                    cols.append(f"{'fails':>15}")
                    continue
                dq, dv = max_diff(sol.q, full.q, dps) / tol, max_diff(sol.v, full.v, dps) / tol
                if nw == "auto":
                    worst = max(worst, dq, dv)
                cols.append(f"{dq:>7.1f}|{dv:<7.1f}")
            if out["auto"][1] is not None:
                ratios.append(tf / out["auto"][0])
            sps = [f"{steps / out[nw][0]:>9.0f}" if out[nw][1] is not None else f"{'-':>9}" for nw in VARIANTS]
            lu = (f"{full.stats['nlu']}/{out['auto'][1].stats['nlu']}" if out["auto"][1] is not None else "-")
            print(f"{scene:>16} {method:>24} {' '.join(sps)} {' '.join(cols)} {lu:>12}", flush=True)
    print(f"largest auto-full difference: {worst:.1f} tol; steps/s auto / full: median {np.median(ratios):.2f}, "
          f"range {min(ratios):.2f}-{max(ratios):.2f} over {len(ratios)} rows")
    return worst


def jacobian_table(calls=300):
    """float64 Newton matrix: ``_jacobian_einsum`` vs ``_jacobian_blocks`` on the same stage
    values (median CPU microseconds of ``calls`` assemblies) and their largest difference."""
    from ldaspark.core.spark import SparkMethod
    print(f"\nfloat64 Newton matrix assembly, median CPU us of {calls} calls (same stage values)")
    print(f"{'scene':>16} {'method':>24} {'size':>5} {'einsum':>8} {'blocks':>8} {'einsum/blocks':>13} {'max |diff|':>10}")
    for scene in ("robot", "particle", "mp-particles"):
        for method in ("gauss-2", "lobatto-iiia-iiib-3"):
            sc = get_scene(scene)
            meth = SparkMethod(sc.system, get_method(method))
            t0, q0, v0 = sc.initial()
            q0, v0, h = np.array(q0), np.array(v0), 0.05
            x = meth.initial_guess(v0)
            V, Lam, v1 = meth.unpack(x)
            T = [t0 + meth.tab.c[i] * h for i in range(meth.s)]
            Q = q0 + meth.tab.A.dot(V) * h
            bk = meth.backend
            st = [sc.system.stage(bk, T[i], Q[i], V[i], Lam[i], True, h=h) for i in range(meth.s)]
            fin = sc.system.stage(bk, t0 + h, q0 + meth.tab.b.dot(V) * h, v1, bk.zeros(meth.m), True)
            out = {}
            for name in ("_jacobian_einsum", "_jacobian_blocks"):
                fn = getattr(meth, name)
                ts = []
                for _ in range(calls):
                    c = time.process_time()
                    J = fn(h, st, fin)
                    ts.append(time.process_time() - c)
                out[name] = (float(np.median(ts)), J)
            e, b = out["_jacobian_einsum"], out["_jacobian_blocks"]
            print(f"{scene:>16} {method:>24} {meth.size:>5} {e[0] * 1e6:>8.1f} {b[0] * 1e6:>8.1f} "
                  f"{e[0] / b[0]:>13.2f} {np.max(np.abs(e[1] - b[1])):>10.1e}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--dps", type=int, default=30)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--methods", default=",".join(METHODS_F64))
    ap.add_argument("--methods-mp", default=",".join(METHODS_MP))
    ap.add_argument("--repeat", type=int, default=1, help="interleaved repeats (least CPU time kept)")
    ap.add_argument("--skip-f64", action="store_true")
    ap.add_argument("--skip-mp", action="store_true")
    ap.add_argument("--jacobian-only", action="store_true", help="only the float64 Newton-matrix assembly table")
    a = ap.parse_args(argv)
    jacobian_table()
    if a.jacobian_only:
        return
    scenes = a.scenes.split(",")
    if not a.skip_f64:
        table(None, a.steps, a.methods.split(","), scenes, a.repeat)
    if not a.skip_mp:
        table(a.dps, a.steps, a.methods_mp.split(","), scenes, a.repeat)


if __name__ == "__main__":
    main()
