"""Rules of ``ldaspark.core.validate`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
from __future__ import annotations

import concurrent.futures as cf
from types import SimpleNamespace
import numpy as np
import pytest
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.core.errors import InputError
import mpmath
# --- core/validate.py ---------------------------------------------------------------------------
from ldaspark.core import validate as V  # noqa: E402


# ============================== core/validate ==============================================
def test_check_executor_refuses_a_shut_down_pool_and_keeps_a_live_one():
    from ldaspark.core import validate
    live = cf.ThreadPoolExecutor(1)
    assert validate.check_executor(live) is live and validate.check_executor(None) is None
    live.shutdown()
    with pytest.raises(InputError, match="shut down"):
        validate.check_executor(live)
    flag = SimpleNamespace(submit=print, map=map, _shutdown=1)        # truthy but not True: not shut down
    assert validate.check_executor(flag) is flag
    with pytest.raises(InputError, match="shut down"):
        validate.check_executor(SimpleNamespace(submit=print, map=map, _shutdown_thread=True))
    with pytest.raises(InputError, match="submit, map"):
        validate.check_executor(SimpleNamespace(submit=print))


def test_point_takes_the_scenes_data_only_where_none_is_given():
    from ldaspark.core import validate
    calls = []
    scene = SimpleNamespace(initial=lambda dps: calls.append(dps) or (0.5, [1.0, 2.0], [3.0, 4.0]))
    sys2 = SimpleNamespace(n=2)
    assert validate.point(sys2, None, None, [7.0, 8.0], scene=scene, dps=30) == (0.5, [1.0, 2.0], [7.0, 8.0])
    assert calls == [30]
    assert validate.point(sys2, 1.0, [5.0, 6.0], None, scene=scene) == (1.0, [5.0, 6.0], [3.0, 4.0])
    assert validate.point(sys2, 2.0, [5.0, 6.0], [7.0, 8.0], scene=scene) == (2.0, [5.0, 6.0], [7.0, 8.0])
    assert len(calls) == 2                           # everything given: the scene is not asked
    with pytest.raises(InputError, match="give q0 and v0"):
        validate.point(sys2, 0.0, None, [1.0, 2.0])
    with pytest.raises(InputError, match="n = 2"):
        validate.point(sys2, 0.0, [1.0], [1.0, 2.0])


def test_step_advances_boundary_in_float64_and_digits():
    from ldaspark.core import validate
    t0 = 1e17
    need = 2 * float(np.spacing(t0 + 64))          # T = t0 + n h, h = need (the same spacing)
    validate.step_advances(t0, need, 1)
    with pytest.raises(InputError, match="does not advance"):
        validate.step_advances(t0, np.nextafter(need, 0), 1)
    with pytest.raises(InputError, match="does not advance"):
        validate.step_advances(-t0, -1.0, 1)
    validate.step_advances(0.0, 1e-300, 3)
    need30 = 2 * 1.0 * 10.0 ** (1 - 30)
    validate.step_advances(1.0, need30, 1, dps=30)
    with pytest.raises(InputError, match="30 digits"):
        validate.step_advances(1.0, need30 * 0.99, 1, dps=30)
    # n_steps enters T: the last time sets the spacing
    validate.step_advances(0.0, 1.0, 10 ** 15)
    with pytest.raises(InputError):
        validate.step_advances(0.0, 1.0, 10 ** 17)


def test_step_advances_beyond_float_range_of_the_digits():
    """At dps >= ~310 the spacing 2 T 10^(1 - dps) underflowed to 0.0 in float (and so did a
    string h such as "1e-420"): a step that leaves t where it is was accepted, and the run
    returned status 0 with every time equal (dps 400, t0 = 1, h = "1e-420"; dps 2000, t0 = 1e6,
    h = "1e-1999"). Two-sided: the smallest step that resolves passes, 0.99 of it is refused."""
    from ldaspark.core import validate
    validate.step_advances("1", "2e-399", 1, dps=400)
    with pytest.raises(InputError, match="400 digits"):
        validate.step_advances("1", "1.98e-399", 1, dps=400)
    with pytest.raises(InputError, match="400 digits"):
        validate.step_advances("1", "1e-420", 3, dps=400)
    with pytest.raises(InputError, match="2000 digits"):
        validate.step_advances("1e6", "1e-1999", 2, dps=2000)
    validate.step_advances("1e6", "2.1e-1993", 2, dps=2000)
    import ldaspark
    with pytest.raises(InputError, match="does not advance"):
        ldaspark.integrate("particle", "gauss-1", t0="1", h="1e-420", n_steps=2, dps=400, engine="generic")


def test_a_float64_step_below_its_range_is_named_as_such():
    """h = "1e-99999999" in float64 passed the nonzero check (read in its own digits), became 0.0,
    and was refused with "h = 0 does not advance t near 0 ...: use |h| >= 0" (advice no step can
    follow). Now it says the step rounds to 0 in float64 and needs dps= digits; controls: a subnormal
    step (1e-310) passes this check at t0 = 0, and the same text at 30 digits is judged there."""
    from ldaspark.core import validate
    import ldaspark
    for h in ("1e-99999999", "-1e-400", 1e-330):
        with pytest.raises(InputError, match="rounds to 0 there") as e:
            validate.step_advances(0.0, h, 2)
        assert ">= 0 " not in str(e.value)
    with pytest.raises(InputError, match="rounds to 0 there"):
        ldaspark.integrate("particle", "gauss-1", h="1e-99999999", n_steps=2)
    validate.step_advances(0.0, 1e-310, 2)
    with pytest.raises(InputError, match="30 digits"):
        validate.step_advances(1.0, "1e-99999999", 2, dps=30)


@pytest.mark.parametrize("where", ["h", "q0", "tol", "n_steps", "h at dps"])
def test_numbers_too_large_to_print_get_an_input_error(where):
    """An integer beyond 4300 digits (or a Fraction, sympy Integer or Rational holding one) as h,
    q0, tol or n_steps: the InputError's message called repr, which raises ValueError for such an
    integer, so the user got "ValueError: Exceeds the limit (4300 digits) for integer string
    conversion" (16 of 20 cases before). Controls: the message names the size; a Fraction h that
    mpmath can read at 30 digits runs (1/10^5000 is a step there)."""
    import sympy
    from fractions import Fraction
    import ldaspark
    big = [10 ** 5000, Fraction(1, 10 ** 5000), sympy.Integer(10) ** 5000, sympy.Rational(1, 10 ** 5000)]
    sc = ldaspark.get_scene("particle")
    for x in big:
        kw = dict(h=0.1, n_steps=2)
        q0 = [float(c) for c in sc.initial()[1]]
        if where == "q0":
            if isinstance(x, (Fraction, sympy.Rational)) and not isinstance(x, sympy.Integer):
                continue                      # a tiny coordinate is a valid one
            q0[0] = x
        elif where == "h at dps":
            kw.update(h=x, dps=30)
            if isinstance(x, (Fraction, sympy.Rational)) and not isinstance(x, sympy.Integer):
                r = ldaspark.integrate(sc, "gauss-1", q0=q0, v0=sc.initial()[2], **kw)
                assert r.status == 0 and r.stats["steps"] == 2 and r.t[-1] > 0
                continue
        else:
            kw[where] = x
        with pytest.raises(InputError, match="10\\^5000"):
            ldaspark.integrate(sc, "gauss-1", q0=q0, v0=sc.initial()[2], **kw)


def test_sympy_real_numbers_and_complex_tolerances():
    """h = pi/10 as a sympy number passed the number check and then failed the step count of the
    finished run with "TypeError: cannot create mpf from pi/10" (float64; at dps it ran); a
    complex tol (np.complex128(1e-10)) was accepted. Controls: the sympy h runs bit for bit as its
    float; a real tol of the same value is accepted."""
    import sympy
    import numpy as np
    import ldaspark
    r1 = ldaspark.integrate("particle", "gauss-1", h=sympy.pi / 10, n_steps=3)
    r2 = ldaspark.integrate("particle", "gauss-1", h=float(sympy.pi / 10), n_steps=3)
    assert r1.status == 0 and r1.stats["steps"] == 3 and np.array_equal(r1.q, r2.q)
    with pytest.raises(InputError, match="tolerance must be a finite positive number"):
        ldaspark.integrate("particle", "gauss-1", h=0.1, n_steps=2, tol=np.complex128(1e-10))
    assert ldaspark.integrate("particle", "gauss-1", h=0.1, n_steps=2, tol=np.float64(1e-10)).status == 0


def test_fmt_int_names_huge_integers_by_their_decimal_exponent():
    from ldaspark.core import validate
    assert validate._fmt_int(10 ** 30 - 1) == str(10 ** 30 - 1)
    assert validate._fmt_int(10 ** 30) == "about 10^30"
    assert validate._fmt_int(-(10 ** 40) + 1) == "-about 10^39"
    assert validate._fmt_int(10 ** 5000) == "about 10^5000"
    assert validate._fmt_int(2 ** 200) == "about 10^60"


def test_a_huge_integer_in_a_message_is_its_size():
    from ldaspark.core import validate
    for x in (10 ** 400, -(10 ** 5000)):
        with pytest.raises(InputError, match="about 10"):
            validate.check_dps(x)
    with pytest.raises(InputError, match="100000"):
        validate.check_dps(100000)


def test_real_number_refuses_an_mpmath_complex():
    with pytest.raises(InputError, match="must be a real number"):
        V.real_number(mpmath.mpc(1, 2), "h")
    with pytest.raises(InputError, match="must be a real number"):
        V.real_number(mpmath.mpc(1, 0), "h")


def test_real_number_decimal_string_zero_is_not_positive():
    with pytest.raises(InputError, match="must be positive"):
        V.real_number("0", "h", positive=True)
    with pytest.raises(InputError, match="must be positive"):
        V.real_number(" 0.000 ", "h", positive=True)
    assert V.real_number("1e-400", "h", positive=True) == "1e-400"


def test_describe_marks_a_cut_repr_with_dots():
    r61 = "a" * 59                              # repr: 61 characters, cut to 60
    assert V._describe(r61) == f"str '{'a' * 59}..."
    r60 = "a" * 58                              # repr: 60 characters, whole
    assert V._describe(r60) == f"str '{'a' * 58}'"
    with pytest.raises(InputError, match=r"\.\.\.$"):
        V.count(r61, "n_steps")


def test_count_bound_is_written_plainly_below_a_million():
    with pytest.raises(InputError, match=r"between 1 and 3, got 4$"):
        V.count(4, "stages", lo=1, hi=3)
    with pytest.raises(InputError, match=r"between 1 and 1e\+06, got 0$"):
        V.count(0, "n", lo=1, hi=10 ** 6)


def test_check_executor_returns_the_executor():
    with cf.ThreadPoolExecutor(1) as ex:
        assert V.check_executor(ex) is ex
    assert V.check_executor(None) is None


def test_step_advances_judges_the_spacing_at_the_end_of_the_run():
    # h = 1 advances t = 1, but not t = 2**53 + 1 reached after 2**53 steps
    V.step_advances(1.0, 1.0, n_steps=1)
    with pytest.raises(InputError, match="does not advance t"):
        V.step_advances(1.0, 1.0, n_steps=2 ** 53)


def test_step_advances_needs_two_spacings_in_float64():
    # t0 + h != t0, but h is one spacing only: t0 + 2h rounds (ties to even) onto t0 + h's neighbours
    assert 2.0 ** 52 + 1.0 != 2.0 ** 52
    with pytest.raises(InputError, match="does not advance t"):
        V.step_advances(2.0 ** 52, 1.0, n_steps=1)
    V.step_advances(2.0 ** 52, 2.0, n_steps=1)


def test_step_advances_in_digits_needs_two_units_of_the_last_digit():
    with pytest.raises(InputError, match="in 30 digits"):
        V.step_advances(1e30, 1.0, n_steps=1, dps=30)
    V.step_advances(1e30, 100.0, n_steps=1, dps=30)
