"""Rules of ``ldaspark.analysis.flow_jacobian`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import math
import mpmath
import numpy as np
import pytest
import sympy
from ldaspark.core.errors import InputError, NonFiniteError
from ldaspark.core.system import LagrangianSystem
from ldaspark.analysis import flow_jacobian as FJ


# ---------------------------------------------------------------------------------------------
# small systems
def _oscillator(param=False):
    """q1'' = -k q1 (k a parameter or 1), q2 cyclic with the constraint v2 = v1 (m = 1)."""
    q, v = sympy.symbols("q1:3"), sympy.symbols("v1:3")
    k = sympy.Symbol("kk", positive=True) if param else 1
    L = (v[0] ** 2 + v[1] ** 2) / 2 - k * q[0] ** 2 / 2
    kw = {"params": [k]} if param else {}
    return LagrangianSystem(L, [v[1] - v[0]], q, v, name="osc-p" if param else "osc", **kw)


def _rotated(dps=None):
    return FJ.flow_jacobian(_oscillator(), "gauss-1", [0.1, 0], [0.2, 0.2], 0.1, dps=dps)


# ---------------------------------------------------------------------------------------------
# flow_jacobian
def test_flow_jacobian_params_are_applied_and_checked():
    sp = _oscillator(param=True)
    a = FJ.flow_jacobian(sp, "gauss-1", [0.1, 0], [0.2, 0.2], 0.1, params={"kk": 1})
    b = FJ.flow_jacobian(sp, "gauss-1", [0.1, 0], [0.2, 0.2], 0.1, params={"kk": 4})
    ref = _rotated()
    # kk = 1 is the plain oscillator. With v2 = v1 the mass is 2: q1'' = -(kk/2) q1, and the
    # midpoint rule (gauss-1) gives dv1/dq1(0) = -h w2 / (1 + h^2 w2 / 4), w2 = kk / 2
    tol = 1e-12
    assert np.max(np.abs(a.full - ref.full)) < tol
    for fj, kk in ((a, 1), (b, 4)):
        w2, h = kk / 2, 0.1
        assert abs(fj.full[2, 0] + h * w2 / (1 + h * h * w2 / 4)) < tol
    with pytest.raises(InputError, match="params must be a dict"):
        FJ.flow_jacobian(sp, "gauss-1", [0.1, 0], [0.2, 0.2], 0.1, params=[("kk", 1)])
    with pytest.raises(InputError):
        FJ.flow_jacobian(sp, "gauss-1", [0.1, 0], [0.2, 0.2], 0.1, params={"kk": float("nan")})


def test_flow_jacobian_argument_combinations_are_refused():
    sysm = _oscillator()
    args = (sysm, "gauss-1", [0.1, 0], [0.2, 0.2], 0.1)
    with pytest.raises(InputError, match="needs dps"):
        FJ.flow_jacobian(*args, how="difference")
    with pytest.raises(InputError, match="not both"):
        FJ.flow_jacobian(*args, tangent=np.eye(4)[:, :1], select=[0], coords=[0])
    with pytest.raises(InputError, match="not both"):
        FJ.flow_jacobian(*args, tangent=np.eye(4)[:, :1], select=[0], dependent=[1])
    with pytest.raises(InputError, match="read with tangent"):
        FJ.flow_jacobian(*args, select=[0])
    with pytest.raises(InputError, match="must be a list"):
        FJ.flow_jacobian(*args, rates="v1")
    with pytest.raises(InputError, match="must be a list"):
        FJ.flow_jacobian(*args, dependent=3)
    with pytest.raises(InputError, match="dependent is read with"):
        FJ.flow_jacobian(*args, dependent=[1])
    # the tangent path: S full B with B a column of the identity reads one entry of full
    fj = FJ.flow_jacobian(*args, tangent=np.eye(4)[:, [0]], select=[2])
    assert fj.J.shape == (1, 1) and fj.J[0, 0] == fj.full[2, 0]
    assert fj.select == [2]


def test_check_tangent_shapes_and_entries():
    n = 2
    ok = FJ._check_tangent(np.eye(4)[:, :2], n, None)
    assert np.asarray(ok).shape == (4, 2)
    FJ._check_tangent(np.eye(4), n, None)                      # r = 2n is allowed
    FJ._check_tangent(np.eye(4)[:, :1], n, None)               # r = 1 is allowed
    for bad in (np.zeros((4, 0)), np.zeros((4, 5)), np.zeros((3, 2)), np.zeros(4), np.zeros((5, 1))):
        with pytest.raises(InputError, match="2n x r"):
            FJ._check_tangent(bad, n, None)

    class Refuses:
        def __array__(self, *a, **k):
            raise ValueError("no")
    with pytest.raises(InputError, match="2n x r"):
        FJ._check_tangent(Refuses(), n, None)
    t = [[1, 0], [0, "x"], [0, 0], [0, 0]]
    with pytest.raises(InputError, match="tangent entry 3"):
        FJ._check_tangent(t, n, None)
    with pytest.raises(InputError, match="tangent entry 2"):
        FJ._check_tangent([[1, 0], [float("nan"), 0], [0, 0], [0, 0]], n, None)


def test_index_bounds_names_and_repeats():
    sysm = _oscillator()                   # n = 2
    assert FJ._index([0, 1], sysm, "q") == [0, 1]
    assert FJ._index([np.int64(1)], sysm, "q") == [1]
    for bad in (2, -1):
        with pytest.raises(InputError, match="out of range"):
            FJ._index([bad], sysm, "q")
    assert FJ._index(["q2", "q1"], sysm, "q") == [1, 0]
    assert FJ._index(["v2"], sysm, "v") == [1]
    assert FJ._index(["q2"], sysm, "v") == [1]           # a rate named after its coordinate
    with pytest.raises(InputError, match="not one of the coordinates"):
        FJ._index(["v2"], sysm, "q")                     # a coordinate is never named after its rate
    with pytest.raises(InputError, match="not one of"):
        FJ._index([True], sysm, "q")                     # a bool is not an index
    with pytest.raises(InputError, match="twice"):
        FJ._index([0, "q1"], sysm, "q")


def test_choose_dependent_is_the_best_conditioned_column_outside_the_rates():
    K = np.array([[0.5, 0.0, 3.0]])
    assert FJ._choose_dependent(K, [], 1) == [2]
    assert FJ._choose_dependent(K, [2], 1) == [0]
    K2 = np.array([[1.0, 0.0, 0.0, 5.0], [0.0, 0.1, 2.0, 0.0]])
    assert FJ._choose_dependent(K2, [], 2) == [2, 3]       # sorted, the two dominant columns
    assert FJ._choose_dependent(K2, [2], 2) == [1, 3]
    with pytest.raises(InputError, match="no invertible"):
        FJ._choose_dependent(np.array([[0.0, 1.0, 0.0]]), [1], 1)
    with pytest.raises(InputError, match="no invertible"):
        FJ._choose_dependent(np.array([[1.0, 1.0]]), [0, 1], 1)   # nothing left outside the rates


def test_restriction_refuses_dependent_overlapping_the_rates_and_rank_deficient_K():
    sysm = _oscillator()
    args = (sysm, "gauss-1", [0.1, 0], [0.2, 0.2], 0.1)
    with pytest.raises(InputError, match="disjoint"):
        FJ.flow_jacobian(*args, rates=["v1"], dependent=["v1"])
    with pytest.raises(InputError, match="disjoint"):
        FJ.flow_jacobian(*args, rates=["v1"], dependent=[])
    # the only velocities outside the rates have a zero column of K: k = v2 - v1, rates v1, v2
    with pytest.raises(InputError, match="no invertible"):
        FJ.flow_jacobian(*args, rates=["v1", "v2"])
    # coordinate q1 with v2 dependent: the linearised constraint k_v dv = 0 moves v2 with v1
    fj = FJ.flow_jacobian(*args, coords=["q1"], rates=["v1"])
    B = np.asarray(fj.tangent, dtype=float)
    assert B[:, 0].tolist() == [1, 0, 0, 0]             # k_q = 0: q1 moves alone
    assert B[:, 1].tolist() == [0, 0, 1, 1]             # v2 = v1 to first order
    assert fj.select == [0, 2]
    assert np.allclose(fj.J, fj.full[[0, 2], :].dot(B), rtol=0, atol=1e-15)


def test_finite_rule_needs_every_entry_finite_and_real():
    FJ._finite(np.array([[1.0, 2.0], [3, np.int64(4)]], dtype=object), 0.0)
    FJ._finite(np.array([mpmath.mpf(1), mpmath.mpf(-2)], dtype=object), 0.0)
    for bad in (float("nan"), float("inf"), mpmath.mpf("inf"), mpmath.mpc(1, 1), mpmath.mpc(1, 0), "1", None):
        with pytest.raises(NonFiniteError):
            FJ._finite(np.array([1.0, 2.0, bad], dtype=object), 0.0)


def test_multipliers_and_eigenvalues_of_a_known_J():
    h = 0.5
    a, b = math.exp(-0.3 * h), math.exp(0.7 * h)
    J = np.array([[b, 0.0], [0.0, a]])
    fj = FJ.FlowJacobian(J, J, None, [0, 1], h, None, np.zeros(1), np.zeros(1))
    mu = sorted(fj.multipliers(), key=lambda z: z.real)
    assert abs(mu[0] - a) < 1e-15 and abs(mu[1] - b) < 1e-15
    lam = fj.eigenvalues()
    assert abs(lam[0] - (-0.3)) < 1e-14 and abs(lam[1] - 0.7) < 1e-14      # sorted by real part
    with mpmath.workdps(30):
        hm = mpmath.mpf(1) / 2
        Jm = np.array([[mpmath.exp(mpmath.mpf("0.7") * hm), 0], [0, mpmath.exp(mpmath.mpf("-0.3") * hm)]],
                      dtype=object)
    fm = FJ.FlowJacobian(Jm, Jm, None, [0, 1], hm, 30, np.zeros(1), np.zeros(1))
    lm = fm.eigenvalues()
    with mpmath.workdps(30):
        assert abs(lm[0] - mpmath.mpf("-0.3")) < mpmath.mpf(10) ** -27
        assert abs(lm[1] - mpmath.mpf("0.7")) < mpmath.mpf(10) ** -27


def test_index_error_names_at_most_40_characters():
    with pytest.raises(InputError) as e:
        FJ._index(["x" * 50], _oscillator(), "q")
    assert "x" * 40 in str(e.value) and "x" * 41 not in str(e.value)


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), mpmath.mpf("nan"), mpmath.mpc(1, 1)])
def test_flow_jacobian_refuses_one_non_finite_entry_among_finite_ones(bad):
    from ldaspark.core.errors import NonFiniteError
    from ldaspark.analysis.flow_jacobian import _finite
    _finite(np.array([[1.0, 2.0], [3.0, 4.0]]), 0)                          # finite: accepted
    with pytest.raises(NonFiniteError):
        _finite(np.array([[1.0, 2.0], [3.0, bad]], dtype=object), 0)
