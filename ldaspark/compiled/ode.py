"""The underlying ODE (3a-b) of a system as compiled right-hand sides, for a fair comparison
with explicit ODE solvers (scipy's DOP853, CyRK, SUNDIALS): generated from the same sympy
expressions as the SPARK model (``codegen``).

The acceleration dv/dt is the a of the saddle system (4), [[L_vv, K^T], [K, 0]] [a; psi] =
[L_q - L_vt - L_vq v; -k_t - k_q v]. Three ways to get it, all in the generated module:

* ``rhs(t, y)``: the saddle system assembled and solved by ``np.linalg.solve`` (LAPACK), three
  arrays allocated per call (the simplest form; IDA's residual and ``psi_of`` use its parts);
* ``accel_closed``: the closed form, the saddle system solved symbolically (block elimination:
  a = L_vv^-1 (r1 - K^T psi), psi = (K L_vv^-1 K^T)^-1 (K L_vv^-1 r1 - r2)) and printed after
  ``sympy.cse``; absent (``HAS_CLOSED = False``) when the expressions grow too large;
* ``accel_solve``: the saddle system assembled into a caller's work array and solved there by
  Gaussian elimination without pivoting, in the order of its blocks: the first n pivots are
  those of L_vv (positive definite), the last m those of -K L_vv^-1 K^T (negative definite for
  K of full rank), so none vanishes; no allocation.

Each comes in the calling conventions of the peers, with a work array ``W`` of ``n_work(n, m)``
doubles passed in (unused by the closed form): ``rhs_closed(t, y, W)`` / ``rhs_solve(t, y, W)``
return dy/dt; ``rhs_into_closed(t, y, yp, W)`` / ``rhs_into_solve(t, y, yp, W)`` write it.

    mod = compiled_ode_module(system)
    W = np.zeros(n_work(system.n, system.m))
    scipy.integrate.solve_ivp(mod.rhs_closed, (0, T), y0, args=(W,), method="DOP853", ...)
"""
from __future__ import annotations

import sympy

from .cache import load_source
from .codegen import NotCompilableError, header, _emit, _mat_outputs, _named, _only_generated_symbols, _Printer, \
    _Symbols, _vec_outputs, nonideal_term

#: the closed form is dropped when its printed expressions, after cse, have more operations
#: than this (a larger straight-line code than the numeric solve it replaces is slower)
CLOSED_MAX_OPS = 4000

# every function through _jit (cache.model_jit: numba's files recorded and checked in the trusted
# cache); numba.njit(cache=True) would cache in NUMBA_CACHE_DIR, unchecked
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


@_jit(nogil=True)
def rhs_into(t, y, yp):
    """rhs(t, y) written into yp (SUNDIALS CVODE's calling convention, scikit-sundae)."""
    yp[:] = rhs(t, y)


@_jit(nogil=True)
def psi_of(t, y):
    """The multipliers psi of (3a-b) at y = (q, v): the last m entries of the saddle solve (4)."""
    n, m = N_DOF, N_CON
    S = np.zeros((n + m, n + m))
    r = np.zeros(n + m)
    ode_parts(t, np.ascontiguousarray(y[:n]), np.ascontiguousarray(y[n:2 * n]), S, r)
    return np.linalg.solve(S, r)[n:]


@_jit(nogil=True)
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


@_jit(nogil=True)
def accel_solve(t, y, out, W):
    """out[n:2n] = a of (4) at y = (q, v), the saddle system assembled into W (row-major, then the
    right-hand side) and solved there by elimination without pivoting (see the module docstring)."""
    n, m = N_DOF, N_CON
    N = n + m
    R = N * N
    saddle_into(t, y, W)
    for k in range(N):
        p = 1.0 / W[k * N + k]
        for i in range(k + 1, N):
            f = W[i * N + k] * p
            if f != 0.0:
                for j in range(k + 1, N):
                    W[i * N + j] -= f * W[k * N + j]
                W[R + i] -= f * W[R + k]
    for i in range(N - 1, -1, -1):
        s = W[R + i]
        for j in range(i + 1, N):
            s -= W[i * N + j] * W[R + j]
        W[R + i] = s / W[i * N + i]
    for i in range(n):
        out[n + i] = W[R + i]
'''

_FORMS = '''

@_jit(nogil=True)
def rhs_{X}(t, y, W):
    """dy/dt = (v, a) of (3a-b), a by accel_{X}; W: work array of n_work(n, m) doubles."""
    n = N_DOF
    out = np.empty(2 * n)
    for i in range(n):
        out[i] = y[n + i]
    accel_{X}(t, y, out, W)
    return out


@_jit(nogil=True)
def rhs_into_{X}(t, y, yp, W):
    """rhs_{X}(t, y, W) written into yp."""
    n = N_DOF
    for i in range(n):
        yp[i] = y[n + i]
    accel_{X}(t, y, yp, W)
'''


def n_work(n, m) -> int:
    """Doubles of the work array of ``accel_solve``: the saddle matrix and its right-hand side."""
    return (n + m) ** 2 + (n + m)


def _parts(system, S):
    """(L_vv, K, r1 = L_q - L_vt - L_vq v, r2 = -k_t - k_q v) in the generated code's symbols."""
    X = lambda M: sympy.Matrix(M).xreplace(S.sub)          # noqa: E731
    Lvv, kv = X(system.L_vv), X(system.k_v)
    vv = sympy.Matrix(S.v)
    return Lvv, kv, X(system.L_q) - X(system.L_vt) - X(system.L_vq) * vv, -X(system.k_t) - X(system.k_q) * vv


def closed_form(system):
    """(entries, a) or (None, why not): the saddle system (4) solved by block elimination (the
    Schur complement K L_vv^-1 K^T) with a symbol _e<k> in the place of every entry of L_vv, K, r1,
    r2 that is not a number, so that sympy eliminates on symbols (and never has to decide whether
    an expression is zero); ``entries`` = [(_e<k>, its expression in _t, _q<i>, _v<i>)], ``a`` the
    n accelerations in the _e<k>."""
    S = _Symbols(system, system.m)
    Lvv, kv, r1, r2 = _parts(system, S)
    ent = {}

    def atom(e):
        if e.is_number:
            return e
        if e not in ent:
            ent[e] = sympy.Symbol(f"_e{len(ent)}", real=True)
        return ent[e]
    M = Lvv.applyfunc(atom)
    K, b1, b2 = kv.applyfunc(atom), r1.applyfunc(atom), r2.applyfunc(atom)
    try:
        Minv = M.inv(method="LU")
        X = Minv * K.T
        y = Minv * b1
        psi = (K * X).inv(method="LU") * (K * y - b2)
    except (ValueError, ZeroDivisionError) as exc:
        return None, f"the saddle system has no symbolic solution ({type(exc).__name__})"
    return ([(s, e) for e, s in ent.items()], list(y - X * psi)), None


def closed_form_exprs(system):
    """The n accelerations of ``closed_form`` as expressions in _t, _q<i>, _v<i> (None without a
    closed form)."""
    cf, _ = closed_form(system)
    if cf is None:
        return None
    back = dict(cf[0])
    return [e.xreplace(back) for e in cf[1]]


def _closed_function(system, cf):
    """(source of ``accel_closed(t, y, out, W)``, its operation count) from ``closed_form``'s
    (entries, a), each part after cse; (None, why not) when it is too large."""
    n = system.n
    entries, a = cf
    _only_generated_symbols("accel_closed", [e for _, e in entries])
    own = {s for s, _ in entries}
    if not set().union(*(e.free_symbols for e in a)) <= own:
        raise NotCompilableError("accel_closed: the closed form has symbols other than its entries")
    r1, e1 = sympy.cse([e for _, e in entries], symbols=sympy.numbered_symbols("_x"), optimizations="basic")
    r2, e2 = sympy.cse(a, symbols=sympy.numbered_symbols("_y"), optimizations="basic")
    ops = sum(sympy.count_ops(e) for _, e in r1 + r2) + sum(sympy.count_ops(e) for e in e1 + e2)
    if ops > CLOSED_MAX_OPS:
        return None, f"the closed form has {ops} operations after cse (more than {CLOSED_MAX_OPS})"
    pr = _Printer({"fully_qualified_modules": True})
    used = set().union(*(e.free_symbols for _, e in entries))
    unpack = [("_t", "t")] + [(f"_q{i}", f"y[{i}]") for i in range(n)] + [(f"_v{i}", f"y[{n + i}]") for i in range(n)]
    lines = ["@_jit(nogil=True)", "def accel_closed(t, y, out, W):",
             '    """out[n:2n] = a of (4) at y = (q, v), the saddle system solved symbolically (W unused)."""']
    lines += [f"    {s} = {src}" for s, src in unpack if sympy.Symbol(s, real=True) in used]
    lines += [f"    {s} = {pr.doprint(e)}" for s, e in r1]
    lines += [f"    {s} = {pr.doprint(e)}" for (s, _), e in zip(entries, e1)]
    lines += [f"    {s} = {pr.doprint(e)}" for s, e in r2]
    lines += [f"    out[{n + i}] = {pr.doprint(e)}" for i, e in enumerate(e2)]
    return "\n".join(lines), ops


def _saddle_function(system, sad, r):
    """Source of ``saddle_into(t, y, W)``: every entry of the saddle matrix (zeros too, as the
    elimination overwrites them) and of its right-hand side, written into W."""
    n, N = system.n, sad.rows
    pr = _Printer({"fully_qualified_modules": True})
    exprs = [sad[i, j] for i in range(N) for j in range(N)] + list(r)
    _only_generated_symbols("saddle_into", exprs)
    nz = [(k, e) for k, e in enumerate(exprs) if not e.is_zero]
    reps, red = sympy.cse([e for _, e in nz], symbols=sympy.numbered_symbols("_x"), optimizations="basic")
    used = set().union(*(e.free_symbols for e in exprs))
    unpack = [("_t", "t")] + [(f"_q{i}", f"y[{i}]") for i in range(n)] + [(f"_v{i}", f"y[{n + i}]") for i in range(n)]
    lines = ["@_jit(nogil=True)", "def saddle_into(t, y, W):"]
    lines += [f"    {s} = {src}" for s, src in unpack if sympy.Symbol(s, real=True) in used]
    lines += [f"    {s} = {pr.doprint(e)}" for s, e in reps]
    lines += [f"    W[{k}] = 0.0" for k, e in enumerate(exprs) if e.is_zero]
    lines += [f"    W[{k}] = {pr.doprint(e)}" for (k, _), e in zip(nz, red)]
    return "\n".join(lines)


@_named
def ode_source(system) -> str:
    """Module with ``ode_parts(t, q, v, S, r)`` (the saddle matrix (4) and the right-hand side of
    (3a-b), nonzero entries only), ``rhs(t, y)`` and the buffered forms of the module docstring.
    Ideal constraints only: with a nonideal term (3.3), (3a) is nonlinear in psi
    (``LagrangianSystem.ode_rhs`` solves it by Newton)."""
    if nonideal_term(system) is not None:
        raise NotCompilableError(f"{system.name}: the compiled ODE (3a-b) has no nonideal term (3.3)")
    if system.params:       # the ODE module has no run-time parameter block (numba: NameError PARAMS)
        raise NotCompilableError(f"{system.name}: the compiled ODE (3a-b) takes no parameters "
                                 f"({', '.join(str(p) for p in system.params)[:80]}); substitute their values in L and k")
    n, m = system.n, system.m
    S = _Symbols(system, m)
    Lvv, kv, r1, r2 = _parts(system, S)
    sad = sympy.zeros(n + m, n + m)
    sad[:n, :n] = Lvv
    sad[:n, n:] = kv.T
    sad[n:, :n] = kv
    outs = _mat_outputs("S", sad) + _vec_outputs("r", list(r1) + list(r2))
    fn = _emit("ode_parts", "ODE_SIG", ["t", "q", "v", "S", "r"], S.ut + S.uq + S.uv, outs,
               _Printer({"fully_qualified_modules": True}))
    cf, why = closed_form(system)
    closed, info = (None, why) if cf is None else _closed_function(system, cf)
    head = header(system.name, "ode", n, m) + "import numpy as np\n"
    head += f"HAS_CLOSED = {closed is not None}\n"
    # why there is no closed form, or its operation count: printed as a quoted literal of our
    # own text (never the system's)
    head += f"CLOSED_INFO = {str(info)!r}\n"
    src = head + "\n\n" + fn + _RHS + "\n\n" + _saddle_function(system, sad, list(r1) + list(r2))
    src += _FORMS.format(X="solve")
    if closed is not None:
        src += "\n\n" + closed + _FORMS.format(X="closed")
    return src


def compiled_rhs(system):
    """The numba-compiled f(t, y) of (3a-b) for ``system`` (cached on disk like the models)."""
    return load_source(ode_source(system), prefix="ldaspark_ode_").rhs


def compiled_ode_module(system):
    """The module of ``ode_source(system)``: ``rhs(t, y)``, ``rhs_into(t, y, yp)`` (CVODE's form),
    ``psi_of(t, y)``, ``dae_residual(t, y, yp, res)`` (the index-1 form for IDA), the buffered
    forms ``rhs_solve``, ``rhs_into_solve`` and, where ``HAS_CLOSED``, ``rhs_closed``,
    ``rhs_into_closed``; each compiled on its first call."""
    return load_source(ode_source(system), prefix="ldaspark_ode_")
