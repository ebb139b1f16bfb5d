"""Compensated (Kahan) summation of the q and p updates: round-off against the same discrete
map in 40-digit mpmath (ldaspark.compiled.fast.roundoff_errors), on a linear system where the 2-stage
Lobatto IIIA-B SPARK step is a linear map. 1e5 steps here; 1e6 in benchmarks/kahan_long_run.py."""
import pytest

from ldaspark.compiled.fast import growth_exponent, roundoff_errors

N_STEPS = 100_000


@pytest.fixture(scope="module")
def pow2():
    return roundoff_errors(n_steps=N_STEPS, every=1000, n_ics=16, h=1 / 16)


@pytest.fixture(scope="module")
def decimal_h():
    return roundoff_errors(n_steps=N_STEPS, every=1000, n_ics=16, h=0.05)


def test_compensated_roundoff_grows_like_sqrt_n(pow2):
    """h = 1/16 (products with h exact): compensated round-off follows sqrt(N) (Brouwer's law)
    and is several times below plain summation."""
    comp, plain = pow2["rms"]["compensated"], pow2["rms"]["plain"]
    assert growth_exponent(pow2["N"], comp) <= 0.65
    assert comp[-1] * 3 <= plain[-1]
    assert comp[-1] <= 50 * 2.0 ** -52 * N_STEPS ** 0.5


def test_neutral_direction_gains_most(decimal_h):
    """Along the conserved q1 + q2 + q3 errors only accumulate; Kahan removes the O(eps |q|)
    per-step rounding there, for any h."""
    comp, plain = decimal_h["rms_neutral"]["compensated"], decimal_h["rms_neutral"]["plain"]
    assert growth_exponent(decimal_h["N"], comp) <= 0.65
    assert comp[-1] * 5 <= plain[-1]


def test_exponent_check_detects_linear_drift(decimal_h):
    """Negative control: with h = 0.05 products x * h round with a bias that acts as a frequency
    shift of ~1e-18 per step; the same exponent check sees the linear phase drift (Kahan does not
    remove it: it is in the increments, not in the sums)."""
    assert growth_exponent(decimal_h["N"], decimal_h["rms"]["compensated"]) > 0.8


def _drift_system():
    """A free particle in the plane kept on the line y = 0 (k = v_y): x(t) = x0 + v_x t exactly,
    with every stage value V_i = v0 and every multiplier 0 (the residual of (21) vanishes at the
    zero increments on every path), so each step adds exactly h b_j-sum v_x = h v_x to x."""
    import sympy

    from ldaspark.core.system import LagrangianSystem
    x, y, vx, vy = sympy.symbols("x y vx vy")
    return LagrangianSystem((vx ** 2 + vy ** 2) / 2, [vy], [x, y], [vx, vy], name="kahan-drift")


def _kernel_paths():
    """(label, run(compensated) -> FastSolution) for every compiled step loop that sums q and v:
    the SPARK kernel with the dense and the block LU, the general-form kernel, the quasi-Newton
    kernels of both forms and the semi-implicit kernel (25)."""
    q0, v0, h, n = [1.0, 0.0], [2.0 ** -60, 0.0], 2.0 ** -4, 2 ** 13
    return q0, v0, h, n, _paths(_drift_system(), q0, v0, h, n)


def _paths(system, q0, v0, h, n, general=True):
    from ldaspark.compiled.quasi import run_quasi
    from ldaspark.compiled.runner import compile_system, run_kernels
    mech = compile_system(system)
    assert mech.form == "mechanical"
    paths = {
        "spark dense": lambda c: run_kernels(mech, "gauss-2", 0.0, q0, v0, h, n, n, c, kernel="spark",
                                             linear_solver="dense", reuse_matrix=False),
        "spark sparse": lambda c: run_kernels(mech, "gauss-2", 0.0, q0, v0, h, n, n, c, kernel="spark",
                                              linear_solver="sparse", reuse_matrix=False),
        "quasi": lambda c: run_quasi(mech, "gauss-2", 0.0, q0, v0, h, n, n, c),
        "semi-implicit (25)": lambda c: run_kernels(mech, "lobatto-iiia-iiib-2", 0.0, q0, v0, h, n, n, c),
    }
    if general:
        gen = compile_system(system, form="general")
        assert gen.form == "general"
        paths["general"] = lambda c: run_kernels(gen, "gauss-2", 0.0, q0, v0, h, n, n, c, kernel="spark")
        paths["quasi general"] = lambda c: run_quasi(gen, "gauss-2", 0.0, q0, v0, h, n, n, c)
    return paths


def test_every_kernel_sums_as_asked():
    """x0 = 1, v_x = 2^-60, h = 2^-4: each step adds 2^-64 to x, below half an ulp of 1 (2^-53),
    so plain summation never moves x (exactly x0 after any number of steps), while the
    compensated sum keeps the lost bits and after N = 2^13 steps is within one ulp (2^-52) of the
    exact x0 + N h v_x = 1 + 2^-51 (Kahan's bound; GNI VIII.5). On every kernel: a kernel that
    ignored ``compensated`` (or dropped the correction) is 2 ulps off, one that compensated when
    asked not to lands on 1 + 2^-51."""
    q0, v0, h, n, paths = _kernel_paths()
    exact = q0[0] + n * h * v0[0]
    ulp = 2.0 ** -52
    assert exact - q0[0] == 2 * ulp
    for label, run in paths.items():
        comp, plain = run(True), run(False)
        assert comp.stats["compensated"] is True and plain.stats["compensated"] is False, label
        assert comp.stats["steps"] == plain.stats["steps"] == n, label
        assert abs(float(comp.q[-1][0]) - exact) <= ulp, (label, float(comp.q[-1][0]) - exact)
        assert float(plain.q[-1][0]) == q0[0], (label, float(plain.q[-1][0]) - q0[0])
        assert float(comp.q[-1][1]) == float(plain.q[-1][1]) == 0.0, label


def _fall_system():
    """The particle of ``_drift_system`` under a constant force g = 2^-60 along x (U = g x): in
    the mechanical form every stage of (21) has grad U = g, so each step adds exactly
    dv = -h (b^_1 + b^_2) g = -h g to v_x (b^ = (1/2, 1/2), h a power of 2: no rounding)."""
    import sympy

    from ldaspark.core.system import LagrangianSystem
    x, y, vx, vy = sympy.symbols("x y vx vy")
    g = sympy.Integer(2) ** -60
    return LagrangianSystem((vx ** 2 + vy ** 2) / 2 - g * x, [vy], [x, y], [vx, vy], name="kahan-fall")


def test_every_mechanical_kernel_sums_the_velocity_as_asked():
    """The velocity's sum v1 = v0 + dv is compensated too (``newton.advance``; the test above sees
    only q, v being constant there): v0 = 1, dv = -h g = -2^-64 a step, below half an ulp of v
    (2^-54 just below 1), so plain summation never moves v_x (exactly 1 after any number of
    steps), while the compensated sum after N = 2^13 steps is within one ulp (2^-53) of the exact
    1 - N h g = 1 - 2^-51 (Kahan's bound, as above). The mechanical kernels only: the general
    form's residual holds p(v1) - p(v0), whose rounding, eps |p| ~ 1e-16 a step, swamps the 2^-64
    (measured: its plain sum leaves 1 too). Planted: v summed plainly whatever ``compensated``
    says, or the quasi loop passing q's compensation for v's: 2^-51 (4 ulps) off. Control: the
    same runs without compensation stay at exactly 1, so the tolerance cannot pass a plain sum."""
    q0, v0, h, n = [0.0, 0.0], [1.0, 0.0], 2.0 ** -4, 2 ** 13
    exact = 1.0 - n * h * 2.0 ** -60
    ulp = 2.0 ** -53                    # the spacing of the doubles in [1/2, 1)
    assert 1.0 - exact == 4 * ulp
    for label, run in _paths(_fall_system(), q0, v0, h, n, general=False).items():
        comp, plain = run(True), run(False)
        assert comp.stats["steps"] == plain.stats["steps"] == n, label
        assert abs(float(comp.v[-1][0]) - exact) <= ulp, (label, float(comp.v[-1][0]) - exact)
        assert float(plain.v[-1][0]) == 1.0, (label, float(plain.v[-1][0]) - 1.0)
        assert float(comp.v[-1][1]) == float(plain.v[-1][1]) == 0.0, label
