"""Nonideal constraints (3.3) on the compiled general kernel, measured side by side in one run:
steps per second (CPU time, best of ``--reps`` runs, generic path best of 3) on ``friction-skate`` for the compiled
kernel, the same skate with N dropped on the general kernel (the price of N, N_q, N_v, N_psi),
and the generic path; plus the agreement of the compiled and generic trajectories.

Usage: python benchmarks/compiled_nonideal.py [--reps 9] [--steps 20000]
"""
import argparse
import time

import numpy as np

from ldaspark.compiled.fast import compile_system, run_compiled
from ldaspark.core.families import get_method
from ldaspark.models.scenes import get_scene
from ldaspark.core.spark import integrate
from ldaspark.core.system import LagrangianSystem


def best_cpu(fn, reps):
    best = float("inf")
    for _ in range(reps):
        c = time.process_time()
        out = fn()
        best = min(best, time.process_time() - c)
    return best, out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--reps", type=int, default=9)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--h", type=float, default=0.001)
    a = ap.parse_args()
    S = get_scene("friction-skate").system
    ideal = LagrangianSystem(S.L, list(S.k), S.q, S.v, S.t, name="skate-no-N")
    cs, cs0 = compile_system(S), compile_system(ideal, form="general")
    q0, v0 = [0.0, 0.0, 0.0], [0.0, 0.0, 1.0]
    n_gen = max(a.steps // 40, 50)
    print(f"friction-skate, h = {a.h}, CPU time, best of {a.reps}; generic path: {n_gen} steps")
    print("method | compiled steps/s (us/step) | N dropped, general kernel | generic steps/s | compiled/generic "
          "| max |q_c - q_g| over the generic run")
    for meth in ("gauss-1", "gauss-2", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-iiid-2", "gauss-3"):
        def run(c=cs, n=a.steps):
            return run_compiled(c, meth, 0.0, q0, v0, a.h, n, every=n, kernel="spark")
        run(n=10)
        run(cs0, 10)
        tc = t0 = float("inf")
        for _ in range(a.reps):                 # alternated, so that a change of load hits both
            tc = min(tc, best_cpu(run, 1)[0])
            t0 = min(t0, best_cpu(lambda: run(cs0), 1)[0])
        tg, g = best_cpu(lambda: integrate(S, get_method(meth), 0.0, q0, v0, a.h, n_steps=n_gen), 3)
        fc = run_compiled(cs, meth, 0.0, q0, v0, a.h, n_gen, compensated=False, kernel="spark")
        err = float(np.abs(fc.q - np.asarray(g.q, float)).max())
        sc, s0, sg = a.steps / tc, a.steps / t0, n_gen / tg
        print(f"{meth} | {sc:.3g} ({1e6 / sc:.1f}) | {s0:.3g} ({1e6 / s0:.1f}) | {sg:.3g} | {sc / sg:.0f}x | {err:.1e}",
              flush=True)


if __name__ == "__main__":
    main()
