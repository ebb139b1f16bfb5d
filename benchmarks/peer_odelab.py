"""An external peer side by side: odelab (O. Verdier, github.com/olivierverdier/odelab) against
this library on odelab's mobile robot, defined identically on both sides; 1000 steps of h = 0.05.

odelab is not a dependency of ldaspark. Set it up in a separate environment (odelab needs
``newton`` and ``padexp``, same author), e.g.::

    python3 -m venv /tmp/venv-peer
    for r in odelab newton padexp; do git clone https://github.com/olivierverdier/$r; done
    (cd odelab && git apply /path/to/ldaspark/benchmarks/peer/odelab-compat.patch)
    /tmp/venv-peer/bin/pip install numpy scipy -e newton -e padexp -e odelab -e /path/to/ldaspark
    /tmp/venv-peer/bin/python benchmarks/peer_odelab.py          # writes reports/peer_odelab.json

The patch adds the subpackage ``odelab.system.exponential``, missing from odelab's setup.py
(a plain, non-editable install fails to import odelab without it). Editable installs record the
commits of the three clones in the JSON.

The system. odelab's ``odelab.system.nonholonomic.rolling.Robot``: state u = (q, v, lambda) with
q = (x, y, phi, theta) = u[0:4], v = u[4:8], lambda = u[8:10]; identity mass matrix (the default
``momentum``), force f = (0, 0, 0, -10 cos q[3]), codistribution A(q) = [[1, 0, 0, -cos q[2]],
[0, 1, 0, -sin q[2]]], constraint A(q) v = 0, equations v' = f + A^T lambda, energy
|v|^2/2 + 10 sin q[3]. Here: the built-in robot of 8.3 (``ldaspark.models.scenes.robot``),
L = m(v1^2 + v2^2)/2 + I v3^2/2 + 3 I_w v4^2/2 - 10 sin q4, k = (v1 - l cos(q3) v4,
v2 - l sin(q3) v4), with m = I = l = 1 and I_w = 1/3 (the paper's I_w = 1 gives the wheel a
mass 3, odelab's mass matrix is the identity): then M = I, grad U = -f, K(q) = A(q), b = 0 and
(1b) M v' = -grad U - K^T psi is odelab's equation with lambda = -psi. Variables map one to one,
q_i+1 (here, 1-based) = u[i] (odelab, 0-based).

The methods (read from odelab's source, and the coefficients checked below at run time):
* odelab ``Spark2``/``Spark3`` (``odelab.scheme.rungekutta.Spark``, after Jay 2003): Lobatto IIIA
  on q' = v, Lobatto IIIB on v' = f + A^T lambda (force and reaction alike), constraint rows
  sum_j a_ij A(Q_j) V_j = 0 for the IIIA rows i = 2..s and A(q1) v1 = 0. That is
  ``lobatto-iiia-iiib-s`` here (A = IIIA, A_hat = A_tilde = IIIB, b, and (21e) whose rows omega span
  the same space as odelab's IIIA rows, (21f) the same).
* odelab ``McLachlan`` (McLachlan-Perlmutter (4.18)): q_1/2 = q0 + h/2 v0, p1 = p0 + h f(q_1/2) -
  A(q_1/2)^T lambda, q1 = q_1/2 + h/2 v1, A(q1) v1 = 0; that is (26), ``mp-lobatto-iiib-a-2``
  here (lambda = h Psi_1). It is not the form (25) (``lobatto-iiia-iiib-2-leapfrog``), which has
  the constraint (25) and grad U at q0; the run against (25) is the negative control.
* Not compared: odelab ``NonHolonomicLeapFrog`` imposes A(q_i)(v_i + v_i+1) = 0 at one point q_i,
  where (25) averages K(q_k) and K(q_k+1) on one velocity; ``SymplecticEuler`` and the
  ``NonHolonomicEnergy*`` schemes (discrete-gradient force) have no counterpart here.

odelab's ``Robot`` lacks ``state`` and its ``codistribution`` takes one state at a time, while
``Spark`` evaluates all stages at once; ``SparkRobot`` below adds both (the stacked form of the
same matrix, as odelab's ``VerticalRollingDisk`` writes it). odelab solves each step with
``scipy.optimize.fsolve`` (xtol 1.5e-8), so agreement is to that tolerance; a second, untimed
odelab run with xtol 1e-12 shows how much of the difference that tolerance accounts for.

Usage: python benchmarks/peer_odelab.py [--n-steps 1000] [--h 0.05] [--out reports/peer_odelab.json]
"""
from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
import sys
import time

import numpy as np
import sympy

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# (initial data label, v0); q0 = 0 throughout. "odelab-test" is the robot's data in odelab's own
# tests (= the paper's 8.3); with v3 = 0 the heading q3 stays 0, so "turning" (v3 = 1/2) also
# exercises K(q) varying along the trajectory.
INITIAL = (("odelab-test", (1.0, 0.0, 0.0, 1.0)), ("turning", (1.0, 0.0, 0.5, 1.0)))  # (1b) holds: v1 = cos(q3) v4
# (odelab scheme, ldaspark method, matched?)
PAIRS = (("Spark2", "lobatto-iiia-iiib-2", True), ("Spark3", "lobatto-iiia-iiib-3", True),
         ("McLachlan", "mp-lobatto-iiib-a-2", True), ("McLachlan", "lobatto-iiia-iiib-2-leapfrog", False))
TIGHT_XTOL = 1e-12
NOT_COMPARED = {
    "NonHolonomicLeapFrog": "constraint A(q_i)(v_i + v_i+1) = 0 at one point; (25) averages K(q_k), K(q_k+1) "
                            "on one velocity v_k+1/2: a different method",
    "SymplecticEuler": "q1 = q0 + h v0 and the force at q1 as in euler-ii, but the reaction uses A((q0 + q1)/2) "
                       "where euler-ii uses K(q1): a different method",
    "NonHolonomicEnergy (and -0, -EMP)": "discrete-gradient (average) force with a multiplier recursion: "
                                         "not a method of this library",
}


def odelab_robot_scene(v0=INITIAL[0][1]):
    """odelab's Robot as a scene here: the built-in robot (8.3) with I_w = 1/3 (M = identity)."""
    from dataclasses import replace
    from ldaspark.models.scenes import robot
    sc = robot(I_w=sympy.Rational(1, 3))
    return replace(sc, name="robot", v0=[sympy.nsimplify(x) for x in v0], _exact_fns={},
                   description="odelab's mobile robot: robot (8.3) with I_w = 1/3")


# --- odelab side ------------------------------------------------------------------------------
def _odelab_classes():
    from odelab.system.nonholonomic.rolling import Robot

    class SparkRobot(Robot):
        """odelab's Robot with what its Spark scheme needs: ``state`` and a stacked codistribution."""

        def state(self, u):
            return u[:8]

        def codistribution(self, u):
            q2 = self.position(u)[2]
            one, zero = np.ones_like(q2), np.zeros_like(q2)
            return np.array([[one, zero, zero, -np.cos(q2)], [zero, one, zero, -np.sin(q2)]])
    return Robot, SparkRobot


def _odelab_solver(scheme_name, v0, h):
    import odelab.scheme.rungekutta as rk
    from odelab import Solver
    from odelab.scheme.constrained import McLachlan
    Robot, SparkRobot = _odelab_classes()
    scheme = McLachlan() if scheme_name == "McLachlan" else getattr(rk, scheme_name)()
    scheme.h = h
    s = Solver(scheme, Robot() if scheme_name == "McLachlan" else SparkRobot())
    u0 = np.zeros(10)
    u0[4:8] = v0
    s.initialize(u0=u0)
    return s


def run_odelab(scheme_name, v0, h, n, xtol=None):
    """(CPU seconds of Solver.run, t, q, v, energy, constraint) of n steps of odelab's scheme,
    timed after a 2-step run (imports of scipy.optimize and the like outside the clock).
    ``xtol``: fsolve's tolerance in odelab's root solver (default 1.49012e-8) for this run."""
    import newton
    _odelab_solver(scheme_name, v0, h).run(time=1.5 * h)
    s = _odelab_solver(scheme_name, v0, h)
    default = newton.FSolve.xtol
    newton.FSolve.xtol = default if xtol is None else xtol
    try:
        t = time.process_time()
        s.run(time=(n - 0.5) * h)          # stops at the first t > (n - 1/2) h: exactly n steps
        cpu = time.process_time() - t
    finally:
        newton.FSolve.xtol = default
    with s.open_store() as events:
        ev = np.array(events[:, :])                 # (u, t) columns at every step point
    if ev.shape[1] != n + 1:
        raise RuntimeError(f"odelab made {ev.shape[1] - 1} steps, not {n}")
    u = ev[:-1].T
    energy = np.array([s.system.energy(x) for x in u])
    Robot, _ = _odelab_classes()
    cons = np.array([Robot().codistribution(x[:4]) @ x[4:8] for x in u])
    return cpu, ev[-1], u[:, :4], u[:, 4:8], energy, cons


# --- ldaspark side ----------------------------------------------------------------------------
def run_ldaspark(scene, method, h, n, engine, repeats=1):
    """(best CPU seconds of ``repeats``, Result) of ``ldaspark.integrate`` on ``scene``, timed
    after a 2-step run (sympy derivation, lambdify and numba compilation outside the clock)."""
    import ldaspark
    ldaspark.integrate(scene, method, h=h, n_steps=2, engine=engine, raise_on_failure=True)
    best, res = float("inf"), None
    for _ in range(repeats):
        t = time.process_time()
        res = ldaspark.integrate(scene, method, h=h, n_steps=n, engine=engine, raise_on_failure=True)
        best = min(best, time.process_time() - t)
    return best, res


# --- coefficients read from odelab, compared with this library's tableaux ----------------------
def _same_rows(P, Q):
    """The rows of P and Q span the same space."""
    r = np.linalg.matrix_rank
    return bool(r(P) == r(Q) == r(np.vstack([P, Q])))


def tableau_check(s):
    """odelab's Spark coefficients for s stages against ``lobatto-iiia-iiib-s``."""
    import odelab.scheme.rungekutta as rk
    from ldaspark.core.families import lobatto_iiia_iiib
    ta = lobatto_iiia_iiib(s).arrays()
    IIIA, IIIB = rk.LobattoIIIA.tableaux[s], rk.LobattoIIIB.tableaux[s]
    spark = getattr(rk, f"Spark{s}")()
    Q = spark.QT.T                                      # constraint rows on (K(Y_1..Y_s), k(y_1))
    W = np.zeros((s, s + 1))
    W[:-1, :-1] = ta.omega                              # (21e)
    W[-1, -1] = 1.0                                     # (21f)
    close = lambda a, b: bool(np.allclose(a, b, rtol=0, atol=1e-14))
    out = {"s": s, "odelab": f"Spark{s}", "ldaspark": f"lobatto-iiia-iiib-{s}",
           "A": close(IIIA[:-1, 1:], ta.A), "A_hat": close(IIIB[:-1, 1:], ta.A_hat),
           "A_tilde": close(IIIB[:-1, 1:], ta.A_tilde), "b": close(IIIA[-1, 1:], ta.b)
           and close(IIIB[-1, 1:], ta.b_hat) and close(IIIB[-1, 1:], ta.b_tilde),
           "c": close(IIIA[:-1, 0], ta.c), "constraints": _same_rows(Q, W)}
    out["match"] = all(out[k] for k in ("A", "A_hat", "A_tilde", "b", "c", "constraints"))
    return out


def _git(path, *args):
    try:
        return subprocess.run(["git", "-C", path, *args], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def versions():
    import importlib
    import scipy
    import ldaspark
    out = {"ldaspark": getattr(ldaspark, "__version__", None), "ldaspark_commit": _git(ROOT, "rev-parse", "HEAD"),
           "numpy": np.__version__, "scipy": scipy.__version__, "python": platform.python_version()}
    for name in ("odelab", "newton", "padexp"):
        src = os.path.dirname(os.path.dirname(importlib.import_module(name).__file__))
        out[name] = {"source": f"https://github.com/olivierverdier/{name}", "commit": _git(src, "rev-parse", "HEAD"),
                     "local_changes": _git(src, "diff", "--stat", "HEAD") or ""}
    out["odelab"]["patch"] = "benchmarks/peer/odelab-compat.patch"
    return out


# --- one comparison ---------------------------------------------------------------------------
def _drift(energy, cons):
    e = np.asarray(energy, float)
    k = np.asarray(cons, float)
    return {"energy_drift": float(np.max(np.abs(e - e[0]))), "constraint": float(np.max(np.abs(k)))}


def compare(label, v0, odelab_scheme, method, matched, h, n, repeats, odelab_cache):
    """One row: CPU times (odelab once, generic once, compiled best of ``repeats``; one-time
    set-up outside the clock on both sides) and the trajectories' max differences over all
    n + 1 step points."""
    key = (label, odelab_scheme)
    if key not in odelab_cache:
        odelab_cache[key] = run_odelab(odelab_scheme, v0, h, n)
    cpu_o, t_o, q_o, v_o, E_o, K_o = odelab_cache[key]
    scene = odelab_robot_scene(v0)
    cpu_g, rg = run_ldaspark(scene, method, h, n, "generic")
    row = {"initial": label, "v0": list(v0), "odelab": odelab_scheme, "ldaspark": method, "matched": matched,
           "n_steps": n, "h": h, "odelab_cpu": cpu_o, "generic_cpu": cpu_g,
           "max_dt": float(np.max(np.abs(t_o - rg.t))),
           "max_dq": float(np.max(np.abs(q_o - rg.q))), "max_dv": float(np.max(np.abs(v_o - rg.v))),
           "odelab_drift": _drift(E_o, K_o), "generic_drift": _drift(rg.energy, rg.constraint)}
    if matched:    # odelab's fsolve tolerance bounds the agreement: tighten it (not timed)
        _, _, q_t, v_t, _, _ = run_odelab(odelab_scheme, v0, h, n, xtol=TIGHT_XTOL)
        row.update(tight_xtol=TIGHT_XTOL, tight_max_dq=float(np.max(np.abs(q_t - rg.q))),
                   tight_max_dv=float(np.max(np.abs(v_t - rg.v))))
    try:
        cpu_c, rc = run_ldaspark(scene, method, h, n, "compiled", repeats)
    except Exception as exc:          # a method without a compiled kernel: generic only
        row.update(compiled_cpu=None, compiled_note=f"{type(exc).__name__}: {str(exc).splitlines()[0]}")
    else:
        row.update(compiled_cpu=cpu_c, compiled_engine=rc.engine, compiled_max_dq=float(np.max(np.abs(q_o - rc.q))),
                   compiled_max_dv=float(np.max(np.abs(v_o - rc.v))),
                   generic_vs_compiled_dq=float(np.max(np.abs(rg.q - rc.q))),
                   compiled_drift=_drift(rc.energy, rc.constraint))
    return row


def print_table(data):
    hdr = ("initial", "odelab", "ldaspark", "odelab s", "generic s", "compiled s", "max|dq|", "max|dv|",
           "max|dq| comp.", "dq xtol 1e-12", "dE odelab", "dE here")
    print(" ".join(f"{x:>16s}" if i > 2 else f"{x:28s}" if i == 2 else f"{x:12s}" for i, x in enumerate(hdr)))
    for r in data["runs"]:
        cc = "-" if r["compiled_cpu"] is None else f"{r['compiled_cpu']:.3g}"
        cq = "-" if r["compiled_cpu"] is None else f"{r['compiled_max_dq']:.2e}"
        ct = f"{r['tight_max_dq']:.2e}" if "tight_max_dq" in r else "-"
        print(f"{r['initial']:12s} {r['odelab']:12s} {r['ldaspark']:28s} {r['odelab_cpu']:16.3g} "
              f"{r['generic_cpu']:16.3g} {cc:>16s} {r['max_dq']:16.2e} {r['max_dv']:16.2e} {cq:>16s} {ct:>16s} "
              f"{r['odelab_drift']['energy_drift']:16.2e} {r['generic_drift']['energy_drift']:16.2e}"
              + ("" if r["matched"] else "   (different methods: negative control)"))
    for t in data["tableau_check"]:
        print(f"coefficients odelab {t['odelab']} vs {t['ldaspark']}: " + ("match" if t["match"] else f"DIFFER {t}"))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-steps", type=int, default=1000)
    ap.add_argument("--h", type=float, default=0.05)
    ap.add_argument("--repeats", type=int, default=3, help="best of REPEATS for the compiled runs")
    ap.add_argument("--out", default=os.path.join(ROOT, "reports", "peer_odelab.json"))
    args = ap.parse_args(argv)
    try:
        import odelab  # noqa: F401
    except ImportError:
        print("peer_odelab: odelab is not importable here; see this script's docstring for the set-up",
              file=sys.stderr)
        return 2
    from ldaspark.core.io import atomic_write_json
    from ldaspark.lab.reports.markdown import jsonable
    load = list(os.getloadavg()) if hasattr(os, "getloadavg") else None
    cache, runs = {}, []
    for label, v0 in INITIAL:
        for scheme, method, matched in PAIRS:
            runs.append(compare(label, v0, scheme, method, matched, args.h, args.n_steps, args.repeats, cache))
            print(f"  {label}: odelab {scheme} vs {method} done", file=sys.stderr)
    data = {"command": "python benchmarks/peer_odelab.py", "date": datetime.date.today().isoformat(),
            "cpu_count": os.cpu_count(), "load_average_at_start": load, "machine": platform.machine(),
            "versions": versions(),
            "scene": "odelab's mobile robot = robot (8.3) with m = I = l = 1, I_w = 1/3; q0 = 0",
            "timing": "time.process_time; odelab and generic once, compiled best of "
                      f"{args.repeats}; each after a 2-step run (imports, sympy, numba outside the clock)",
            "tableau_check": [tableau_check(s) for s in (2, 3)],
            "not_compared": NOT_COMPARED, "runs": runs}
    print_table(data)
    atomic_write_json(args.out, jsonable(data))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
