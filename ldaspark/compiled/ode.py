"""The underlying ODE (3a-b) of a system as a compiled right-hand side, for a fair comparison
with explicit ODE solvers (scipy's DOP853): generated from the same sympy expressions as the
SPARK model (``codegen``), the saddle system (4) solved in numba.

    f = compiled_rhs(system)        # f(t, y) with y = (q, v); dv/dt from (3a-b)
    scipy.integrate.solve_ivp(f, (0, T), y0, method="DOP853", rtol=..., atol=...)
"""
from __future__ import annotations

import sympy

from .cache import load_source
from .codegen import NotCompilableError, header, _emit, _mat_outputs, _named, _Printer, _Symbols, _vec_outputs, \
    nonideal_term

_RHS = '''

@_jit(nogil=True)
def rhs(t, y):
    """dy/dt = (v, a) with [[L_vv, K^T], [K, 0]] [a; psi] = [L_q - L_vt - L_vq v; -k_t - k_q v] (3a-b), (4)."""
    n, m = N_DOF, N_CON
    q = np.ascontiguousarray(y[:n])
    v = np.ascontiguousarray(y[n:])
    S = np.zeros((n + m, n + m))
    r = np.zeros(n + m)
    ode_parts(t, q, v, S, r)
    a = np.linalg.solve(S, r)
    out = np.empty(2 * n)
    out[:n] = v
    out[n:] = a[:n]
    return out


@numba.njit(cache=True, nogil=True)
def rhs_into(t, y, yp):
    """rhs(t, y) written into yp (SUNDIALS CVODE's calling convention, scikit-sundae)."""
    yp[:] = rhs(t, y)


@numba.njit(cache=True, nogil=True)
def psi_of(t, y):
    """The multipliers psi of (3a-b) at y = (q, v): the last m entries of the saddle solve (4)."""
    n, m = N_DOF, N_CON
    S = np.zeros((n + m, n + m))
    r = np.zeros(n + m)
    ode_parts(t, np.ascontiguousarray(y[:n]), np.ascontiguousarray(y[n:2 * n]), S, r)
    return np.linalg.solve(S, r)[n:]


@numba.njit(cache=True, nogil=True)
def dae_residual(t, y, yp, res):
    """The index-1 form of (1) for SUNDIALS IDA, y = (q, v, psi): res = (q' - v,
    L_vv v' + K^T psi - (L_q - L_vt - L_vq v), K v' + k_t + k_q v), the velocity constraint
    differentiated once, (3a-b) with psi algebraic."""
    n, m = N_DOF, N_CON
    q = np.ascontiguousarray(y[:n])
    v = np.ascontiguousarray(y[n:2 * n])
    S = np.zeros((n + m, n + m))
    r = np.zeros(n + m)
    ode_parts(t, q, v, S, r)
    x = np.empty(n + m)
    x[:n] = yp[n:2 * n]
    x[n:] = y[2 * n:]
    res[:n] = yp[:n] - v
    res[n:] = S.dot(x) - r
'''


@_named
def ode_source(system) -> str:
    """Module with ``ode_parts(t, q, v, S, r)`` (the saddle matrix (4) and the right-hand side of
    (3a-b), nonzero entries only) and ``rhs(t, y)``. Ideal constraints only: with a nonideal
    term (3.3), (3a) is nonlinear in psi (``LagrangianSystem.ode_rhs`` solves it by Newton)."""
    if nonideal_term(system) is not None:
        raise NotCompilableError(f"{system.name}: the compiled ODE (3a-b) has no nonideal term (3.3)")
    n, m = system.n, system.m
    S = _Symbols(system, m)
    X = lambda M: sympy.Matrix(M).xreplace(S.sub)          # noqa: E731
    Lvv, kv = X(system.L_vv), X(system.k_v)
    vv = sympy.Matrix(S.v)
    r1 = X(system.L_q) - X(system.L_vt) - X(system.L_vq) * vv
    r2 = -X(system.k_t) - X(system.k_q) * vv
    sad = sympy.zeros(n + m, n + m)
    sad[:n, :n] = Lvv
    sad[:n, n:] = kv.T
    sad[n:, :n] = kv
    outs = _mat_outputs("S", sad) + _vec_outputs("r", list(r1) + list(r2))
    fn = _emit("ode_parts", "ODE_SIG", ["t", "q", "v", "S", "r"], S.ut + S.uq + S.uv, outs,
               _Printer({"fully_qualified_modules": True}))
    head = header(system.name, "ode", n, m) + "import numpy as np\n"
    return head + "\n\n" + fn + _RHS


def compiled_rhs(system):
    """The numba-compiled f(t, y) of (3a-b) for ``system`` (cached on disk like the models)."""
    return load_source(ode_source(system), prefix="ldaspark_ode_").rhs


def compiled_ode_module(system):
    """The module of ``ode_source(system)``: ``rhs(t, y)``, ``rhs_into(t, y, yp)`` (CVODE's form),
    ``psi_of(t, y)`` and ``dae_residual(t, y, yp, res)`` (the index-1 form for IDA), each compiled
    on its first call."""
    return load_source(ode_source(system), prefix="ldaspark_ode_")
