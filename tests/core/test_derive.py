"""The sparse derivation of ldaspark.core.derive: the derived expressions equal the former sympy
derivation (grad L, the Hessians, k_q, k_v, k_t, R = -K^T lam and its partials, the energy (8),
the partials of N) on every scene and on random systems, numerically at 30 digits at random
points; zeros are never differentiated; the sympy attributes are made only when read; a perturbed
derivative is caught by the same comparison (its negative control)."""
import pickle
import random
import sys
import types

import mpmath
import pytest
import sympy
from hypothesis import given, settings, strategies as st

from ldaspark.core import derive
from ldaspark.models import scenes
from ldaspark.core.system import _NONSMOOTH, LagrangianSystem


def reference(S) -> dict:
    """The derivation LagrangianSystem did before (sympy, dense), formula for formula, with Abs,
    sign, re, im, arg differentiated as functions of real variables as it was."""
    from ldaspark.core.derive import _real_dummies
    reps = _real_dummies(S)
    if reps:
        back = {d: x for x, d in reps.items()}
        X = lambda e: e.xreplace(reps)                    # noqa: E731
        R = types.SimpleNamespace(q=[X(x) for x in S.q], v=[X(x) for x in S.v], t=X(S.t), L=X(S.L), k=X(S.k),
                                  lam=S.lam, N=None if S.N is None else X(S.N), psi=S.psi)
        return {key: val.xreplace(back) for key, val in reference(R).items()}
    q, v, t, L, k = S.q, S.v, S.t, S.L, S.k
    out = {"L_q": sympy.Matrix([sympy.diff(L, x) for x in q]), "L_v": sympy.Matrix([sympy.diff(L, x) for x in v])}
    Lv = out["L_v"]
    out.update(L_vv=Lv.jacobian(v), L_vq=Lv.jacobian(q), L_qq=out["L_q"].jacobian(q), L_vt=Lv.diff(t),
               L_t=sympy.diff(L, t), k_q=k.jacobian(q), k_v=k.jacobian(v), k_t=k.diff(t))
    out["R_lam"] = R = -out["k_v"].T * sympy.Matrix(S.lam)
    out.update(R_q=R.jacobian(q), R_v=R.jacobian(v), energy_expr=(Lv.T * sympy.Matrix(v))[0, 0] - L)
    if S.N is not None:
        out.update(N_q=S.N.jacobian(q), N_v=S.N.jacobian(v), N_psi=S.N.jacobian(S.psi))
    return out


def mismatches(S, ref, seed=0, points=2, tol=1e-14) -> list:
    """[(name, entry, why)] where the system's derived expressions differ from ``ref``: a
    different structural zero pattern (unless the reference entry simplifies to 0), or values at
    random points in (0.2, 0.9) (30 digits) that differ by more than tol (1 + |value|)."""
    rng = random.Random(seed)
    bad = []
    syms = list(S.q) + list(S.v) + [S.t] + list(S.lam) + list(S.psi) + list(S.params)
    for name, R in ref.items():
        A = getattr(S, name)
        A = A if isinstance(A, sympy.MatrixBase) else sympy.Matrix([A])
        R = R if isinstance(R, sympy.MatrixBase) else sympy.Matrix([R])
        if A.shape != R.shape:
            bad.append((name, None, f"shape {A.shape} != {R.shape}"))
            continue
        diff = [(i, j) for i in range(A.rows) for j in range(A.cols) if A[i, j] != R[i, j]]
        for i, j in diff:
            if (A[i, j] == 0) != (R[i, j] == 0) and sympy.simplify(A[i, j] - R[i, j]) != 0:
                bad.append((name, (i, j), "zero pattern"))
        if not diff:
            continue
        fa = sympy.lambdify(syms, [A[i, j] for i, j in diff], [_NONSMOOTH, "mpmath"])
        fr = sympy.lambdify(syms, [R[i, j] for i, j in diff], [_NONSMOOTH, "mpmath"])
        with mpmath.workdps(30):
            for _ in range(points):
                pt = [mpmath.mpf(rng.uniform(0.2, 0.9)) for _ in syms]
                for (i, j), a, r in zip(diff, fa(*pt), fr(*pt)):
                    if abs(a - r) > tol * (1 + abs(r)):
                        bad.append((name, (i, j), f"{a} != {r}"))
    return bad


# the bicycle's reference derivation and evaluation take minutes: with --exhaustive only
SCENE_NAMES = [n for n in scenes.SCENES if n != "bicycle"]


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_every_scene_derives_what_sympy_derived(name):
    sc = scenes.SCENES[name]()
    S = sc.system
    assert mismatches(S, reference(S)) == []
    # the paper's and the general scenes are elementary: the C++ engine took them
    if name in scenes.PAPER_SCENES + scenes.GENERAL_SCENES + scenes.NONIDEAL_SCENES:
        assert S._derived.engine == "symengine"


@pytest.mark.exhaustive
def test_the_bicycle_derives_what_sympy_derived():
    S = scenes.SCENES["bicycle"]().system
    assert mismatches(S, reference(S), points=1) == []


def test_a_perturbed_derivative_is_caught():
    """Negative control of the comparison: one Hessian entry off by 1e-12 q0, L_vq transposed, a
    structural entry dropped, each is reported."""
    sc = scenes.SCENES["relativistic"]()
    S = sc.system
    ref = reference(S)
    assert mismatches(S, ref) == []
    for name, change in (("L_vv", lambda M: M + sympy.Matrix(M.rows, M.cols, lambda i, j: 0 if (i, j) != (0, 0)
                                                                          else sympy.Rational(1, 10 ** 12) * S.q[0])),
                         ("L_vq", lambda M: M.T),
                         ("k_q", lambda M: M.applyfunc(lambda e: 0))):
        bad = dict(ref)
        bad[name] = change(ref[name])
        assert bad[name] != ref[name]
        found = mismatches(S, bad)
        assert found and {f[0] for f in found} == {name}, (name, found)


# --- random systems -------------------------------------------------------------------------------
N_DOF = 3
Q = sympy.symbols(f"q0:{N_DOF}")
V = sympy.symbols(f"v0:{N_DOF}")
T = sympy.Symbol("t")
LEAVES = list(Q) + list(V) + [T]


def _expr(draw, depth, nonsmooth):
    kind = draw(st.integers(0, 9 if depth > 0 else 1))
    if kind == 0:
        return draw(st.sampled_from(LEAVES))
    if kind == 1:
        return sympy.Rational(draw(st.integers(-5, 5)), draw(st.integers(1, 4)))
    a = _expr(draw, depth - 1, nonsmooth)
    b = _expr(draw, depth - 1, nonsmooth)
    if kind == 2:
        return a + b
    if kind == 3:
        return a * b
    if kind == 4:
        return a ** draw(st.integers(2, 3))
    if kind == 5:
        return draw(st.sampled_from([sympy.sin, sympy.cos, sympy.atan, sympy.sinh, sympy.tanh]))(a)
    if kind == 6:
        return sympy.exp(a / 4) + sympy.log(2 + a ** 2) + sympy.sqrt(1 + b ** 2)
    if kind == 7:
        return sympy.atan2(a, 2 + b ** 2) + sympy.cos(a) / (2 + sympy.sin(b))
    if kind == 8:
        return sympy.Float("0.1000000000000000000000000000003", 40) * a * b
    if nonsmooth:
        return draw(st.sampled_from([sympy.Abs, sympy.sign, lambda x: sympy.Piecewise((x, x > 0), (x ** 2, True))]))(a) * b
    return a - b


@st.composite
def systems(draw, nonsmooth=False):
    """L = |v|^2/2 + a random term (so that L_vv is regular near 0) and one random constraint."""
    L = sum(x ** 2 for x in V) / 2 + _expr(draw, 3, nonsmooth) / 10
    k = [V[draw(st.integers(0, N_DOF - 1))] + _expr(draw, 2, nonsmooth)]
    return L, k


@settings(max_examples=25)
@given(systems())
def test_random_elementary_systems(sys_):
    L, k = sys_
    S = LagrangianSystem(L, k, list(Q), list(V), T)
    assert S._derived.engine == "symengine"
    assert mismatches(S, reference(S), seed=1) == []


@settings(max_examples=6)
@given(systems(nonsmooth=True))
def test_random_systems_with_nonsmooth_functions(sys_):
    L, k = sys_
    S = LagrangianSystem(L, k, list(Q), list(V), T)
    assert mismatches(S, reference(S), seed=2) == []


def test_functions_symengine_is_not_trusted_with_go_to_sympy():
    x, vx = sympy.symbols("x vx")
    y, vy = sympy.symbols("y vy")
    for term, engine in ((sympy.cos(x), "symengine"), (sympy.Abs(x), "sympy"), (sympy.Max(x, y), "sympy"),
                         (sympy.sinc(x), "sympy"), (sympy.erf(x), "sympy"), (sympy.I * x * x, "sympy")):
        S = LagrangianSystem((vx ** 2 + vy ** 2) / 2 - term, [vy - x * vx], [x, y], [vx, vy])
        assert S._derived.engine == engine, term
        assert mismatches(S, reference(S)) == [], term


def test_floats_keep_their_precision_and_symbols_their_assumptions():
    """Floats pass through the C++ engine as placeholders: the derivative holds the same 50-digit
    Float; a symbol with assumptions comes back as itself (not a plain symbol of its name)."""
    c = sympy.Float("0.12345678901234567890123456789012345678901234567891", 50)
    x = sympy.Symbol("x", positive=True)
    y, vx, vy = sympy.symbols("y vx vy")
    S = LagrangianSystem(c * vx ** 2 + (vy ** 2) / 2 - x ** 3, [vy - x * vx], [x, y], [vx, vy])
    assert S._derived.engine == "symengine"
    assert S.L_vv[0, 0] == 2 * c and S.L_vv[0, 0].atoms(sympy.Float) == {2 * c}
    assert S.L_q[0] == -3 * x ** 2 and S.L_q[0].free_symbols == {x}
    assert x in S.k_v.free_symbols and sympy.Symbol("x") not in S.k_v.free_symbols | S.L_q.free_symbols


# --- sparsity -----------------------------------------------------------------------------------------
def test_zeros_are_not_differentiated(monkeypatch):
    """With the sympy engine (the same algorithm as symengine's), every derivative taken is with
    respect to a symbol the expression contains, and their number grows with the size of the
    expressions (terms x their symbols), not with n^2."""
    calls = []
    orig = sympy.Expr.diff

    def counting(self, *symbols, **kw):
        if sys._getframe(1).f_code.co_filename == derive.__file__:   # derive's own calls, not sympy's inside
            calls.append((self, symbols))
        return orig(self, *symbols, **kw)
    sc = scenes.SCENES["mp-particles-nh"](m=10)          # n = 21
    S = sc.system
    monkeypatch.setattr(sympy.Expr, "diff", counting)
    d = derive.derive(S.L, S.k, S.q, S.v, S.t, S.lam, engine="sympy")
    monkeypatch.undo()
    assert calls
    assert all(len(s) == 1 and s[0] in e.free_symbols for e, s in calls)
    n = S.n
    assert len(calls) < 40 * n                            # dense: 2n + 5 n^2 + ... > 2000
    ref = reference(S)
    for name in ("L_vv", "L_qq", "L_vq", "k_q", "k_v", "R_q", "R_v"):
        assert d.count(name) == sum(1 for e in ref[name] if e != 0), name
    assert d.count("L_vv") == n and d.count("L_vq") == 0


def test_symmetric_hessians_are_derived_once():
    sc = scenes.SCENES["mp-particles-nh"](m=3)
    d = sc.system._derived
    nz = d.nonzeros("L_qq")
    off = [(i, j) for (i, j) in nz if i < j]
    assert off and all(nz[i, j] is nz[j, i] for i, j in off)


@pytest.mark.parametrize("m", [100, pytest.param(500, marks=pytest.mark.exhaustive)])
def test_a_thousand_coordinates_derive_without_a_dense_pass(m):
    """n = 2m + 1 = 201 (1001 with --exhaustive; the McLachlan-Perlmutter chain): the entries
    kept are the nonzeros (a dense derivation of n = 1001 has 5 n^2 = 5e6 entries of second
    derivatives)."""
    sc = scenes.SCENES["mp-particles-nh"](m=m)
    d = sc.system._derived
    n = sc.system.n
    assert d.engine == "symengine"
    assert d.count("L_qq") == n + 2 * m + 2 + 0 and d.count("L_vv") == n
    assert d.count("k_q") + d.count("k_v") + d.count("R_q") < 4 * n
    assert "L_vv" not in sc.system.__dict__                # not yet made into sympy


# --- lazy sympy -------------------------------------------------------------------------------------
def test_sympy_attributes_are_made_when_read_and_survive_copy_and_pickle():
    sc = scenes.SCENES["skate"]()
    S = sc.system
    fresh = LagrangianSystem(S.L, S.k, S.q, S.v, S.t)
    assert not set(derive.NAMES) & set(fresh.__dict__)
    assert fresh._derived._sympy == {}
    M = fresh.L_vv
    assert set(fresh._derived._sympy) == {"L_vv"} and fresh.__dict__["L_vv"] is M
    with pytest.raises(AttributeError):
        fresh.N_q                                         # no nonideal term: no such attribute
    with pytest.raises(AttributeError):
        fresh.no_such_attribute
    back = pickle.loads(pickle.dumps(fresh))
    assert all(getattr(back, k) == getattr(fresh, k) for k in derive.NAMES if k in fresh._derived)
    view = fresh.with_params()
    assert view.k_v == fresh.k_v
