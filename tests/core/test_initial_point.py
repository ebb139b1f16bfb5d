"""One initial-point check (``ldaspark.core.validate.initial_point``) for every engine and entry
point: each refuses an inconsistent start with the same message, and each goes through that one
function (replaced here by one that raises a sentinel: every path raises the sentinel)."""
import math
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import ldaspark
from ldaspark.core import validate
from ldaspark.core.backend import Backend
from ldaspark.core.errors import InconsistentInitialDataError, InputError, LdasparkError, NonFiniteError
from ldaspark.core.families import get_method

SK = ldaspark.get_scene("skate")
BAD_V0 = [0.0, 0.3, 1.0]          # k = v2 - v1 tan(theta)-type constraint of the skate violated at q0 = 0
Q0 = [0.0, 0.0, 0.0]


def _paths():
    """name -> a call that starts a run at (0, Q0, v0) on that path."""
    from ldaspark.compiled.fast import fast_integrate
    from ldaspark.core.comparators import integrate_comparator
    from ldaspark.core.spark import integrate as spark_integrate
    from ldaspark.ensemble import RunSpec

    def api(**kw):
        return lambda v0: ldaspark.integrate("skate", kw.pop("method", "gauss-2"), q0=Q0, v0=v0, h=0.1, n_steps=2,
                                             **kw)

    def fast(v0):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            return fast_integrate(SK, "gauss-2", t0=0.0, q0=Q0, v0=v0, h=0.1, n_steps=2)

    def ensemble(v0):
        with ThreadPoolExecutor(1) as ex:
            return ldaspark.integrate("skate", "gauss-2", q0=[Q0, Q0], v0=[[0.0, 0.0, 1.0], v0], h=0.1, n_steps=2,
                                      executor=ex)
    return {
        "generic": api(engine="generic"),
        "generic-mpmath": api(engine="generic", dps=20),
        "compiled": api(engine="compiled"),
        "comparator": api(engine="generic", method="gauss-irk-2"),
        "compiled-lf2": api(engine="compiled", method="lobatto-iiia-iiib-2"),
        "fast_integrate": fast,
        "RunSpec": lambda v0: RunSpec(SK.system, "gauss-2", 0.0, [Q0], [v0], 0.1, 2),
        "ensemble": ensemble,
        "core.spark.integrate": lambda v0: spark_integrate(SK.system, get_method("gauss-2"), 0.0, Q0, v0, 0.1,
                                                           n_steps=2),
        "integrate_comparator": lambda v0: integrate_comparator("gauss-irk-2", SK.system, 0.0, Q0, v0, 0.1, 2),
    }


PATHS = sorted(_paths())


@pytest.mark.parametrize("name", PATHS)
def test_every_path_refuses_an_inconsistent_start_with_the_one_message(name):
    run = _paths()[name]
    with pytest.raises(InconsistentInitialDataError) as err:
        run(BAD_V0)
    msg = str(err.value)
    msg = msg.split(": ", 1)[1] if msg.startswith("ensemble member") else msg
    # |k| = 0.3 against the default tolerance 1e3 eps (1 + |v0|_inf) = 2e3 eps: 4.4e-13 in float64
    # (at 20 digits the backend's eps is 1e-20: 2e-17)
    tol = "2.0e-17" if name == "generic-mpmath" else "4.4e-13"
    assert msg == f"initial data are inconsistent: |k(t0, q0, v0)| = 3.000e-01 > {tol} (pass project=True / " \
                  "--project to project v0 onto k = 0)", msg
    if name in ("RunSpec", "ensemble"):
        assert str(err.value).startswith("ensemble member")
    run([0.0, 0.0, 1.0])          # negative control: the consistent start runs on the same path


class Sentinel(LdasparkError):
    pass


@pytest.mark.parametrize("name", PATHS)
def test_every_path_goes_through_the_one_function(name, monkeypatch):
    def refuse(*a, **k):
        raise Sentinel("the one initial-point check")
    monkeypatch.setattr(validate, "initial_point", refuse)
    with pytest.raises(Sentinel):
        _paths()[name]([0.0, 0.0, 1.0])


def test_the_checks_in_order_and_the_member_prefix():
    bk, system = Backend(None), SK.system
    with pytest.raises(InputError, match="must be numbers"):
        validate.initial_point(system, bk, 0.0, ["a", 0, 0], [0, 0, 1])
    with pytest.raises(InputError, match="the system has n = 3"):
        validate.initial_point(system, bk, 0.0, [0, 0], [0, 0, 1])
    with pytest.raises(InputError, match="ensemble member 2: initial data contain NaN"):
        validate.initial_point(system, bk, 0.0, [0, 0, float("nan")], [0, 0, 1], member="ensemble member 2: ")
    with pytest.raises(NonFiniteError, match="^ensemble member 1: the energy"):
        validate.initial_point(system, bk, 0.0, [0, 0, 0], [0, 0, 1e200], member="ensemble member 1: ")
    with pytest.raises(InconsistentInitialDataError, match="^m: initial data are inconsistent"):
        validate.initial_point(system, bk, 0.0, Q0, BAD_V0, member="m: ")
    t, q, v = validate.initial_point(system, bk, 0.0, Q0, BAD_V0, project=True)
    assert abs(float(system.constraint(bk, t, q, v)[0])) < 1e-15 and v[1] != BAD_V0[1]
    # consistent=False: the set-up checks (4) and (1c) are skipped, the finite checks are not
    validate.initial_point(system, bk, 0.0, Q0, BAD_V0, consistent=False)
    with pytest.raises(NonFiniteError):
        validate.initial_point(system, bk, 0.0, [0, 0, 0], [0, 0, 1e200], consistent=False)


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_a_given_tol_sets_the_consistency_tolerance_to_ten_tol(engine):
    # with tol given the start must satisfy |k| <= 10 tol (1 + |v0|_inf) on every engine: at
    # tol = 1e-10 and |v0|_inf = 1 that is 2e-9; a violation of 1.5e-9 runs, one of 3e-9 is refused
    # with that bound in the message (a tolerance 1e4 x too loose would accept both)
    def go(d):
        return ldaspark.integrate("skate", "gauss-2", q0=Q0, v0=[0.0, d, 1.0], h=0.1, n_steps=2, tol=1e-10,
                                  engine=engine)
    assert go(1.5e-9).status == 0
    with pytest.raises(InconsistentInitialDataError, match=r"\|k\(t0, q0, v0\)\| = 3\.000e-09 > 2\.0e-09 "):
        go(3e-9)


def _knife_at_large_t():
    """The knife edge of 8.2 on an incline, rheonomic: k = sin(q3) v1 - cos(q3) v2 - 3/10 sin(2 t)
    (k_t = -3/5 cos(2 t), up to 0.6)."""
    import sympy
    t = sympy.Symbol("t")
    x, y, th = sympy.symbols("x y theta")
    vx, vy, vth = sympy.symbols("vx vy vtheta")
    L = (vx ** 2 + vy ** 2 + vth ** 2) / 2 - x / 2
    k = [sympy.sin(th) * vx - sympy.cos(th) * vy - sympy.Rational(3, 10) * sympy.sin(2 * t)]
    return ldaspark.LagrangianSystem(L, k, [x, y, th], [vx, vy, vth], t=t, name="knife-rheonomic")


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_a_rheonomic_run_at_large_t_continues_from_its_own_saved_states(engine):
    """(1c) at t0 ~ 1e4 is known only to |k_t| ulp(t0): the time's own rounding (a decimal t0, or a
    step ending at fl(t_n + h) where the grid saves fl(t0 + (n+1) h)) moves k by up to 0.6 x 1.8e-12.
    Before, the consistency check ignored it: the saved state of step 130 of this run (|k| = 1.09e-12)
    was refused as inconsistent initial data (> 4.4e-13) by the next chunk. A violation far beyond
    the time's rounding (1e-9) is still refused."""
    system = _knife_at_large_t()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = ldaspark.integrate(system, "gauss-2", t0=1e4, n_steps=200, q0=[0, 0, 0.2], v0=[1, 0, 1], h=0.01,
                               engine=engine, project=True)
    assert r.status == 0
    worst = int(np.argmax(np.abs(np.asarray(r.constraint, float))))
    assert abs(float(r.constraint[worst][0])) > 4.4e-13           # the time's rounding, measured 1.09e-12
    nxt = ldaspark.integrate(system, "gauss-2", t0=r.t[worst], n_steps=2, q0=r.q[worst], v0=r.v[worst], h=0.01,
                             engine=engine)
    assert nxt.status == 0
    v_off = np.array(r.v[worst], float) + [0.0, 1e-9 / math.cos(float(r.q[worst][2])), 0.0]
    with pytest.raises(InconsistentInitialDataError):
        ldaspark.integrate(system, "gauss-2", t0=r.t[worst], n_steps=2, q0=r.q[worst], v0=v_off, h=0.01,
                           engine=engine)


@pytest.mark.parametrize("engine,dps", [("generic", None), ("compiled", None), ("generic", 30)])
def test_project_reaches_a_constraint_nonlinear_in_v_far_from_v0(engine, dps):
    """project=True is Newton on the KKT system of min (v - v0)^T L_vv (v - v0) / 2 subject to
    k(t0, q0, v) = 0: for k nonlinear in v its matrix needs sum_i mu_i (k_i)_vv next to L_vv. Before,
    it had L_vv alone and diverged for the constant-speed constraint k = v1^2 + v2^2 - 1 from
    v0 = (3, 4, 0) (mu = 2: the iteration's rate 2 mu = 4 > 1), 'projection of v0 onto k = 0 did not
    converge' on every engine; the closest point is (3, 4, 0) / 5. With L_vv = diag(2, 1, 1) the
    answer is checked by (1c) and the stationarity L_vv (v - v0) parallel to k_v(v) = 2 (v1, v2, 0)."""
    import sympy
    x, y, z = sympy.symbols("x y z")
    vx, vy, vz = sympy.symbols("vx vy vz")
    for mass, want in ((1, [0.6, 0.8, 0.0]), (2, None)):
        L = (mass * vx ** 2 + vy ** 2 + vz ** 2) / 2 - z ** 2 / 2
        system = ldaspark.LagrangianSystem(L, [vx ** 2 + vy ** 2 - 1], [x, y, z], [vx, vy, vz], name="constant-speed")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = ldaspark.integrate(system, "gauss-2", t0=0, n_steps=2, q0=[0, 0, 0.1], v0=[3, 4, 0], h=0.1,
                                   engine=engine, dps=dps, project=True)
        assert r.status == 0
        v = np.array([float(c) for c in r.v[0]])
        assert abs(v[0] ** 2 + v[1] ** 2 - 1) <= 4 * np.finfo(float).eps and v[2] == 0
        g = np.array([mass * (v[0] - 3), v[1] - 4])            # L_vv (v - v0), first two components
        assert abs(g[0] * v[1] - g[1] * v[0]) <= 1e-14 * np.abs(g).max()     # parallel to (v1, v2)
        assert g.dot(v[:2]) < 0                                  # toward v0's side: the closest point
        if want is not None:
            assert np.abs(v - want).max() <= 4 * np.finfo(float).eps


@pytest.mark.parametrize("engine", ["generic", "compiled"])
def test_project_onto_a_constraint_without_zeros_names_the_projection(engine):
    """k = v1^2 + v2^2 + 1 has no real zero: project=True fails as the projection, one
    InconsistentInitialDataError naming it; before, the KKT solve's SingularMatrixError said
    'Newton matrix is numerically singular (pivot ratio 0.0e+00)', as if a step of (21) had failed."""
    import sympy
    x, y, z = sympy.symbols("x y z")
    vx, vy, vz = sympy.symbols("vx vy vz")
    system = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2 + vz ** 2) / 2, [vx ** 2 + vy ** 2 + 1], [x, y, z],
                                       [vx, vy, vz], name="no-zero")
    with pytest.raises(InconsistentInitialDataError, match=r"^projection of v0 onto k = 0 failed"):
        ldaspark.integrate(system, "gauss-2", t0=0, n_steps=2, q0=[0, 0, 0], v0=[1, 0, 0], h=0.1, engine=engine,
                           project=True)
