"""Kane's minimal speeds in ``from_mechanics`` (issue 47, item 4): KanesMethod models with fewer
generalized speeds than coordinates, the rolling condition built into the kinematic differential
equations q' = W(q) u + w(q), run as written. The velocity constraints k = N(q)^T (q' - w) = 0 are
derived from the kinematics (``core.mechanics._minimal_speeds``); a quaternion's unit norm comes
out in its velocity form e . e' = 0.

Checked against sympy's own equations of motion (KanesMethod's mass_matrix_full x' =
forcing_full): the accelerations of (1) mapped to u' agree at random consistent states, and
``integrate`` converges at order 2s for gauss-s and 2s - 2 for lobatto-iiia-iiib-s against a
DOP853 solve of sympy's equations at rtol = atol = 1e-13 (~5 s in all; the negative control of
the term that makes the ball's L_vv regular is exhaustive-marked)."""
import math

import numpy as np
import pytest
import sympy
import sympy.physics.mechanics as me
from scipy.integrate import solve_ivp

import ldaspark
import ldaspark.core.mechanics as mech
from ldaspark import LagrangianSystem
from ldaspark.core.backend import Backend
from ldaspark.core.errors import SystemDefinitionError
from ldaspark.models.kane_rolling import chaplygin_ball, rolling_disc

t = me.dynamicsymbols._t
#: accelerations O(1-30) from 3x3..11x11 solves of condition <= 1e3 in float64: 1e-10 relative
#: is 1e3 above round-off and far below the O(1) change a wrong or missing constraint row makes
ACC_TOL = 1e-10


class _Sympy:
    """sympy's equations of a model of ``kane_rolling``: x = (q, u) -> x', consistent states, and
    the map (q, q', q'') -> u_ind' of the model's own kinematics (to compare (1)'s v')."""

    def __init__(self, kane, info):
        self.info = info
        q, u = info["q"], info["u"]
        pv = {sympy.Symbol(k): v for k, v in info["params"].items()}
        self.n, self.o = len(q), len(kane.u)
        self.n_ind = len(u) - len(info["fnh"])
        self._f = sympy.lambdify([q + u], (kane.mass_matrix_full.xreplace(pv), kane.forcing_full.xreplace(pv)),
                                 cse=True)
        kdd = kane.kindiffdict()
        self._qd = sympy.lambdify([q + u], [kdd[x.diff(t)].xreplace(pv) for x in q])
        u_ind, u_dep = u[:self.n_ind], u[self.n_ind:]
        dep = sympy.solve(info["fnh"], u_dep, dict=True)[0] if u_dep else {}
        self._dep = sympy.lambdify([q + u_ind], [dep[w].xreplace(pv) for w in u_dep])
        # u_ind from the first kinematic equations (they determine it from q, q'), and its rate
        U = sympy.Matrix(list(sympy.linsolve(info["kd"][:self.n_ind], u_ind).args[0]))
        a = sympy.symbols(f"a0:{self.n}")
        Ud = U.diff(t).xreplace({x.diff(t, 2): ai for x, ai in zip(q, a)})
        plain = {**{x.diff(t): sympy.Symbol(f"qd{i}") for i, x in enumerate(q)},
                 **{x: sympy.Symbol(f"qq{i}") for i, x in enumerate(q)}}
        self._ud = sympy.lambdify([[plain[x] for x in q], [plain[x.diff(t)] for x in q], list(a)],
                                  Ud.xreplace(plain).xreplace(pv))

    def xdot(self, x):
        M, F = self._f(list(x))
        return np.linalg.solve(np.array(M, float), np.array(F, float).ravel())

    def state(self, q0, u_ind):
        """(x0, v0): the full state with the dependent speeds solved, and q' = v0."""
        u = list(u_ind) + list(np.array(self._dep(list(q0) + list(u_ind)), float).ravel())
        x0 = list(q0) + u
        return np.array(x0, float), np.array(self._qd(x0), float).ravel()

    def u_rate(self, q0, v0, vdot):
        return np.array(self._ud(list(q0), list(v0), list(vdot)), float).ravel()


def _random_q(rng, n, sphere):
    q0 = rng.uniform(-1.0, 1.0, n)
    if sphere:
        q0[:4] /= np.linalg.norm(q0[:4])
    return q0


def _acc_diff(system, ref, sphere, seed=47, states=3):
    """max over random consistent states of |u'(1) - u'(sympy)| / (1 + |u'(sympy)|), and max |k|."""
    rng = np.random.default_rng(seed)
    sp = system.with_params(ref.info["params"])
    bk, worst, kmax = Backend(None), 0.0, 0.0
    for _ in range(states):
        q0 = _random_q(rng, ref.n, sphere)
        x0, v0 = ref.state(q0, rng.uniform(-1.5, 1.5, ref.n_ind))
        kmax = max(kmax, float(np.max(np.abs(sp.constraint(bk, 0.0, q0, v0)))))
        want = ref.xdot(x0)[ref.n:ref.n + ref.n_ind]
        got = ref.u_rate(q0, v0, np.asarray(sp.ode_rhs(bk, 0.0, q0, v0)[0], float))
        worst = max(worst, float(np.max(np.abs(got - want) / (1 + np.abs(want)))))
    return worst, kmax


def _orders(system, ref, x0, v0, t_end, hs, methods):
    """{method: (errors at hs, observed order)} of q(t_end) against DOP853 on sympy's equations."""
    sol = solve_ivp(lambda _t, x: ref.xdot(x), (0, t_end), list(x0), method="DOP853", rtol=1e-13, atol=1e-13)
    assert sol.success
    q_ref = sol.y[:ref.n, -1]
    out = {}
    for meth in methods:
        errs = []
        for h in hs:
            r = ldaspark.integrate(system, meth, t_span=(0, t_end), q0=x0[:ref.n], v0=v0, h=h,
                                   params=ref.info["params"], engine="generic")
            assert r.success, r.message
            errs.append(float(np.max(np.abs(r.q[-1] - q_ref))))
        out[meth] = (errs, math.log(errs[0] / errs[1]) / math.log(hs[0] / hs[1]))
    return out


def _expected(meth):
    s = int(meth.rsplit("-", 1)[1])
    return 2 * s - 2 if meth.startswith("lobatto") else 2 * s


# --- the rolling disc: 5 coordinates, 3 speeds, the contact advancing with the contact ----------------
@pytest.fixture(scope="module")
def disc():
    kane, info = rolling_disc()
    return LagrangianSystem.from_mechanics(kane, name="disc"), _Sympy(kane, info)


def test_disc_runs_as_written_with_the_rolling_rows_derived(disc):
    s, ref = disc
    assert s.n == 5 and s.m == 2 and len(s.added_constraints) == 2
    assert all("kinematics" in why for why in s.added_constraints)
    # the rows are polynomial in sin/cos (no removable 0/0 from inverting the kinematics) and
    # free of the speeds: k = v_q4 - r v_q3 cos(q1), v_q5 - r v_q3 sin(q1) up to sign
    for row in s.k:
        assert sympy.fraction(sympy.together(row))[1].is_number, row
    r = [p for p in s.params if str(p) == "r"][0]
    q1, v3, v4, v5 = s.q[0], s.v[2], s.v[3], s.v[4]
    want = [v4 - r * v3 * sympy.cos(q1), v5 - r * v3 * sympy.sin(q1)]
    for row, w in zip(s.k, want):
        assert sympy.expand(row - w) == 0 or sympy.expand(row + w) == 0, row
    worst, kmax = _acc_diff(s, ref, sphere=False)
    assert worst <= ACC_TOL and kmax <= 1e-14


def test_disc_converges_at_the_methods_orders(disc):
    s, ref = disc
    x0, v0 = ref.state(np.array([0.3, 0.1, 1.97, -0.35, 2.27]), [0.5, -3.0, 0.4])
    res = _orders(s, ref, x0, v0, 0.5, (0.05, 0.025), ["gauss-2", "gauss-3", "lobatto-iiia-iiib-3"])
    for meth, (errs, p) in res.items():
        # the errors are the method's: order 2s (2s - 2), within [p - 0.3, p + 0.6]
        assert _expected(meth) - 0.3 <= p <= _expected(meth) + 0.6, (meth, errs, p)


@pytest.mark.parametrize("fault", ["dropped", "sign"])
def test_a_wrong_rolling_row_is_refused_or_disagrees_with_sympy(fault, monkeypatch):
    """Negative control: one derived row left out, or the sign of its rolling term flipped. The
    model's set velocities (the contact's, the centre's) then differ from the derived ones on the
    constraint manifold, so the model is refused; if it were not, the comparison above fails."""
    real = mech._minimal_speeds

    def wrong(*a):
        u_map, rows, why = real(*a)
        if fault == "dropped":
            return u_map, rows[:1], why[:1]
        x4 = rows[0].atoms(sympy.Derivative)
        d4 = [d for d in x4 if str(d.expr.func) == "q4"][0]
        return u_map, [2 * d4 - rows[0]] + rows[1:], why
    monkeypatch.setattr(mech, "_minimal_speeds", wrong)
    kane, info = rolling_disc()
    try:
        s = LagrangianSystem.from_mechanics(kane, name="disc")
    except SystemDefinitionError as exc:
        assert "point" in str(exc)
        return
    worst, _ = _acc_diff(s, _Sympy(kane, info), sphere=False)
    assert worst > 1e3 * ACC_TOL


@pytest.mark.skipif(not hasattr(me, "System"), reason="sympy.physics.mechanics.System needs sympy >= 1.13")
def test_disc_as_a_system_equals_the_kane_form(disc):
    """The same disc given as a ``System`` (coordinates, speeds, kinematic equations, body, load):
    the same L and the same derived rows (two-sided: equal, symbolically)."""
    s, _ = disc
    kane, info = rolling_disc()
    sysm = me.System(kane._inertial)
    sysm.add_coordinates(*info["q"])
    sysm.add_speeds(*info["u"])
    sysm.add_kdes(*info["kd"])
    sysm.add_bodies(*kane.bodies)
    sysm.add_loads(*kane.loads)
    s2 = LagrangianSystem.from_mechanics(sysm, name="disc")
    assert sympy.expand(s.L - s2.L) == 0 and s2.m == 2
    assert all(sympy.expand(a - b) == 0 for a, b in zip(s.k, s2.k))


def test_speeds_that_are_not_independent_are_refused():
    q = me.dynamicsymbols("q1:4")
    u1, u2 = me.dynamicsymbols("u1 u2")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q[0] * N.x + q[1] * N.y + q[2] * N.z)
    P.set_vel(N, (u1 + u2) * (N.x + N.y + 2 * N.z))
    kd = [q[0].diff(t) - (u1 + u2), q[1].diff(t) - (u1 + u2), q[2].diff(t) - 2 * (u1 + u2)]
    km = me.KanesMethod(N, list(q), [u1, u2], kd, bodies=[me.Particle("p", P, sympy.Symbol("m"))])
    with pytest.raises(SystemDefinitionError) as ei:
        LagrangianSystem.from_mechanics(km)
    assert "\n" not in str(ei.value) and "not independent" in str(ei.value)


# --- the Chaplygin ball in quaternions: 6 coordinates, 5 speeds -------------------------------------
@pytest.fixture(scope="module")
def ball():
    kane, info = chaplygin_ball()
    return LagrangianSystem.from_mechanics(kane, name="ball"), _Sympy(kane, info)


def test_ball_in_quaternions_agrees_with_sympys_equations(ball):
    s, ref = ball
    assert s.n == 6 and s.m == 3
    # the derived row is the unit norm in velocity form: e . e' (up to a constant factor)
    e, ve = s.q[:4], s.v[:4]
    row = sympy.expand(s.k[2])
    c = row.coeff(ve[0]) / e[0]
    assert c.is_number and c != 0 and sympy.expand(row - c * sum(a * b for a, b in zip(e, ve))) == 0
    assert len(s.added_terms) == 1           # L_vv made regular along e (zero on k = 0)
    worst, kmax = _acc_diff(s, ref, sphere=True)
    assert worst <= ACC_TOL and kmax <= 1e-14


def _ball_start(ref):
    q0 = np.array([0.9, 0.2, -0.3, 0.25, 0.1, -0.2])
    q0[:4] /= np.linalg.norm(q0[:4])
    return ref.state(q0, [1.5, -2.0, 3.0])


def test_ball_converges_at_the_methods_orders(ball):
    s, ref = ball
    x0, v0 = _ball_start(ref)
    res = _orders(s, ref, x0, v0, 1.0, (0.1, 0.05), ["gauss-2", "gauss-3", "lobatto-iiia-iiib-3"])
    for meth, (errs, p) in res.items():
        assert _expected(meth) - 0.3 <= p <= _expected(meth) + 0.6, (meth, errs, p)


@pytest.mark.exhaustive
def test_ball_without_the_regular_term_loses_its_order(monkeypatch):
    """Negative control of the term added along the unit-norm direction: without it L_vv e = 0,
    the stage equations (21) do not fix V_i along e, and gauss-2 does not converge at order 4."""
    monkeypatch.setattr(mech, "_regularize_unit_norm", lambda L, *a: L)
    kane, info = chaplygin_ball()
    s, ref = LagrangianSystem.from_mechanics(kane, name="ball"), _Sympy(kane, info)
    assert s.added_terms == []
    x0, v0 = _ball_start(ref)
    (errs, p), = _orders(s, ref, x0, v0, 1.0, (0.1, 0.05), ["gauss-2"]).values()
    assert not (4 - 0.3 <= p <= 4 + 0.6), (errs, p)
