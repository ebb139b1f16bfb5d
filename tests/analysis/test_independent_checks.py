"""The exported analysis functions against computations written independently here (probe t11):
a general (non-mechanical) Lagrangian L(t, q, v) with a rheonomic constraint k(t, q, v) nonlinear
in v, n = 3, m = 2, at t0 = 0.3 and h = +-0.2, which the other tests do not use.

Independent means: L, dL/dv and K = dk/dv are lambdified here from the sympy expressions; L_d,
p0, p1 and the forces f_d^+- are assembled here from Theorem 1's formulas with dV/dq taken by
finite differences of the returned stages (not from the library's implicit differentiation);
dL_d/dq by finite differences of L_d. Definition 1's sign convention (section 4, as Theorem 1
states it): dL_d/dq0 = -p0 - f_d^-, dL_d/dq1 = p1 - f_d^+."""
import mpmath
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.analysis.discrete import base_point
from ldaspark.core.backend import Backend
from ldaspark.core.errors import InputError
from ldaspark.core.spark import SparkMethod
from ldaspark.core.system import LagrangianSystem

T = sympy.Symbol("t")
Q = sympy.symbols("x y z")
V = sympy.symbols("u w r")
T0, H = "0.3", "0.2"
Q0 = ["0.2", "-0.1", "0.4"]


def general(a=1, b=1, params=None):
    """L not of the form v^T M v / 2 - U (quartic in u, v-v coupling through x, explicit t);
    k depends on t and is quadratic in w."""
    x, y, z = Q
    u, w, r = V
    L = (u**2 + w**2 + r**2) / 2 + a * u**4 / 12 + x * w * r / 4 + sympy.sin(T) * u * z / 3 \
        - b * sympy.cos(y) / 2 + T * x * z / 5
    k = [w - x * u + T * r / 5, r + w**2 / 10 - y * u - T / 10]
    return LagrangianSystem(L, k, Q, V, t=T, name="general-rheonomic", params=params), L, k


SYS, L_EXPR, K_EXPR = general()


def consistent_v0(system, dps=60):
    bk = Backend(dps)
    with bk.context():
        return [mpmath.nstr(x, dps) for x in system.project_velocity(
            bk, mpmath.mpf(T0), [mpmath.mpf(a) for a in Q0], [mpmath.mpf(a) for a in ("0.5", "0.2", "0.1")])]


V0 = consistent_v0(SYS)
METHODS = ["gauss-1", "gauss-2", "gauss-3", "lobatto-iiia-iiib-2", "lobatto-iiia-iiib-3"]


def tableau(name):
    fam, s = name.rsplit("-", 1)
    return ldaspark.gauss(int(s)) if fam == "gauss" else ldaspark.lobatto_iiia_iiib(int(s))


def _max(a):
    return max(abs(x) for x in np.asarray(a, dtype=object).reshape(-1))


# ---------------------------------------------------------------------------------------------
# discrete_lagrangian: L_d, p0, p1, f_d^+- and Definition 1 by finite differences at 60 digits
@pytest.mark.parametrize("h", [H, "-" + H])
@pytest.mark.parametrize("method", METHODS)
def test_discrete_lagrangian_against_independent_differences(method, h):
    """60 digits; 4-point central differences (error delta^4 f^(5)/30) with delta = 1e-20.
    f^(5) grows like sigma_min(J)^-4 (the BVP Jacobian; sigma_min/sigma_max down to 1.2e-6 for
    Gauss 3 here, measured 5th derivatives ~1e26 delta^-4 error coefficient): truncation <= 1e-52;
    round-off (18/12) 1e-60 cond(J) / delta <= 1e-33 with cond(J) <= 1e7. Tolerance 1e-30
    relative to max |p| (measured <= 2.4e-42). Controls: the same identity without the forces
    fails by |f_d^-| (>= 1e-3 here), and a tableau with A_hat[0, s-1] + 1e-6 (violating (22b))
    fails it by more than 1e-12 (the identity is then only O(1e-6 h^k))."""
    dps = 60
    tab = tableau(method)
    s, n, m = tab.s, 3, 2
    Lf = sympy.lambdify((T, *Q, *V), L_EXPR, "mpmath")
    Lv = sympy.lambdify((T, *Q, *V), [sympy.diff(L_EXPR, vi) for vi in V], "mpmath")
    Kf = sympy.lambdify((T, *Q, *V), sympy.Matrix(K_EXPR).jacobian(V), "mpmath")
    bk = Backend(dps)
    with bk.context():
        t0, hh = mpmath.mpf(T0), mpmath.mpf(h)
        q0, v0 = [mpmath.mpf(a) for a in Q0], [mpmath.mpf(a) for a in V0]
        ar = tab.arrays(dps)

        def identity_residuals(tb):
            t1, q1, xg = base_point(SYS, tb, t0, q0, v0, hh, dps)
            solve = lambda qa, qb: ldaspark.discrete_lagrangian(SYS, tb, t0, qa, t1, qb, dps=dps, x_guess=xg)
            r = solve(q0, q1)
            # L_d = h sum b_i L(T_i, Q_i, V_i), Q_i = q0 + h sum_j a_ij V_j (13), from the returned V
            Qs = [[q0[a] + hh * sum(ar.A[i][j] * r.V[j][a] for j in range(s)) for a in range(n)] for i in range(s)]
            Ld = hh * sum(ar.b[i] * Lf(t0 + ar.c[i] * hh, *Qs[i], *r.V[i]) for i in range(s))
            assert abs(Ld - r.L_d) <= 1e-55
            assert _max(np.array(Lv(t0, *q0, *r.v0), dtype=object) - r.p0) <= 1e-55
            assert _max(np.array(Lv(t1, *q1, *r.v1), dtype=object) - r.p1) <= 1e-55
            d = mpmath.mpf(10) ** -20
            grad, dV = {}, {}
            for side in (0, 1):
                for kk in range(n):
                    Ls, Vs = [], []
                    for e in (-2 * d, -d, d, 2 * d):
                        qa, qb = list(q0), list(q1)
                        (qa if side == 0 else qb)[kk] += e
                        rr = solve(qa, qb)
                        Ls.append(rr.L_d)
                        Vs.append(rr.V)
                    fd = lambda f: (f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * d)
                    grad[side, kk] = fd(Ls)
                    dV[side, kk] = [[fd([W[i][a] for W in Vs]) for a in range(n)] for i in range(s)]
            K = [Kf(t0 + ar.c[j] * hh, *Qs[j], *r.V[j]) for j in range(s)]
            PK = [[sum(r.Psi[j][l] * K[j][l, a] for l in range(m)) for a in range(n)] for j in range(s)]

            def force(side, weight):      # h sum_i b_i (h sum_j weight_ij Psi_j^T K_j) dV_i/dq
                return [hh * sum(ar.b[i] * hh * sum(weight(i, j) * PK[j][a] for j in range(s)) * dV[side, kk][i][a]
                                 for i in range(s) for a in range(n)) for kk in range(n)]
            fm = force(0, lambda i, j: ar.A_tilde[i][j])
            fp = [-x for x in force(1, lambda i, j: ar.b_tilde[j] - ar.A_tilde[i][j])]
            scale = max(_max(r.p0), _max(r.p1))
            return r, fm, fp, scale, ([grad[0, a] + r.p0[a] + fm[a] for a in range(n)],
                                      [grad[1, a] - r.p1[a] + fp[a] for a in range(n)],
                                      [grad[0, a] + r.p0[a] for a in range(n)])

        r, fm, fp, scale, (res0, res1, without) = identity_residuals(tab)
        # the library's forces (implicit differentiation) equal the ones assembled here
        assert _max(np.array(fm, dtype=object) - r.f_d_minus) <= 1e-30 * scale
        assert _max(np.array(fp, dtype=object) - r.f_d_plus) <= 1e-30 * scale
        assert _max(res0) <= 1e-30 * scale and _max(res1) <= 1e-30 * scale, (res0, res1)
        assert _max(without) >= 1e-3 * scale                  # control: the forces matter
        pert = tab.with_entry("A_hat", 0, s - 1, "1e-6")
        _, _, _, scale_p, (p0res, p1res, _) = identity_residuals(pert)
        assert max(_max(p0res), _max(p1res)) >= 1e-12 * scale_p    # control: (22b) violated


# ---------------------------------------------------------------------------------------------
# theorem1_residuals and check_symmetry: two-sided, h of both signs, t0 nonzero, parameters
@pytest.mark.parametrize("h", [H, "-" + H])
@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-3"])
def test_theorem1_and_symmetry_two_sided(method, h):
    """At 30 digits (differences at 50) a correct tableau gives Theorem 1 residuals <= 1e-27
    (the 30-digit level with a 1e3 allowance; measured 1e-54 Gauss, 1.4e-42 Lobatto) and symmetry
    residuals <= 1e-27 (measured <= 1.8e-31). Control: A_hat[0, 1] + 1e-6 violates (22b) and
    (23c); A[0, 1] + 1e-6 violates (22b) and (23b): the residuals rise to the perturbation's
    order times a power of h (measured Theorem 1 3.5e-9 .. 1.2e-6, symmetry 5.7e-10 .. 1.8e-7),
    asserted >= 1e-12, fifteen orders above the correct tableau's."""
    tab = tableau(method)
    ok = ldaspark.theorem1_residuals(SYS, tab, T0, Q0, V0, h, dps=30)
    assert ok["theorem1-q0"] <= 1e-27 and ok["theorem1-q1"] <= 1e-27
    assert ok["without_forces_q0"] >= 1e-4
    sym = ldaspark.check_symmetry(SYS, tab, T0, Q0, V0, h, dps=30)
    keys = ("symmetry-Ld", "symmetry-fd-plus", "symmetry-fd-minus", "symmetry-Phi")
    assert max(sym[k] for k in keys) <= 1e-27, sym
    for entry in ("A_hat", "A"):
        pert = tab.with_entry(entry, 0, 1, "1e-6")
        bad = ldaspark.theorem1_residuals(SYS, pert, T0, Q0, V0, h, dps=30)
        assert min(bad["theorem1-q0"], bad["theorem1-q1"]) >= 1e-12, (entry, bad)
        bsym = ldaspark.check_symmetry(SYS, pert, T0, Q0, V0, h, dps=30)
        assert max(bsym[k] for k in keys) >= 1e-12, (entry, bsym)


def test_parameters_are_the_substituted_system():
    """A parameterised L (a, b with defaults 3, 2; then a = 5 by with_params) gives the L_d,
    momenta and Theorem 1 numbers of the system with the values substituted (to the working
    precision: 40 digits, allowance 1e-35); control: the default-valued system differs from the
    a = 5 one by O(1e-3) in L_d."""
    a, b = sympy.symbols("a b")
    sp = general(a, b, params={a: 3, b: 2})[0]
    tab = ldaspark.gauss(2)
    bk = Backend(40)
    with bk.context():
        t1, q1, xg = base_point(general(3, 2)[0], tab, T0, Q0, V0, H, 40)
        lds = {}
        for nm, S1, S2 in (("default", sp, general(3, 2)[0]), ("five", sp.with_params({a: 5}), general(5, 2)[0])):
            r1 = ldaspark.discrete_lagrangian(S1, tab, T0, Q0, t1, q1, dps=40, x_guess=xg)
            r2 = ldaspark.discrete_lagrangian(S2, tab, T0, Q0, t1, q1, dps=40, x_guess=xg)
            assert abs(r1.L_d - r2.L_d) <= 1e-35
            assert _max(r1.p0 - r2.p0) <= 1e-35 and _max(r1.f_d_minus - r2.f_d_minus) <= 1e-35
            lds[nm] = r1.L_d
        assert abs(lds["default"] - lds["five"]) >= 1e-4
    th = ldaspark.theorem1_residuals(sp, tab, T0, Q0, V0, H, dps=30)
    assert th["theorem1-q0"] <= 1e-27 and th["theorem1-q1"] <= 1e-27
    assert th["L_d"] == ldaspark.theorem1_residuals(general(3, 2)[0], tab, T0, Q0, V0, H, dps=30)["L_d"]


def test_edge_arguments_are_refused_with_one_message():
    with pytest.raises(InputError):
        ldaspark.discrete_lagrangian(SYS, ldaspark.gauss(2), T0, Q0, T0, Q0, dps=30)     # t1 = t0
    with pytest.raises(InputError):
        ldaspark.theorem1_residuals(SYS, ldaspark.gauss(2), T0, Q0, V0, 0, dps=30)
    with pytest.raises(ldaspark.LdasparkError, match="s >= 2"):
        ldaspark.lobatto_iiia_iiib(1)


# ---------------------------------------------------------------------------------------------
# flow_jacobian: 'ift' against 'difference', float64 against digits, the restriction against
# differences along the constraint manifold
def _diff(a, b):
    """max |a - b| at 60 digits (mpf(x) rounds to the ambient precision: at mpmath's default 15
    digits two 30-digit entries 1e-21 apart became equal and the difference 0)."""
    with mpmath.workdps(60):
        return max(abs(mpmath.mpf(x) - mpmath.mpf(y)) for x, y in zip(np.asarray(a).reshape(-1), np.asarray(b).reshape(-1)))


@pytest.mark.parametrize("method", METHODS)
def test_flow_jacobian_methods_agree_on_the_general_system(method):
    """'difference' uses step 10^-10 at 30 digits: truncation 1e-20 |d^3 Phi| (|Phi'''| = O(1)
    here), round-off 1e-30/1e-10; tolerance 1e-18 (measured 3.5e-21). float64 'ift' against the
    30-digit one: the step's Newton matrix conditioning times 1.1e-16; tolerance 1e-13 (measured
    <= 3.8e-16). Control: the Jacobian of a step from t0 = 0 (k is rheonomic) differs by > 1e-4."""
    a = ldaspark.flow_jacobian(SYS, method, Q0, V0, H, t0=T0, dps=30)
    b = ldaspark.flow_jacobian(SYS, method, Q0, V0, H, t0=T0, dps=30, how="difference")
    c = ldaspark.flow_jacobian(SYS, method, [float(x) for x in Q0], [float(x) for x in V0], float(H), t0=float(T0))
    assert _diff(a.full, b.full) <= 1e-18
    assert _diff(a.full, c.full) <= 1e-13
    assert _diff(a.full, ldaspark.flow_jacobian(SYS, method, Q0, V0, H, t0=0, dps=30).full) >= 1e-4


@pytest.mark.parametrize("method", ["gauss-2", "lobatto-iiia-iiib-3"])
def test_flow_jacobian_methods_agree_on_a_mechanical_scene(method):
    """The skate (L = v^T M v / 2 - U, k = K(q) v): same tolerances as above."""
    a = ldaspark.flow_jacobian("skate", method, None, None, "0.1", dps=30)
    b = ldaspark.flow_jacobian("skate", method, None, None, "0.1", dps=30, how="difference")
    c = ldaspark.flow_jacobian("skate", method, None, None, 0.1)
    assert _diff(a.full, b.full) <= 1e-18 and _diff(a.full, c.full) <= 1e-13
    assert _diff(a.full, np.eye(6)) >= 1e-3          # control: not the identity


@pytest.mark.parametrize("coords,rates,dependent", [(["x"], ["u"], ["w", "r"]), (["y", "z"], [], ["u", "w"]),
                                                    ([], ["w"], ["u", "r"]), (["x", "y", "z"], ["u"], ["w", "r"])])
def test_restriction_against_differences_on_the_constraint_manifold(coords, rates, dependent):
    """J restricted to coords/rates equals 4-point differences (delta = 1e-12, 40 digits) of the
    step map along curves on {k(t0, q, v) = 0}: the chosen coordinates / rates moved, the
    dependent velocities re-solved from k = 0 (mpmath.findroot to 1e-38). Error: truncation
    delta^4 = 1e-48, the root's 1e-38 / delta = 1e-26; tolerance 1e-24 (measured 6.5e-30).
    Control: the curve with the dependent velocities not re-solved (off the manifold) differs
    by > 1e-3."""
    dps = 40
    kf = sympy.lambdify((T, *Q, *V), K_EXPR, "mpmath")
    names_q, names_v = [str(x) for x in Q], [str(x) for x in V]
    dep = [names_v.index(x) for x in dependent]
    fj = ldaspark.flow_jacobian(SYS, "gauss-2", Q0, V0, H, t0=T0, dps=dps, coords=coords, rates=rates,
                                dependent=dependent)
    sm = SparkMethod(SYS, ldaspark.gauss(2), dps=dps, newton="full")
    bk = sm.backend
    with bk.context():
        t0, h = mpmath.mpf(T0), mpmath.mpf(H)
        q0, v0 = [mpmath.mpf(a) for a in Q0], [mpmath.mpf(a) for a in V0]

        def on_manifold(q, v, dep):
            if not dep:                   # the control: a curve off the manifold
                return v

            def F(*vd):
                vv = list(v)
                for a, j in enumerate(dep):
                    vv[j] = vd[a]
                return kf(t0, *q, *vv)
            root = mpmath.findroot(F, [v[j] for j in dep], tol=mpmath.mpf(10) ** -76)
            vv = list(v)
            for a, j in enumerate(dep):
                vv[j] = root[a]
            return vv

        def restricted(dep):
            d = mpmath.mpf(10) ** -12
            cols = []
            for kind, i in [("q", names_q.index(c)) for c in coords] + [("v", names_v.index(x)) for x in rates]:
                outs = []
                for e in (-2 * d, -d, d, 2 * d):
                    q, v = list(q0), list(v0)
                    (q if kind == "q" else v)[i] += e
                    st = sm.step(t0, bk.array(q), bk.array(on_manifold(q, v, dep)), h)
                    outs.append(np.concatenate([st.q1, st.v1]))
                cols.append((outs[0] - 8 * outs[1] + 8 * outs[2] - outs[3]) / (12 * d))
            return np.array(cols, dtype=object).T[fj.select, :]
        assert _diff(restricted(dep), fj.J) <= 1e-24
        assert _diff(restricted([]), fj.J) >= 1e-3


def test_tangent_must_be_a_basis():
    """A tangent with linearly dependent columns (a zero column, a repeated one) is not the
    basis the docstring asks for: J had a zero (repeated) column and multipliers() a spurious 0
    (repeated eigenvalue), as coords=['x', 'x'] would, which is refused. Refused the same way;
    control: a full-rank tangent is accepted and gives full[select] B."""
    kw = dict(t0=T0, dps=30)
    B = np.zeros((6, 2))
    B[0, 0] = 1
    with pytest.raises(InputError, match="linearly independent"):
        ldaspark.flow_jacobian(SYS, "gauss-2", Q0, V0, H, tangent=B, select=[0, 1], **kw)
    B[:, 1] = B[:, 0]
    with pytest.raises(InputError, match="linearly independent"):
        ldaspark.flow_jacobian(SYS, "gauss-2", Q0, V0, H, tangent=B, select=[0, 1], **kw)
    with pytest.raises(InputError, match="twice"):
        ldaspark.flow_jacobian(SYS, "gauss-2", Q0, V0, H, coords=["x", "x"], **kw)
    B[1, 1] = 1
    fj = ldaspark.flow_jacobian(SYS, "gauss-2", Q0, V0, H, tangent=B, select=[0, 1], **kw)
    with mpmath.workdps(30):                              # the working precision of fj
        expected = fj.full[[0, 1], :].dot(np.asarray(B, dtype=object))
    assert _diff(fj.J, expected) == 0


# ---------------------------------------------------------------------------------------------
# classify_wellposedness
def _cyclic_z():
    """z is cyclic (L has no z); k = r - x u - t w / 5 (m = 1, rheonomic)."""
    x, y, z = Q
    u, w, r = V
    L = (u**2 + w**2 + r**2) / 2 + u**4 / 12 - sympy.cos(y) / 2 + x * w / 3
    return LagrangianSystem(L, [r - x * u - T * w / 5], Q, V, t=T, name="cyclic-z"), L


def _holonomic():
    """The first constraint r - x u = d/dt (z - x^2 / 2) is holonomic (docs/verification.md:
    Gauss s >= 2 then has a dependent (21e) row: 'singular')."""
    sysm, L = _cyclic_z()
    x, y, z = Q
    u, w, r = V
    return LagrangianSystem(L, [r - x * u, w - y * u / 3 - T / 7], Q, V, t=T, name="holonomic")


@pytest.mark.parametrize("method,expected,deficiency", [
    ("gauss-1", "well-posed", 0), ("gauss-2", "well-posed", 0), ("gauss-3", "well-posed", 0),
    ("lobatto-iiia-iiib-2", "gauge-deficient", 2), ("lobatto-iiia-iiib-3", "gauge-deficient", 2)])
def test_classification_of_the_general_system(method, expected, deficiency):
    """docs/verification.md: Gauss well-posed; Lobatto IIIA-IIIB (A_tilde's first column constant
    = b_tilde_1) gauge-deficient with m = 2 null directions. Gauss 3's smallest sigma here is a
    genuine 1.2e-6 (~h^k, the same at 30 and 50 digits), not a structural zero."""
    v0 = consistent_v0(SYS, 40)
    r = ldaspark.classify_wellposedness(SYS, method, T0, Q0, v0, H)
    assert (r["class"], r["rank_deficiency"]) == (expected, deficiency)
    assert ldaspark.classify_wellposedness(SYS, method, T0, Q0, v0, "-" + H)["class"] == expected


def test_a_cyclic_coordinate_is_not_a_gauge():
    """A cyclic z does not make the BVP deficient: (21c) fixes its increment q1 - q0 = h b.V, so
    Gauss 2 stays well-posed and Lobatto IIIA-IIIB 2 has its m = 1 gauge only (the docs' gauge:
    p0 and Lambda_1 together). Control: the holonomic system, where Gauss 2 is 'singular' with
    one dependent row and Gauss 1 (no (21e) row) well-posed, as docs/verification.md states."""
    cyc = _cyclic_z()[0]
    v0 = consistent_v0(cyc, 40)
    g = ldaspark.classify_wellposedness(cyc, "gauss-2", T0, Q0, v0, H)
    assert (g["class"], g["rank_deficiency"]) == ("well-posed", 0)
    lo = ldaspark.classify_wellposedness(cyc, "lobatto-iiia-iiib-2", T0, Q0, v0, H)
    assert (lo["class"], lo["rank_deficiency"]) == ("gauge-deficient", 1)
    hol = _holonomic()
    v0 = consistent_v0(hol, 40)
    s2 = ldaspark.classify_wellposedness(hol, "gauss-2", T0, Q0, v0, H)
    assert (s2["class"], s2["rank_deficiency"]) == ("singular", 1)
    assert ldaspark.classify_wellposedness(hol, "gauss-1", T0, Q0, v0, H)["class"] == "well-posed"


def test_check_symmetry_needs_consistent_data():
    """(23)'s symmetry is a property of the step on consistent data: the step ends on k = 0,
    so Phi_-h(Phi_h(y)) cannot return to a y off it, and the reversed BVP (whose (21f) imposes
    k = 0 at the forward t0) is another solution (_tangent_projector's assumption). With v0 off
    k = 0 by 0.12 the symmetric Gauss 2 was reported asymmetric: symmetry-Phi 0.12,
    symmetry-Ld 2.8e-5; with v0 rounded to float64 (|k| = 3.5e-18) symmetry-Phi 3.4e-18 at 30
    digits, where the floor is 1e-30. Now refused (|k| above check_consistent's 1e3 eps (1 + |v|),
    as integrate refuses such data). Control: the projected v0 passes and gives residuals at the
    floor (test_theorem1_and_symmetry_two_sided); the same data stay accepted by
    theorem1_residuals, whose Theorem 1 needs no consistency (v0 is an unknown of the BVP)."""
    from ldaspark.core.errors import InconsistentInitialDataError
    tab = ldaspark.gauss(2)
    for v0 in (["0.5", "0.2", "0.1"], [float(x) for x in V0]):
        with pytest.raises(InconsistentInitialDataError, match="check_symmetry: .*k = 0"):
            ldaspark.check_symmetry(SYS, tab, T0, Q0, v0, H, dps=30)
    ok = ldaspark.check_symmetry(SYS, tab, T0, Q0, V0, H, dps=30)
    assert ok["symmetry-Phi"] <= 1e-27
    th = ldaspark.theorem1_residuals(SYS, tab, T0, Q0, ["0.5", "0.2", "0.1"], H, dps=30)
    assert th["theorem1-q0"] <= 1e-27


@pytest.mark.parametrize("factors", [(1, 1.0), (1, "2/2"), ("1/2", 0.5)])
def test_equal_step_factors_written_differently_are_refused(factors):
    """h_factors (1, 1.0), (1, "2/2"), ("1/2", 0.5) passed the distinctness check (made on the
    text) and ended in a raw ZeroDivisionError from log(h1 / h2) = 0 (the observed power of h).
    Now refused as duplicates by value. Control: (1, "1/2") classifies (well-posed)."""
    v0 = consistent_v0(SYS, 40)
    with pytest.raises(InputError, match="distinct step factors"):
        ldaspark.classify_wellposedness(SYS, "gauss-2", T0, Q0, v0, H, h_factors=factors)
    assert ldaspark.classify_wellposedness(SYS, "gauss-2", T0, Q0, v0, H, h_factors=(1, "1/2"))["class"] == "well-posed"


@pytest.mark.parametrize("dps", [None, 30])
def test_dependent_velocities_with_a_singular_block_of_K(dps):
    """k = r - x u - t w / 5 at x = 0: K's column for u is 0, so dependent=['u'] cannot be solved
    from the linearised constraint. It was a SingularMatrixError saying "Newton matrix is
    numerically singular" (float64) / "zero or has non-finite entries" (30 digits), about a matrix
    the user never chose; now an InputError naming the dependent velocities. All three velocities
    as rates left none to be dependent, and the message advised "give dependent=", which cannot
    help (dependent must be disjoint from the rates); now it says how many rates fit (n - m).
    Control: dependent=['r'] (K's column 1) gives the restricted J."""
    cyc = _cyclic_z()[0]
    args = (cyc, "gauss-2", [0.0, 0.1, 0.2], [0.3, 0.2, 0.0], 0.1)
    for kw in (dict(coords=["x"], dependent=["u"]), dict(rates=["w"], dependent=["u"])):
        with pytest.raises(InputError, match=r"dependent velocities \['u'\]"):
            ldaspark.flow_jacobian(*args, t0=0, dps=dps, **kw)
    with pytest.raises(InputError, match="at most n - m = 2 rates"):
        ldaspark.flow_jacobian(*args, t0=0, dps=dps, coords=["x"], rates=["u", "w", "r"])
    fj = ldaspark.flow_jacobian(*args, t0=0, dps=dps, coords=["x"], rates=["w"], dependent=["r"])
    assert np.asarray(fj.J).shape == (2, 2)


@pytest.mark.parametrize("method,expected,deficiency", [("lobatto-iiia-iiib-2", "gauge-deficient", 2),
                                                        ("gauss-2", "well-posed", 0)])
def test_classification_above_float64_range(method, expected, deficiency):
    """dps may reach 2000, but sigma / sigma_max was taken in float64: a floor sigma ~10^-dps
    below 10^-324 became 0.0 at both precisions, '0 < drop * 0' found no structural zero, and the
    stability ratio divided by it: dps = (330, 360) ended in a raw ZeroDivisionError (had it not,
    the gauge-deficient Lobatto 2 would have been 'well-posed'). Now the ratios are compared in
    mpmath. Control: Gauss 2 stays well-posed there, and both as at (30, 50)."""
    r = ldaspark.classify_wellposedness(SYS, method, T0, Q0, V0, H, dps=(330, 360))
    assert (r["class"], r["rank_deficiency"]) == (expected, deficiency)
    assert all(isinstance(v, float) and np.isfinite(v) for v in (r["sigma_min_nonzero_rel"], r["sigma_min_power_of_h"]))
    assert ldaspark.classify_wellposedness(SYS, method, T0, Q0, V0, H)["class"] == expected
