"""The compiled SPARK step (mechanical form, dense LU) at its operation count, n = 3..7, s = 2..6.

Per (scene, gauss-s): the floating-point operations of one step of the kernel as implemented
(``kernels.spark_run``: ``kernels_mech``, ``newton``), counted from the sizes and the run's own
counters (stats: Newton iterations, residuals, Jacobians, LUs per step), beside the CPU time per
step measured on the fast path (``run_compiled``, min of repeats). Counted, one flop per
multiplication or addition:

* model: the generated model functions, ops of their cse'd sympy expressions (``sympy.count_ops``):
  grad U, K, b at each residual point (s stages + K, b at the end point), Hess U, K^T Lambda_q,
  k_q per Jacobian point;
* residual (21b, d, e, f) without the model: stage points 2 s^2 n + 2 s n, K^T Lambda and k at
  the stages 4 s n m, (21b, d) (s + 1) n (2 nnz(M)/n + 4 s + 2), (21e, f) 2 (s - 1) s m + 2 n m;
* Jacobian assembly: (s + 1) s s (4 n^2 + 4) + constraint rows (s - 1) s (s (2 m n + 2) + m n)
  + 2 s m n;
* LU of the N = s n + s m + n unknowns: 2/3 N^3 (+ the finiteness check N^2);
* per iteration: the two triangular solves 2 N^2, the update and norms 3 N.

The counted time is flops / R with R the rate of the kernel's own LU code (``newton.lu_factor``)
on a 64 x 64 matrix on this CPU (a dense, unit-stride loop with no call or size overhead):
the step would cost that if all of its operations ran at the speed of its best loop. ratio =
measured / counted (the issue's goal: <= 2).

    python benchmarks/step_cost.py [--steps 5000] [--repeats 3] [--out reports/step_cost.json]
"""
from __future__ import annotations

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))

import numpy as np  # noqa: E402

# the generic kernel is timed, as in the reports: no specialised kernel built in the background
# mid-run (ldaspark.compiled.specialised; benchmarks/quasi_step.py times both)
os.environ.setdefault("LDASPARK_SPECIALISE", "0")

SCENES = (("particle", {}), ("skate", {}), ("robot", {}), ("mp-particles-nh", {"m": 2}), ("mp-particles-nh", {}))
METHODS = ("gauss-2", "gauss-3", "gauss-4", "gauss-5", "gauss-6")
H = 0.1


def _scene(name, kw):
    from ldaspark.models.scenes import SCENES as BUILD, get_scene
    return BUILD[name](**kw) if kw else get_scene(name)


def _ops(exprs):
    import sympy
    exprs = [sympy.sympify(e) for e in exprs]
    reps, red = sympy.cse(exprs)
    return int(sum(sympy.count_ops(e) for _, e in reps) + sum(sympy.count_ops(e) for e in red))


def model_ops(system):
    """(flops of one residual point: grad U, K, b; of one Jacobian point: Hess U, d(K^T lam)/dq, k_q)."""
    import sympy
    from ldaspark.compiled.fast import mechanical_parts
    parts = mechanical_parts(system)
    q, v = list(system.q), list(system.v)
    U, K, b = parts["U"], sympy.Matrix(parts["K"]), sympy.Matrix(parts["b"])
    gU = [sympy.diff(U, x) for x in q]
    lam = sympy.symbols(f"lam0:{K.shape[0]}")
    KTl = K.T * sympy.Matrix(lam)
    point = _ops(gU) + _ops(list(K)) + _ops(list(b))
    jac = (_ops([sympy.diff(g, x) for g in gU for x in q]) + _ops(list(KTl.jacobian(q)))
           + _ops(list((K * sympy.Matrix(v) + b).jacobian(q))))
    return point, jac


def counted(s, n, m, nnzM, per_step, mops):
    """Flops per step of the dense mechanical kernel, by part."""
    N = s * n + s * m + n
    res = 2 * s * s * n + 2 * s * n + 4 * s * n * m + (s + 1) * (2 * nnzM + n * (4 * s + 2)) \
        + 2 * (s - 1) * s * m + 2 * n * m
    jac = (s + 1) * s * s * (4 * n * n + 4) + (s - 1) * s * (s * (2 * m * n + 2) + m * n) + 2 * s * m * n
    nres, njac, nit, nlu = per_step["residuals"], per_step["njev"], per_step["iterations"], per_step["nlu"]
    parts = {
        "model": nres * (s + 1) * mops[0] + njac * (s + 1) * mops[1],
        "residual": nres * res,
        "jacobian": njac * jac,
        "lu": nlu * (2 * N ** 3 / 3 + N * N),
        "solves": nit * (2 * N * N + 3 * N),
    }
    parts["total"] = sum(parts.values())
    return N, parts


def lu_rate(size=64, repeats=5):
    """Flops per second of ``newton.lu_factor`` on a well-conditioned size x size matrix."""
    from numba import njit
    from ldaspark.compiled.newton import lu_factor

    @njit(cache=False)
    def loop(A, B, piv, k):
        for _ in range(k):
            B[:, :] = A
            lu_factor(B, piv)

    rng = np.random.default_rng(0)
    A = rng.standard_normal((size, size)) + size * np.eye(size)
    B, piv = A.copy(), np.zeros(size, dtype=np.int64)
    loop(A, B, piv, 1)
    k = 2000
    best = min(_cpu(lambda: loop(A, B, piv, k)) for _ in range(repeats))
    return k * (2 * size ** 3 / 3) / best


def _cpu(f):
    c = time.process_time()
    f()
    return time.process_time() - c


def measure(name, kw, method, steps, repeats):
    from ldaspark.compiled.fast import compile_system, run_compiled
    sc = _scene(name, kw)
    cs = compile_system(sc.system)
    t0, q0, v0 = sc.initial()
    q0, v0 = np.array(q0, float), np.array(v0, float)
    args = (cs, method, float(t0), q0, v0, H, steps)
    run_compiled(*args[:-1], 10, kernel="spark", reuse_matrix=False, linear_solver="dense")
    best, sol = np.inf, None
    for _ in range(repeats):
        c = time.process_time()
        sol = run_compiled(*args, every=steps, kernel="spark", reuse_matrix=False, linear_solver="dense")
        best = min(best, time.process_time() - c)
    st = sol.stats
    s = int(method.split("-")[1])
    nres = (st["nfev"] - st["njev"] * (s + 1)) / (s + 1)        # residual calls (each s + 1 points)
    per = {"iterations": st["newton_iterations"] / steps, "nfev": st["nfev"] / steps,
           "njev": st["njev"] / steps, "nlu": st["nlu"] / steps, "residuals": nres / steps}
    nnzM = int(np.count_nonzero(cs.M))
    N, parts = counted(s, cs.n, cs.m, nnzM, per, model_ops(sc.system))
    return {"scene": name + (f"(m={kw['m']})" if kw else ""), "n": cs.n, "m": cs.m, "method": method, "s": s,
            "N": N, "h": H, "per_step": per, "flops": parts, "us_per_step": best / steps * 1e6}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=5000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=os.path.join(HERE, "..", "reports", "step_cost.json"))
    a = ap.parse_args(argv)
    rate = lu_rate()
    rows = []
    print(f"reference rate R (lu_factor, 64 x 64): {rate / 1e9:.2f} Gflop/s")
    print(f"{'scene':22s} {'n':>2s} {'method':8s} {'N':>3s} {'it':>5s} {'nfev':>5s} {'flops':>7s} "
          f"{'(model/res/jac/lu/solve)':>30s} {'counted us':>10s} {'us/step':>8s} {'ratio':>6s}")
    for name, kw in SCENES:
        for method in METHODS:
            r = measure(name, kw, method, a.steps, a.repeats)
            f = r["flops"]
            r["counted_us"] = f["total"] / rate * 1e6
            r["ratio"] = r["us_per_step"] / r["counted_us"]
            rows.append(r)
            split = "/".join(f"{f[k]:.0f}" for k in ("model", "residual", "jacobian", "lu", "solves"))
            print(f"{r['scene']:22s} {r['n']:2d} {method:8s} {r['N']:3d} {r['per_step']['iterations']:5.2f} "
                  f"{r['per_step']['nfev']:5.1f} {f['total']:7.0f} {split:>30s} {r['counted_us']:10.2f} "
                  f"{r['us_per_step']:8.2f} {r['ratio']:6.2f}", flush=True)
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    from ldaspark.core.io import atomic_write_json
    atomic_write_json(a.out, {"rate_flops_per_s": rate, "load_average": list(load), "steps": a.steps,
                              "repeats": a.repeats, "rows": rows})


if __name__ == "__main__":
    main()
