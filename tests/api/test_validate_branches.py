"""Branch coverage of ``ldaspark.core.validate``: each branch the mutation-mapped tests leave out,
taken by an input chosen for it, with the exact outcome (an ``InputError`` -- a subclass of
``LdasparkError`` -- and a distinctive part of its one-line message, or the value returned), and
where natural the valid neighbour that is accepted. Direct calls, no integration: the file runs
in about a second."""
import concurrent.futures
import decimal
import fractions
import os

import mpmath
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark.core import validate as V
from ldaspark.core.errors import InputError, LdasparkError


def _refused(match, f, *a, **kw):
    """f(*a, **kw) raises exactly InputError (an LdasparkError) with a one-line message matching."""
    with pytest.raises(InputError, match=match) as ei:
        f(*a, **kw)
    assert type(ei.value) is InputError and isinstance(ei.value, LdasparkError)
    assert "\n" not in str(ei.value)
    return str(ei.value)


# --- check_newton_options ---------------------------------------------------------------------

@pytest.mark.parametrize("tol", [np.True_, True])
def test_newton_tol_of_a_bool_type_is_refused(tol):
    # np.True_ was read as tol = 1.0 (only Python's bool was refused); real_number refuses both
    _refused("Newton tolerance must be a finite positive number", V.check_newton_options, tol, 10)
    _refused("max_iter must be an integer", V.check_newton_options, 1e-10, tol)


@pytest.mark.parametrize("tol", [object(), [1e-10], 10 ** 400])
def test_newton_tol_that_float_cannot_convert_is_refused(tol):
    # TypeError (object, list) and OverflowError (int beyond float64) inside the check: not ok
    _refused("Newton tolerance must be a finite positive number", V.check_newton_options, tol, 10)


def test_newton_tol_custom_name_and_valid_neighbours():
    _refused(r"^my tol must be a finite positive number, got 'x'$", V.check_newton_options, "x", 10, "my tol")
    assert V.check_newton_options(1e-12, 1) is None
    assert V.check_newton_options(None, V.MAX_NEWTON_ITER) is None
    assert V.check_newton_options(fractions.Fraction(1, 10 ** 12), np.int64(50)) is None


@pytest.mark.parametrize("max_iter", [True, 10.0, 0, V.MAX_NEWTON_ITER + 1, "10", None])
def test_newton_max_iter_refused(max_iter):
    msg = _refused("max_iter must be an integer between 1 and 1000000", V.check_newton_options, 1e-10, max_iter)
    assert msg.endswith(f"got {max_iter!r}")


# --- check_system_and_tableau -----------------------------------------------------------------

class _SysLike:
    n = m = 1

    def stage(self): ...
    def momentum(self): ...
    def energy(self): ...
    def saddle_matrix(self): ...


class _TabLike:
    arrays = ()
    s = 2


def test_system_without_the_attributes_is_refused():
    _refused("system must be a LagrangianSystem, got dict", V.check_system_and_tableau, {}, _TabLike())


@pytest.mark.parametrize("tab, name", [(object(), "object"), (type("T", (), {"arrays": (), "s": 2.0})(), "T"),
                                       (type("U", (), {"s": 2})(), "U")])
def test_tableau_without_arrays_or_int_s_is_refused(tab, name):
    _refused(f"tableau must be a SparkTableau .*got {name}$", V.check_system_and_tableau, _SysLike(), tab)


def test_duck_typed_system_and_tableau_pass():
    assert V.check_system_and_tableau(_SysLike(), _TabLike()) is None


def test_real_system_and_tableau_pass():
    sc = ldaspark.get_scene("pendulum") if hasattr(ldaspark, "get_scene") else None
    if sc is None:
        pytest.skip("no get_scene")
    from ldaspark.core.families import get_method
    assert V.check_system_and_tableau(sc.system, get_method("gauss-2")) is None


# --- physical_memory / check_storage ---------------------------------------------------------

def test_physical_memory_none_when_sysconf_fails(monkeypatch):
    for exc in (ValueError, OSError, AttributeError):
        def boom(name, exc=exc):
            raise exc(name)
        monkeypatch.setattr(V.os, "sysconf", boom)
        assert V.physical_memory() is None


def test_check_storage_falls_back_to_64_gib_without_physical_memory(monkeypatch):
    monkeypatch.setattr(V, "physical_memory", lambda: None)
    # 64 GiB / 40 bytes = 1717986918.4 floats: one more point of 1 float is too many
    V.check_storage(1717986918, 1)
    msg = _refused(r"storing the trajectory \(1\.72e\+09 points x 1 numbers\).*more than 64 GiB",
                   V.check_storage, 1717986919, 1)
    assert "use fewer steps" in msg
    _refused("storing ensemble", V.check_storage, 10 ** 9, 1, mp=True, what="ensemble")


# --- real_number: the number types -----------------------------------------------------------

def test_real_number_where_float_raises_counts_as_infinite():
    # Fraction beyond float64 (OverflowError) and a signalling Decimal NaN (ValueError)
    _refused(r"^h must be finite, got Fraction\(1000", V.real_number, fractions.Fraction(10 ** 400), "h")
    _refused(r"^h must be finite, got Decimal\('sNaN'\)", V.real_number, decimal.Decimal("sNaN"), "h")
    big = fractions.Fraction(10 ** 300)
    assert V.real_number(big, "h") is big


def test_real_number_mpf():
    x = mpmath.mpf("0.1")
    assert V.real_number(x, "h", positive=True) is x
    tiny = mpmath.mpf("1e-400")                  # 0.0 in float64, but not zero: positive and nonzero
    assert V.real_number(tiny, "h", positive=True, nonzero=True) is tiny
    _refused(r"^h must be finite, got mpf\('\+inf'\)", V.real_number, mpmath.mpf("inf"), "h")
    _refused("^h must be finite", V.real_number, mpmath.mpf("nan"), "h")
    _refused(r"^h must be positive, got mpf\('-0\.5'\)", V.real_number, mpmath.mpf("-0.5"), "h", positive=True)
    _refused("^h must be nonzero", V.real_number, mpmath.mpf(0), "h", nonzero=True)


def test_real_number_mpc_is_refused():
    _refused("^h must be a real number, got mpc", V.real_number, mpmath.mpc(1, 2), "h")


def test_real_number_sympy_whose_complex_raises():
    # UnevaluatedExpr(2).is_number but complex() raises TypeError: taken as complex("nan"), i.e.
    # a real NaN, refused as not finite
    _refused("^h must be finite, got 2$", V.real_number, sympy.UnevaluatedExpr(2), "h")
    assert V.real_number(sympy.Rational(1, 3), "h") == sympy.Rational(1, 3)
    _refused("^h must be a real number, got 1 \\+ I$", V.real_number, 1 + sympy.I, "h")


def test_real_number_sympy_symbolic_and_numpy_0d():
    _refused("^h must be a real number, got Symbol", V.real_number, sympy.Symbol("a"), "h")
    a = np.array(0.25)
    assert V.real_number(a, "h") is a
    _refused("^h must be a real number, got ndarray", V.real_number, np.array(1 + 2j), "h")


def test_real_number_string_zero_exponent_too_large_for_decimal():
    # float() takes "0e99999999999999999999" (0.0); Decimal refuses it (InvalidOperation), so
    # _nonzero says False: a zero, refused as h only when nonzero is asked for
    s = "0e99999999999999999999"
    assert V.real_number(s, "h") is s
    _refused("^h must be nonzero", V.real_number, s, "h", nonzero=True)
    assert V._nonzero(s) is False
    assert V._nonzero("1e-400") is True and V._nonzero("0.000") is False


def test_real_value():
    assert V.real_value(np.float32(0.5), "g") == 0.5 and type(V.real_value(np.float32(0.5), "g")) is float
    assert V.real_value(mpmath.mpf("0.25"), "g") == 0.25
    _refused("^g must be a real number, got bytes b'1'", V.real_value, b"1", "g")
    _refused("^g must be a real number, got str '1'", V.real_value, "1", "g")


# --- count / dps / choice ---------------------------------------------------------------------

def test_count_bounds_format():
    # the size of an integer beyond 10^30 is given from its bit length (floor of a lower bound:
    # 10**99 reads "about 10^98")
    _refused(r"between 1 and 1e\+09, got about 10\^9[89]$", V.count, 10 ** 99, "n_steps")
    _refused(r"between 2 and 7, got -about 10\^40$", V.count, -2 * 10 ** 40, "jobs", 2, 7)
    assert V.count(np.int16(7), "jobs", 2, 7) == 7


# --- check_executor ---------------------------------------------------------------------------

def test_executor_class_instead_of_instance():
    _refused(r"got the class ThreadPoolExecutor \(create one: ThreadPoolExecutor\(\.\.\.\)\)$",
             V.check_executor, concurrent.futures.ThreadPoolExecutor)
    with concurrent.futures.ThreadPoolExecutor(1) as ex:
        assert V.check_executor(ex) is ex
    assert V.check_executor(None) is None


def test_executor_shut_down_message():
    err = V.executor_shut_down(RuntimeError("cannot schedule\nnew futures  after shutdown"))
    assert isinstance(err, InputError)
    assert str(err) == "the executor refused new work (RuntimeError: cannot schedule new futures after shutdown)"


# --- real_vector / param_value ----------------------------------------------------------------

class _NoArray:
    def __array__(self, *a, **kw):
        raise TypeError("no array")


def test_real_vector_that_numpy_cannot_convert():
    _refused("^q0 must be a list of numbers \\(rows of equal length\\), got _NoArray", V.real_vector, _NoArray(), "q0")


def test_real_vector_entry_names():
    _refused(r"^q0\[1\] must be a real number", V.real_vector, [1, "x"], "q0")
    _refused(r"^q0 entry 3 must be finite", V.real_vector, [[1, 2], [3, float("inf")]], "q0")
    v = ["0.1", mpmath.mpf(2)]
    assert V.real_vector(v, "q0") is v


def test_param_value_strings_are_left_to_the_parser():
    assert V.param_value("g", "9.81 + x") == "9.81 + x"      # not parsed here
    assert V.param_value("g", 9.81) == 9.81
    _refused("^parameter g must be finite", V.param_value, "g", float("nan"))


def test_param_value_through_integrate_params():
    # the public path: integrate(..., params={...}) refuses a bool value before any work
    _refused("parameter", ldaspark.integrate, "pendulum", "gauss-2", h=0.1, n_steps=1, params={"g": True})


# --- times (dense output) ---------------------------------------------------------------------

@pytest.mark.parametrize("t", [True, None, "1.0", b"1", np.bool_(False)])
def test_times_refuses_bool_none_strings(t):
    _refused("^t must be a real number or a 1-D array of them", V.times, t)


def test_times_ragged_is_refused():
    _refused("^t must be a real number or a 1-D array of them, got list", V.times, [[0.0, 1.0], [2.0]])


def test_times_object_entries():
    a = V.times([mpmath.mpf("0.5"), fractions.Fraction(1, 4), decimal.Decimal("0.125"), sympy.Rational(1, 8)])
    assert a.dtype == float and a.tolist() == [0.5, 0.25, 0.125, 0.125]
    s = V.times(mpmath.mpf("0.5"))                          # 0-d object array keeps its shape
    assert s.shape == () and float(s) == 0.5
    _refused("^t must be a real number or a 1-D array of them", V.times, [fractions.Fraction(1, 2), "2"])
    _refused("^when must be finite, got mpf", V.times, [mpmath.mpf(1), mpmath.mpf("inf")], "when")


def test_times_complex_2d_and_nonfinite():
    _refused("^t must be a real number or a 1-D array of them, got complex", V.times, 1j)
    _refused("^t must be a real number or a 1-D array of them, got list", V.times, [[0.0, 1.0], [2.0, 3.0]])
    _refused("^t must be finite, got NaN or infinity$", V.times, [0.0, float("nan")])
    a = V.times(np.arange(3, dtype=np.int32))
    assert a.dtype == float and a.tolist() == [0.0, 1.0, 2.0]


def test_times_through_dense_output():
    # the public path: a dense output's sol(t) checks t with times() (HermiteDense on two steps)
    from ldaspark.core.dense import HermiteDense
    sol = HermiteDense(np.array([0.0, 0.5, 1.0]), np.array([[0.0], [0.5], [1.0]]), np.ones((3, 1)))
    q, v = sol(mpmath.mpf("0.25"))
    assert np.allclose(np.ravel(q), 0.25) and np.allclose(np.ravel(v), 1.0)
    _refused("^t must be a real number or a 1-D array of them, got str", sol, "0.25")
    _refused("^t must be finite", sol, [0.25, float("nan")])


# --- regular_file -----------------------------------------------------------------------------

def test_regular_file_path_types(tmp_path):
    _refused("^a result file path must be a string or os.PathLike, got int", V.regular_file, 3, 10, "result file")
    _refused("^a file path must be a string or os.PathLike, got bool", V.regular_file, True, 10)
    _refused("^a file path must not contain a NUL character$", V.regular_file, "a\0b", 10)
    _refused("^a file path must not contain a NUL character$", V.regular_file, b"a\0b", 10)


def test_regular_file_missing_unreadable_directory_large(tmp_path):
    f = tmp_path / "r.json"
    f.write_bytes(b"x" * 10)
    _refused("^no such file: ", V.regular_file, tmp_path / "nope.json", 100)
    _refused("^cannot read file .*r.json/sub", V.regular_file, str(f / "sub"), 100)   # NotADirectoryError
    _refused("is not a regular file$", V.regular_file, tmp_path, 100)
    _refused(r"has 10 bytes, more than 9$", V.regular_file, f, 9)
    assert V.regular_file(f, 10) == 10
    assert V.regular_file(os.fsencode(f), 10) == 10


def test_regular_file_through_load_result(tmp_path):
    _refused("is not a regular file", ldaspark.load_result, str(tmp_path))
    _refused("no such result file", ldaspark.load_result, str(tmp_path / "none.json"))


# --- point ------------------------------------------------------------------------------------

class _N2:
    n = 2


def test_point_needs_q0_and_v0_without_a_scene():
    _refused(r"^flow: give q0 and v0 \(or a Scene", V.point, _N2(), 0, None, [0, 0], "flow: ")
    _refused(r"^give q0 and v0", V.point, _N2(), 0, [0, 0], None)


def test_point_lengths_and_dimensions():
    _refused(r"^v0 must have n = 2 entries, got list \[1, 2, 3\]$", V.point, _N2(), 0, [0, 0], [1, 2, 3])
    _refused(r"^q0 must have n = 2 entries", V.point, _N2(), 0, [[0, 0], [1, 1]], [1, 2])
    assert V.point(_N2(), "0.5", [0, 1], ["1", 2]) == ("0.5", [0, 1], ["1", 2])


# --- index_list / callable_or_none / flag -----------------------------------------------------

@pytest.mark.parametrize("x", ["01", b"01", {0: 1}, 5, None])
def test_index_list_not_a_list(x):
    _refused("^sel must be a list of indices", V.index_list, x, 4, "sel")


def test_index_list_entries():
    _refused("^sel: indices must be integers, got float 1.0$", V.index_list, [0, 1.0], 4, "sel")
    _refused("^sel: indices must be integers, got bool True$", V.index_list, [True], 4, "sel")
    _refused(r"^sel: index 4 out of range 0\.\.3$", V.index_list, [4], 4, "sel")
    _refused(r"^sel: index -1 out of range 0\.\.3$", V.index_list, [-1], 4, "sel")
    _refused(r"^sel lists the same index twice: \[1, 1\]$", V.index_list, (1, np.int64(1)), 4, "sel")
    assert V.index_list([1, 1], 4, "sel", unique=False) == [1, 1]
    out = V.index_list(np.array([3, 0]), 4, "sel")
    assert out == [3, 0] and all(type(i) is int for i in out)
    assert V.index_list([], 4, "sel") == []


def test_callable_or_none():
    _refused("^progress must be callable \\(or None\\), got int 3$", V.callable_or_none, 3, "progress")
    assert V.callable_or_none(None, "progress") is None
    assert V.callable_or_none(print, "progress") is print


@pytest.mark.parametrize("x", [1, 0, "yes", None])
def test_flag_refuses_non_bools(x):
    _refused("^compensated must be True or False", V.flag, x, "compensated")


def test_flag_accepts_bools():
    assert V.flag(True, "c") is True
    assert V.flag(np.bool_(False), "c") is False


# --- _rational_string -------------------------------------------------------------------------

def test_rational_string():
    assert V._rational_string(" -3 / 12 ") == fractions.Fraction(-1, 4)
    assert V._rational_string("1/0") is None
    assert V._rational_string("0.1") is None
    assert V._rational_string(0.1) is None
    assert V._rational_string("1/" + "1" * V.MAX_NUMBER_CHARS) is None          # too long
    # within MAX_NUMBER_CHARS but beyond int()'s 4300-digit limit: ValueError, None
    assert V._rational_string("1" * 4500 + "/3") is None


@pytest.mark.parametrize("x, text", [(10 ** 99, "about 10^99"), (10 ** 99 - 1, "about 10^98"),
                                     (-10 ** 30, "-about 10^30"), (10 ** 30 - 1, str(10 ** 30 - 1)),
                                     (2 ** 1000, "about 10^301"), (10 ** 5000 + 7, "about 10^5000")],
                         ids=["1e99", "1e99-1", "-1e30", "1e30-1", "2^1000", "1e5000+7"])
def test_a_huge_integer_is_named_by_its_power_of_ten(x, text):
    """floor(log10 |x|): an exact power of ten is that power (the bit-length estimate alone
    names 10^99 as 10^98)."""
    from ldaspark.core.validate import _fmt_int
    assert _fmt_int(x) == text
