"""Probe for item 3 of issue 48 (kernels specialised per (s, n, m)): the quasi-Newton kernel
(``ldaspark.compiled.kernels_quasi`` with the residual ``kernels_mech.mech_residual`` and
``newton.stage_points``) regenerated with the sizes s, n, m as module globals, which numba freezes
as compile-time constants (LLVM then knows the trip counts of the small loops), compiled once
(uncached, into a temporary directory) and timed against the generic kernel on the same run
(CPU per step, minimum of interleaved rounds). A measurement, not the feature: nothing here is
used by ``ldaspark.integrate``.

    python benchmarks/quasi_specialised_probe.py [--scene particle] [--method gauss-6] [--h 0.4]
"""
from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from ldaspark.compiled import quasi as Q                                           # noqa: E402
from ldaspark.compiled.runner import STAT_NAMES, compile_system, kernel_spec, n_samples   # noqa: E402
from ldaspark.models.scenes import get_scene                                        # noqa: E402

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "ldaspark", "compiled")


def _grab(text, name):
    m = re.search(r"(@numba\.njit\([^\n]*\)\ndef " + name + r"\(.*?)(?=\n\n\n|\Z)", text, re.S)
    return m.group(1)


def specialised_source(s, n, m) -> str:
    """kernels_quasi's source with mech_residual and stage_points copied in and every size read
    from an array shape on the step's path replaced by the constants S_, N_, M_."""
    src = open(os.path.join(HERE, "kernels_quasi.py")).read()
    mech = open(os.path.join(HERE, "kernels_mech.py")).read()
    newton = open(os.path.join(HERE, "newton.py")).read()
    extra = _grab(mech, "mech_residual") + "\n\n\n" + _grab(newton, "stage_points") + "\n\n\n"
    src = src.replace("from .kernels_mech import mech_residual, mech_workspace",
                      "from ldaspark.compiled.kernels_mech import mech_workspace")
    src = src.replace("from . import modeltypes as mt", "from ldaspark.compiled import modeltypes as mt")
    src = src.replace("from .kernels import", "from ldaspark.compiled.kernels import")
    src = src.replace("from .newton import (", "from ldaspark.compiled.newton import (")
    src = src.replace("QUASI_SIG = types.void", f"S_, N_, M_ = {int(s)}, {int(n)}, {int(m)}\n\n" + extra
                      + "\nQUASI_SIG = types.void")
    src = re.sub(r"^(\s+)s, n, m = [^\n]*$", r"\1s, n, m = S_, N_, M_", src, flags=re.M)
    src = re.sub(r"^(\s+)s, n = [A-Za-z_]+\.shape\[0\], [A-Za-z0-9_]+\.shape\[\d\]$", r"\1s, n = S_, N_", src,
                 flags=re.M)
    src = re.sub(r"^(\s+)s = tab\[1\]\.shape\[0\]$", r"\1s = S_", src, flags=re.M)
    src = re.sub(r"^(\s+)n = q0\.shape\[0\]$", r"\1n = N_", src, flags=re.M)
    src = re.sub(r"^(\s+)m = out_k\.shape\[1\]$", r"\1m = M_", src, flags=re.M)
    src = src.replace("for a in range(out.shape[0]):", "for a in range(N_):")
    return src.replace("cache=True", "cache=False")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="particle")
    ap.add_argument("--method", default="gauss-6")
    ap.add_argument("--h", type=float, default=0.4)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--rounds", type=int, default=5)
    a = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    sc = get_scene(a.scene)
    cs = compile_system(sc.system)
    if cs.form != "mechanical":
        print("the probe specialises the mechanical kernel only", file=sys.stderr)
        return 2
    t0, q0, v0 = sc.initial()
    what = kernel_spec(a.method, "spark")[1]
    s = what[1].shape[0]
    with tempfile.TemporaryDirectory() as d:
        with open(os.path.join(d, "quasi_specialised.py"), "w") as fh:
            fh.write(specialised_source(s, cs.n, cs.m))
        sys.path.insert(0, d)
        import quasi_specialised as K
        w0 = time.time()
        K.quasi_run.compile(K.QUASI_SIG)
        compile_s = time.time() - w0
        ep = K.quasi_run.overloads[tuple(K.QUASI_SIG.args)].entry_point
    Ev, El = Q.extrapolation(what[0])
    N = a.steps

    def spec():
        S = n_samples(N, N)
        outs = (np.zeros(S), np.zeros((S, cs.n)), np.zeros((S, cs.n)), np.zeros(S), np.zeros((S, cs.m)))
        stats = np.zeros(len(STAT_NAMES), dtype=np.int64)
        qstats = np.zeros(len(Q.QUASI_STAT_NAMES), dtype=np.int64)
        out_x = np.zeros(s * (cs.n + cs.m) + cs.n + (S - 1) * s * cs.m)
        ep(cs.model, what, cs.M, cs.Minv, Ev, El, float(t0), np.array(q0, float), np.array(v0, float), a.h, N, N,
           True, Q._TOL_DEFAULT, 50, 3, *outs, stats, out_x, qstats, True)
        return outs[1][-1]
    best_s = best_g = float("inf")
    for _ in range(a.rounds):
        c0 = time.process_time()
        qs = spec()
        c1 = time.process_time()
        g = Q.run_quasi(cs, a.method, t0, q0, v0, a.h, N, N)
        c2 = time.process_time()
        best_s, best_g = min(best_s, c1 - c0), min(best_g, c2 - c1)
    print(f"{a.scene} {a.method} h={a.h:g}: specialised (s, n, m) = ({s}, {cs.n}, {cs.m}) "
          f"{best_s / N * 1e6:.2f} us/step, generic {best_g / N * 1e6:.2f} us/step, speed-up {best_g / best_s:.2f}; |dq_final| "
          f"{np.abs(qs - g.q[-1]).max():.1e}; compile {compile_s:.0f} s wall; load average {os.getloadavg()[0]:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
