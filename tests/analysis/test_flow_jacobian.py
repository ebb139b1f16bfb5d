"""ldaspark.flow_jacobian: the Jacobian of the SPARK step map by the implicit function theorem
(ldaspark/analysis/flow_jacobian.py), on linear systems whose flow exp(h A) is known in closed form."""
import mpmath
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core.errors import InputError
from ldaspark.core.system import LagrangianSystem


def gyroscopic(B=1):
    """L = |v|^2/2 + B (q1 v2 - q2 v1)/2 + (q1^2 + q2^2)/2, k = v3 - v1 (q3 is cyclic and moves
    with q1). Lagrange-d'Alembert: q1'' = q1/2 + B q2'/2, q2'' = q2 - B q1', so the eigenvalues of
    the (q1, q2, q1', q2') flow solve lambda^4 + (B^2/2 - 3/2) lambda^2 + 1/2 = 0; B = 1:
    lambda^2 = (1 +- i)/2, a complex quadruple +-sqrt((1 +- i)/2) (real and imaginary parts)."""
    q, v = sympy.symbols("q1:4"), sympy.symbols("v1:4")
    L = (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 + B * (q[0] * v[1] - q[1] * v[0]) / 2 + (q[0] ** 2 + q[1] ** 2) / 2
    return LagrangianSystem(L, [v[2] - v[0]], q, v, name="gyroscopic")


def exact_gyro(dps=40):
    with mpmath.workdps(dps):
        roots = []
        for s2 in ((1 + 1j) / 2, (1 - 1j) / 2):
            r = mpmath.sqrt(mpmath.mpc(s2))
            roots += [r, -r]
        return sorted(roots, key=lambda z: (float(z.real), float(z.imag)))


Q0, V0 = ["0.1", "0.2", "0"], ["0.3", "0.1", "0.3"]      # consistent: v3 = v1
LAT = dict(coords=["q1", "q2"], rates=["v1", "v2"])


def _err(fj, exact):
    with mpmath.workdps(40):
        return max(abs(a - b) for a, b in zip(fj.eigenvalues(), exact))


@pytest.mark.parametrize("method,order", [("gauss-1", 2), ("gauss-2", 4), ("lobatto-iiia-iiib-3", 4)])
def test_eigenvalues_converge_with_the_order(method, order):
    """log(mu)/h -> lambda with the method's order (2s Gauss, 2s-2 Lobatto IIIA-B): the observed
    order from h = 0.1, 0.05 within 0.1 of the claim (the measured 2.0002, 4.0001, 4.0000; the
    next term of the error expansion is O(h^2) relative, 0.25% of the leading one at h = 0.05)."""
    sysm = gyroscopic()
    exact = exact_gyro()
    e1 = _err(ldaspark.flow_jacobian(sysm, method, Q0, V0, "0.1", dps=30, **LAT), exact)
    e2 = _err(ldaspark.flow_jacobian(sysm, method, Q0, V0, "0.05", dps=30, **LAT), exact)
    p = float(mpmath.log(e1 / e2, 2))
    assert abs(p - order) <= 0.1, (method, p)
    # negative control: the eigenvalues of the (wrongly) undamped oscillator lambda = +-i, +-i
    # are not approached: the error stays O(1)
    wrong = [1j, 1j, -1j, -1j]
    assert max(abs(complex(a) - b) for a, b in zip(ldaspark.flow_jacobian(
        sysm, method, Q0, V0, "0.05", dps=30, **LAT).eigenvalues(), sorted(wrong, key=lambda z: (z.real, z.imag)))) > 0.3


def test_ift_agrees_with_differences():
    """The implicit-function-theorem Jacobian (2n x 2n, at 30 digits) equals central differences
    of the step map (step 1e-10: truncation and round-off both ~1e-20) to 1e-17; its transpose
    (the Jacobian is not symmetric) does not (negative control)."""
    sysm = gyroscopic()
    a = ldaspark.flow_jacobian(sysm, "gauss-2", Q0, V0, "0.1", dps=30)
    b = ldaspark.flow_jacobian(sysm, "gauss-2", Q0, V0, "0.1", dps=30, how="difference")
    diff = max(abs(x - y) for x, y in zip(a.full.reshape(-1), b.full.reshape(-1)))
    assert diff <= 1e-17
    diffT = max(abs(x - y) for x, y in zip(a.full.T.reshape(-1), b.full.reshape(-1)))
    assert diffT > 1e-2


def oscillator(omega=2):
    """q1'' = -omega^2 q1 (q2 held by the constraint v2 = 0): eigenvalues +-i omega."""
    q, v = sympy.symbols("q1:3"), sympy.symbols("v1:3")
    L = (v[0] ** 2 + v[1] ** 2) / 2 - omega ** 2 * q[0] ** 2 / 2
    return LagrangianSystem(L, [v[1]], q, v, name="oscillator")


def test_midpoint_on_the_oscillator_in_closed_form():
    """gauss-1 is the implicit midpoint rule on the unconstrained q1: its step map is the Cayley
    transform of h A, whose eigenvalues give log(mu)/h = +-i (2/h) arctan(omega h / 2) exactly.
    float64: the Jacobian's entries to ~1e-15, so lambda to ~1e-15 / h = 1e-13 (h = 0.1); the
    exact eigenvalues +-2i themselves are 3.3e-3 away (negative control of the closed form)."""
    h, omega = 0.1, 2.0
    fj = ldaspark.flow_jacobian(oscillator(), "gauss-1", [0.5, 0], [0.1, 0], h, coords=["q1"], rates=["v1"])
    lam = fj.eigenvalues()
    pred = 2 / h * np.arctan(omega * h / 2)
    assert np.allclose([z.imag for z in lam], [-pred, pred], rtol=0, atol=1e-12)
    assert np.allclose([z.real for z in lam], 0, atol=1e-12)
    assert abs(lam[1].imag - omega) > 1e-3


def test_restriction_and_input_errors():
    sysm = gyroscopic()
    fj = ldaspark.flow_jacobian(sysm, "gauss-2", [0.1, 0.2, 0], [0.3, 0.1, 0.3], 0.1, **LAT)
    assert fj.J.shape == (4, 4) and fj.full.shape == (6, 6)
    # the tangent basis satisfies the linearised constraint: the rate v1 carries v3 with it
    assert fj.tangent[3 + 2, 2] == pytest.approx(1.0)
    with pytest.raises(InputError):
        ldaspark.flow_jacobian(sysm, "gauss-2", [0.1, 0.2, 0], [0.3, 0.1, 0.3], 0.1, how="difference")
    with pytest.raises(InputError):
        ldaspark.flow_jacobian(sysm, "gauss-2", [0.1, 0.2, 0], [0.3, 0.1, 0.3], 0.1, coords=["lean"])
    with pytest.raises(InputError):
        ldaspark.flow_jacobian(sysm, "gauss-2", [0.1, 0.2, 0], [0.3, 0.1, 0.3], 0.1, rates=["v1"], dependent=["v1"])


def test_scene_initial_data_by_name():
    """A scene name supplies its own initial data (the robot of 8.3: n = 4, m = 2)."""
    fj = ldaspark.flow_jacobian("robot", "gauss-1", None, None, 0.1)
    assert fj.full.shape == (8, 8) and np.all(np.isfinite(fj.full))


@pytest.mark.parametrize("scene", ["rheonomic-skate", "constant-speed", "relativistic", "friction-skate"])
def test_ift_on_general_scenes(scene):
    """t in L and k, k nonlinear in v, L not quadratic in v, a nonideal term (3.3): the IFT
    Jacobian against central differences at 30 digits within 1e-14 (measured 6e-22 .. 6e-21; the
    friction skate 1.4e-17: the smoothed sgn(u) at u = 0 has third derivative ~1/eps^3 = 1e3, so
    the differences' truncation d^2 f'''/6 with d = 1e-10 is ~1e-17)."""
    a = ldaspark.flow_jacobian(scene, "gauss-2", None, None, "0.1", dps=30)
    b = ldaspark.flow_jacobian(scene, "gauss-2", None, None, "0.1", dps=30, how="difference")
    assert max(abs(x - y) for x, y in zip(a.full.reshape(-1), b.full.reshape(-1))) <= 1e-14
