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
