"""The extremes of ``ldaspark.integrate`` (probe t8): huge steps at mpmath precision, the set-up
check of (4) and the det (4) monitor at the run's digits, and the refusals of inputs at the
extremes (numbers beyond float64's range, t_end off the grid). Each case with its control (the
case that passed before, or the case that must still fail)."""
from __future__ import annotations

import re

import mpmath
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core.errors import InputError, NonFiniteError, SingularSaddleError

x, y, vx, vy, w = sympy.symbols("x y vx vy w")
#: a particle in the plane, k = v_y - x v_x, U = w x^2 / 2 (tests/api/test_option_matrix.py's system)
PARTICLE = ldaspark.LagrangianSystem((vx ** 2 + vy ** 2) / 2 - w * x ** 2 / 2, [vy - x * vx], [x, y], [vx, vy],
                                     params=[w], name="param-particle")


def _huge_step(h, dps=400):
    return ldaspark.integrate(PARTICLE, "gauss-2", t0=0, n_steps=1, h=h, params={"w": "1.5"}, engine="generic",
                              dps=dps, q0=["0.3", "0"], v0=["0.2", "0.06"])


@pytest.mark.parametrize("h", ["1e140", "1e160"])
def test_a_residual_beyond_float64s_range_is_a_number_at_dps(h):
    # one gauss-2 step of h = 1e160 at 400 digits: the first residual is ~ w h^2 = 1.5e320, an mpf
    # beyond float64's range. Before: math.isfinite rounded it to inf and the step ended with status
    # -3, "complex or non-finite residual: L or k evaluated outside its domain"; now the step
    # converges (16 iterations). h = 1e140 (residual 1.5e280) is the control that passed before.
    r = _huge_step(h)
    assert r.status == 0, r.message
    # (21f) holds at the end point to the round-off of O(1) numbers at 400 digits (measured
    # 1.3e-402; 1e-395 leaves 7 digits for the conditioning of a step of 1e160)
    assert max(abs(c) for c in r.constraint[-1]) < mpmath.mpf("1e-395")
    with mpmath.workdps(400):
        assert r.t[-1] == mpmath.mpf(h)


def test_a_non_finite_residual_is_still_a_non_finite_step():
    # control: in float64 the same residual overflows (h = 1e300: w h^2 is inf), a NonFiniteError
    # with status -3 on every engine, as before
    for engine in ("generic", "compiled"):
        r = ldaspark.integrate(PARTICLE, "gauss-2", t0=0.0, n_steps=1, h=1e300, params={"w": 1.5},
                               engine=engine, q0=[0.3, 0.0], v0=[0.2, 0.06])
        assert r.status == -3 and isinstance(r.error, NonFiniteError), (engine, r.message)
        assert np.all(np.isfinite(np.asarray(r.q, float)))
        # the message names the overflow (it blamed "L or k evaluated outside its domain" alone)
        assert "float64 overflow" in r.message, (engine, r.message)


def test_a_domain_error_is_not_called_an_overflow():
    # control of the message above: L = |v|^2 / 2 + sqrt(1 - x) evaluated at a stage beyond x = 1
    xs, ys, vxs, vys = sympy.symbols("x y vx vy")
    system = ldaspark.LagrangianSystem((vxs ** 2 + vys ** 2) / 2 + sympy.sqrt(1 - xs), [vys - xs * vxs],
                                       [xs, ys], [vxs, vys], name="sqrt-well")
    for engine in ("generic", "compiled"):
        r = ldaspark.integrate(system, "gauss-2", t0=0.0, n_steps=3, h=0.5, q0=[0.9, 0.0], v0=[1.0, 0.9],
                               engine=engine)
        assert r.status == -3 and "evaluating L or k" in r.message and "overflow" not in r.message, r.message


q1, q2, q3, v1, v2, v3, ep = sympy.symbols("q1 q2 q3 v1 v2 v3 ep")
#: two constraints that differ by ep v2: K K^T has an eigenvalue ~ ep^2 (the report's rank_loss
#: scene); v2 = 0, v3 = q2 v1 is consistent for every ep, and the exact motion keeps v2 = 0
RANK_LOW = ldaspark.LagrangianSystem((v1 ** 2 + v2 ** 2 + v3 ** 2) / 2 - (q1 ** 2 + q2 ** 2) / 2,
                                     [v3 - q2 * v1, v3 - q2 * v1 + ep * v2], [q1, q2, q3], [v1, v2, v3],
                                     params=[ep], name="rank-low")


def _rank_low(eps, dps):
    return ldaspark.integrate(RANK_LOW, "gauss-2", t0=0, n_steps=10, h="0.05", params={"ep": eps}, dps=dps,
                              q0=["0.1", "0.5", "0"], v0=["1", "0", "0.5"], engine="generic")


@pytest.mark.parametrize("eps, dps", [("1e-8", 30), ("1e-12", 100)])
def test_the_saddle_check_at_dps_judges_4_at_the_runs_digits(eps, dps):
    # (4) with cond(K K^T) ~ 1/eps^2 = 1e16 (1e24): before, check_saddle rounded (4) to float64
    # and refused it with float64's tolerance (reciprocal condition 3.1e-17 <= 2.2e-13) at any dps
    r = _rank_low(eps, dps)
    assert r.status == 0, r.message
    # v2 = 0 exactly; the a-priori bound is the round-off 10^-dps times cond (4) ~ eps^-2
    # (1e-14 at 30 digits, 1e-76 at 100; measured 4e-36 and 6e-102)
    bound = mpmath.mpf(10) ** -dps / mpmath.mpf(eps) ** 2
    assert max(abs(v[1]) for v in r.v) < bound


@pytest.mark.parametrize("eps, dps", [("1e-14", 30), ("0", 30), ("1e-8", None)])
def test_the_saddle_check_still_refuses_what_the_digits_cannot_resolve(eps, dps):
    # controls: cond (4) ~ 1e28 above 10^30 / 1e3 at 30 digits, an exactly rank-deficient K, and
    # float64 at cond 1e16 (unchanged) are refused at set-up on the engine that runs them
    with pytest.raises(SingularSaddleError, match=r"\(4\)"):
        _rank_low(eps, dps) if dps else ldaspark.integrate(
            RANK_LOW, "gauss-2", t0=0.0, n_steps=10, h=0.05, params={"ep": float(eps)},
            q0=[0.1, 0.5, 0.0], v0=[1.0, 0.0, 0.5])


#: the same pair of constraints with K depending on q1, which moves: rounded to float64, det (4)
#: is 0 at some points of the motion and positive at others (the singular value ~ eps |K| is below
#: float64's resolution of (4))
RANK_LOW_Q1 = ldaspark.LagrangianSystem((v1 ** 2 + v2 ** 2 + v3 ** 2) / 2 - (q1 ** 2 + q2 ** 2) / 2,
                                        [v3 - q1 * v1, v3 - q1 * v1 + ep * v2], [q1, q2, q3], [v1, v2, v3],
                                        params=[ep], name="rank-low-q1")


@pytest.mark.parametrize("q1_0", ["0.12", "0.5"])
def test_the_saddle_monitor_at_dps_reads_the_sign_of_det_4_at_the_runs_digits(q1_0):
    # before: det (4) rounded to float64 was positive at t = 0 and 0 after the first step from
    # q1 = 0.12, and the run stopped with status -2, "crossed the singular set of (4)", although
    # det (4) keeps its sign (K has full rank, L_vv = I); q1 = 0.5 (float64 sign 0 at t = 0, the
    # monitor off) is the control that passed before
    r = ldaspark.integrate(RANK_LOW_Q1, "gauss-2", t0=0, n_steps=40, h="0.05", params={"ep": "1e-8"}, dps=30,
                           q0=[q1_0, "0.5", "0"], v0=["1", "0", q1_0], engine="generic")
    assert r.status == 0, r.message
    # v2 = 0 exactly: the bound of the test above, 10^-30 eps^-2 = 1e-14 (measured 6e-33)
    assert max(abs(v[1]) for v in r.v) < mpmath.mpf("1e-14")


@pytest.mark.parametrize("where", ["h", "q0", "t0"])
def test_a_number_beyond_float64s_range_is_refused_saying_why(where):
    # h = "1e400" at 1000 digits is a finite number there; every engine's inputs are bounded by
    # float64's range (|x| <= 1.8e308), and the refusal said only "h must be finite, got '1e400'"
    args = dict(t0="0", n_steps=1, h="0.1", q0=["0.3", "0"], v0=["0.2", "0.06"])
    if where == "q0":
        args["q0"] = ["1e400", "0"]
    else:
        args[where] = "1e400"
    with pytest.raises(InputError, match=r"must be finite, got '1e400' \(beyond float64's range"):
        ldaspark.integrate(PARTICLE, "gauss-2", params={"w": "1.5"}, engine="generic", dps=1000, **args)
    # control: an infinite value gets no such hint
    args[where if where != "q0" else "h"] = "inf"
    with pytest.raises(InputError, match=r"must be finite, got 'inf'$"):
        ldaspark.integrate(PARTICLE, "gauss-2", params={"w": "1.5"}, engine="generic", dps=1000, **args)


@pytest.mark.parametrize("t_end, shown", [("1.000000000001", "1.000000000001"),
                                          ("1.0000000000000000000001", "1.0000000000000000000001"),
                                          ("1.05", "1.05")])
def test_t_end_off_the_grid_at_dps_is_shown_with_the_digits_that_differ(t_end, shown):
    # the refusal printed (t_end - t0) at 12 digits: "(t_end - t0) = 1.0 is not an integer multiple of
    # h = 0.1 ... (off by 1.0e-12)"; now with 12 digits plus those down to the offset. 1.05 is the
    # control (12 digits were enough before); float64 prints repr(span), which shows it too
    with pytest.raises(InputError, match=rf"^\(t_end - t0\) = {re.escape(shown)} is not an integer multiple"):
        ldaspark.integrate(PARTICLE, "gauss-2", t_span=("0", t_end), h="0.1", params={"w": "1.5"}, dps=30,
                           q0=["0.3", "0"], v0=["0.2", "0.06"])


def test_the_det_4_monitor_at_dps_reads_the_sign_with_entries_far_apart():
    # (4) of the particle at x = 2e559 (euler-i, one step of h = 1e300 at 30 digits):
    # det [[1, 0, x], [0, 1, 1], [x, 1, 0]] = -(1 + x^2) < 0, the sign at t = 0 as well. mpmath.det
    # called it 0 (a pivot below 10^-30 of the largest entry) and the run stopped with status -2,
    # "det (4) changed sign"; the sign is read by LU as numpy's slogdet does in float64
    from ldaspark.core.spark import _det_sign_mp
    with mpmath.workdps(30):
        big = mpmath.mpf("2e559")
        S = np.array([[1, 0, big], [0, 1, 1], [big, 1, 0]], dtype=object) * mpmath.mpf(1)
        assert _det_sign_mp(S) == -1
        # controls: the signs of random matrices agree with float64's; a singular one is 0
        rng = np.random.default_rng(7)
        for _ in range(20):
            A = rng.normal(size=(5, 5))
            assert _det_sign_mp(np.array([[mpmath.mpf(x) for x in row] for row in A], dtype=object)) \
                == int(np.linalg.slogdet(A)[0])
        assert _det_sign_mp(np.array([[mpmath.mpf(1), mpmath.mpf(2)], [mpmath.mpf(2), mpmath.mpf(4)]])) == 0
    r = ldaspark.integrate(PARTICLE, "euler-i", t0=0, n_steps=1, h="1e300", dps=30, q0=["0.3", "0"],
                           v0=["0.2", "0.06"], params={"w": "1.5"}, engine="generic")
    assert r.status == 0, r.message


def test_the_det_4_monitor_at_dps_still_sees_a_crossing():
    # control of the two monitor tests above: L_vv = diag(1 - q1^2, 1, 1) is singular at q1 = 1,
    # where det (4) changes sign; from q1 = 0.9, v1 = 1 (h = 0.02) the float64 run stops at step 4
    # (tests/api/test_paths_agree.py), and so does the 30-digit run with the sign read in mpf
    q, v = list(sympy.symbols("q1:4")), list(sympy.symbols("v1:4"))
    system = ldaspark.LagrangianSystem((1 - q[0] ** 2) * v[0] ** 2 / 2 + (v[1] ** 2 + v[2] ** 2) / 2,
                                       [v[2] - q[1] * v[0]], q, v, name="mass-vanishing")
    r = ldaspark.integrate(system, "gauss-2", t_span=("0", "2"), h="0.02", dps=30, engine="generic",
                           q0=["0.9", "0.3", "0"], v0=["1", "0.1", "0.3"])
    assert r.status == -2 and "step 4 " in r.message and "crossed the singular set" in r.message, r.message


def test_a_singular_newton_matrix_at_dps_is_named_by_its_pivot_ratio():
    # one gauss-2 step of h = 1e150: the Newton matrix has entries 1 and ~h^2 w = 5.9e299. At 30
    # digits the message said "numerically singular (pivot 1.0 at column 1)", as if a pivot of 1
    # were singular; it gives the ratio to the largest entry now, as float64's message does
    # (the control: "pivot ratio 4.8e-301", unchanged)
    r = _huge_step("1e150", dps=30)
    assert r.status == -1 and re.search(r"numerically singular \(pivot ratio 1\.7e-300 at column 1: pivot 1\.0, "
                                        r"largest entry 5\.92e\+299\)", r.message), r.message
    r64 = ldaspark.integrate(PARTICLE, "gauss-2", t0=0.0, n_steps=1, h=1e150, params={"w": 1.5}, engine="generic",
                             q0=[0.3, 0.0], v0=[0.2, 0.06])
    # (LAPACK's pivots: the ratio's exponent only, not its digits)
    assert r64.status == -1 and re.search(r"numerically singular \(pivot ratio \d\.\de-30[01]\)", r64.message), \
        r64.message


@pytest.mark.parametrize("dps, dense", [(None, False), (500, True)])
def test_a_step_below_float64s_range_is_refused_saying_it_rounds_to_0(dps, dense):
    # h = "1e-400" in float64, or at 500 digits with dense output (whose grid is float64): the
    # refusal read "h = 0 does not advance t near 0 in float64 (times would repeat): use |h| >= 0 or
    # a t0 closer to 0"
    args = dict(t0="0", n_steps=3, h="1e-400", params={"w": "1.5"}, engine="generic", dps=dps,
                dense_output=dense, q0=["0.3", "0"], v0=["0.2", "0.06"])
    with pytest.raises(InputError, match=r"= 1e-400 does not advance t in float64: it rounds to 0 there"):
        ldaspark.integrate(PARTICLE, "gauss-2", **args)
    if dps:     # control: without dense output the 500-digit grid holds the step
        args["dense_output"] = False
        assert ldaspark.integrate(PARTICLE, "gauss-2", **args).status == 0
    # control: a step that rounds to a number but not past t0 keeps its message
    with pytest.raises(InputError, match=r"h = 2e-08 does not advance t near 1e\+08 in float64 \(times would "
                                         r"repeat\): use \|h\| >= 2.98e-08"):
        ldaspark.integrate(PARTICLE, "gauss-2", t0=1e8, n_steps=3, h=2e-8, params={"w": 1.5},
                           q0=[0.3, 0.0], v0=[0.2, 0.06])


def test_the_guard_names_roots_beyond_float64s_range_by_their_digits():
    # euler-i, h = 1e300 at 30 digits: step 1 has two roots (q1 = -1.6e1088 and -3.7e1102). The
    # message printed both as "q1 = [-inf -inf]" with "E = inf", two equal-looking roots; it gives
    # the run's numbers now. Control: a float64 run's message keeps its format (10 digits)
    r = ldaspark.integrate(PARTICLE, "euler-i", t0=0, n_steps=2, h="1e300", dps=30, q0=["0.3", "0"],
                           v0=["0.2", "0.06"], params={"w": "1.5"}, engine="generic")
    assert r.status == -4 and "inf" not in r.message, r.message
    assert re.search(r"the engine's q1 = \[-1\.5611285324e\+1088 -4\.5e\+600\].* E = 1\.827841721e\+2176, and "
                     r"from .* q1 = \[-3\.7362301351e\+1102 ", r.message), r.message
    from ldaspark.core import guard
    err = guard.mismatch(3, 0.3, 0.1, (np.array([1.5, -2.0]), np.array([0.25, 1e-3]), 0.125),
                         (np.array([1.5, 2.0]), np.array([0.25, 1e-3]), 2.5), "a start")
    assert "the engine's q1 = [ 1.5 -2. ], v1 = [0.25  0.001] with energy (8) E = 0.125, and from a start " \
           "q1 = [1.5 2. ], v1 = [0.25  0.001] with E = 2.5;" in str(err), str(err)


def test_the_guard_compares_roots_beyond_float64s_range_in_the_runs_numbers():
    # same_root rounded the roots to float64: two equal roots at 1e400 (30 digits) were inf - inf =
    # NaN apart, "two roots", a status -4 for a step that stands; controls: roots 1e-3 apart
    # (relative) differ, and float64 roots keep their verdicts
    from ldaspark.core import guard
    with mpmath.workdps(30):
        q = np.array([mpmath.mpf("1e400"), mpmath.mpf("-2.5e401")], dtype=object)
        v = np.array([mpmath.mpf("3e350"), mpmath.mpf(1)], dtype=object)
        assert guard.same_root(q, v, q.copy(), v.copy())
        assert not guard.same_root(q, v, q * (1 + mpmath.mpf("1e-3")), v)
    assert guard.same_root(np.array([1.0, 2.0]), np.array([0.5]), np.array([1.0, 2.0 + 1e-12]), np.array([0.5]))
    assert not guard.same_root(np.array([1.0, 2.0]), np.array([0.5]), np.array([1.0, 2.1]), np.array([0.5]))


@pytest.mark.parametrize("engine, dense", [("generic", False), ("compiled", False), ("compiled", True)])
def test_a_trajectory_that_cannot_be_stored_is_refused_naming_save_every(engine, dense, monkeypatch):
    # n_steps = 5 10**6 at save_every = 1 is refused before any step (the samples need 1.3-1.7 GiB;
    # the machine's memory is fixed at 1 GiB here, half of it the bound); the advice named only
    # fewer steps, while a larger save_every keeps the run. With dense output every step is stored:
    # no such advice (control)
    from ldaspark.core import validate
    monkeypatch.setattr(validate, "physical_memory", lambda: 2 ** 30)
    with pytest.raises(InputError, match="needs about") as ei:
        ldaspark.integrate(PARTICLE, "gauss-2", t0=0.0, n_steps=5 * 10 ** 6, h=1e-6, params={"w": 1.5}, engine=engine,
                           dense_output=dense, q0=[0.3, 0.0], v0=[0.2, 0.06])
    assert ("a larger save_every" in str(ei.value)) is (not dense), str(ei.value)
