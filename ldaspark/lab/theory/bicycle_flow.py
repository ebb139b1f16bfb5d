"""The benchmark bicycle's linearised dynamics from the SPARK flow itself.

About upright straight running at forward speed v (``ldaspark.models.bicycle``: all angles 0,
x' = v, theta_R' = -v / r_R, theta_F' = -v / r_F) the coordinates x, y, psi, theta_R, theta_F
are cyclic and the pitch is fixed by the front contact, so lean, steer and their rates evolve
as a closed system to first order (the forward speed decouples: it is even under the lateral
reflection phi, delta, y, psi -> -phi, -delta, -y, -psi, which the lateral variables are odd
under). ``ldaspark.flow_jacobian`` restricted to (phi, delta, phi', delta') with the dependent
velocities (x', y', psi', theta', theta_F') solved from the linearised constraints gives
J(h) = exp(h A(v)) + O(h^(2s+1)) for the s-stage Gauss methods, so lambda = log(mu) / h of its
eigenvalues mu converge to the eigenvalues of the benchmark's A(v) (eq. 5.3 of Meijaard et al.
2007) with order 2s. ``ldaspark.models.bicycle_benchmark`` computes A(v) independently from the
appendix formulas. The front contact height f(phi, theta, delta) has zero lean and steer
derivatives at upright (it is even in (phi, delta)), so perturbing lean and steer alone stays on
f = 0 to first order (``check_tangent`` verifies it).
"""
from __future__ import annotations

import itertools

import numpy as np

from ...models import bicycle as bc
from ...models import bicycle_benchmark as bb
from ...analysis.flow_jacobian import flow_jacobian

LATERAL = ("phi", "delta")


def spark_eigenvalues(v, method="gauss-2", h=0.01, dps=None, model=None) -> list:
    """Eigenvalues log(mu)/h of the SPARK step's Jacobian restricted to lean, steer and their
    rates at upright straight running at speed v (complex, sorted by real then imaginary part)."""
    model = model or bc.build()
    q0, v0 = model.upright(v)
    fj = flow_jacobian(model.system, method, [str(x.evalf(40)) if dps else float(x) for x in q0],
                       [str(x.evalf(40)) if dps else float(x) for x in v0], h, dps=dps, coords=LATERAL,
                       rates=LATERAL, dependent=list(bc.DEPENDENT_V))
    return [complex(z) for z in fj.eigenvalues()]


def match_error(got, want) -> float:
    """max |got_i - want_pi(i)| over the best pairing pi of two lists of 4 eigenvalues."""
    want = [complex(w) for w in want]
    return min(max(abs(g - want[p]) for g, p in zip(got, perm))
               for perm in itertools.permutations(range(len(want))))


def reference_eigenvalues(v, **overrides) -> list:
    return [complex(z) for z in bb.eigenvalues(v, 20, **overrides)]


def weave_real_part(eigs) -> float:
    """Real part of the complex pair (the weave mode); nan when all four are real."""
    cx = [z for z in eigs if abs(z.imag) > 1e-9]
    return max(z.real for z in cx) if cx else float("nan")


def capsize_eigenvalue(eigs) -> float:
    """The largest real eigenvalue (the capsize mode above the weave speed)."""
    return max(z.real for z in eigs if abs(z.imag) <= 1e-9)


def critical_speeds(method="gauss-3", h=0.01, model=None, xtol=1e-9):
    """(v_weave, v_capsize) from the SPARK flow: where the weave pair's real part and the capsize
    eigenvalue change sign (secant iteration on the speed, brackets 4-4.5 and 6-6.1 m/s)."""
    model = model or bc.build()

    def root(fn, a, b):
        fa, fb = fn(a), fn(b)
        for _ in range(30):
            c = b - fb * (b - a) / (fb - fa)
            a, fa, b, fb = b, fb, c, fn(c)
            if abs(b - a) <= xtol:
                break
        return b
    vw = root(lambda v: weave_real_part(spark_eigenvalues(v, method, h, model=model)), 4.0, 4.5)
    vc = root(lambda v: capsize_eigenvalue(spark_eigenvalues(v, method, h, model=model)), 6.0, 6.1)
    return vw, vc


def check_tangent(model=None) -> float:
    """max |df/dphi|, |df/ddelta| of the front contact height at the upright configuration
    (exact zero by the reflection symmetry; a sympy number)."""
    import sympy
    model = model or bc.build()
    sub = {x: 0 for x in model.q}
    return max(abs(sympy.nsimplify(model.f.diff(model.q[bc.COORDS.index(c)]).subs(sub))) for c in LATERAL)


def nonlinear_run(speed=5, lean_rate=0.5, t_end=5.0, h=0.01, method="gauss-2", engine="auto", model=None):
    """The scene ``bicycle`` (upright at ``speed`` with a lean rate) integrated to t_end: returns
    a dict of arrays t, lean, steer, energy, max |k| per step, the front contact height f(q)
    (the holonomic constraint, kept only through its velocity form) and the Result."""
    from ...solve import integrate
    model = model or bc.build()
    sc = model.scene(speed, lean_rate)
    res = integrate(sc, method, t_span=(0, t_end), h=h, engine=engine, raise_on_failure=True)
    import sympy
    f = sympy.lambdify(model.q, model.f, "math")
    return {"t": np.asarray(res.t, float), "lean": np.asarray(res.q[:, bc.LEAN], float),
            "steer": np.asarray(res.q[:, bc.STEER], float), "energy": np.asarray(res.energy, float),
            "k": np.abs(np.asarray(res.constraint, float)).max(axis=1),
            "f": np.array([f(*row) for row in np.asarray(res.q, float)]), "result": res}

