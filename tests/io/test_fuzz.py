"""Property-based fuzzing (hypothesis, derandomized 'ci' profile): the tableau parser and the
command line's argument handling. Whatever the input, the answer comes within seconds and is
either a result (rc 0) or one line and rc 2, never a traceback or a hang. Each example runs
under a time bound that turns a hang into a failure. Cost in the default run: ~20 s."""
import json
import math
import os
import subprocess
import sys

import pytest
import sympy
from hypothesis import given, settings, strategies as st

from ldaspark.core.errors import TableauError
from ldaspark.core.numbers import MAX_MAGNITUDE, _parse_entry
from ldaspark.core.tableau_file import from_json_dict

from run_helpers import assert_ok_or_one_line, run_cli, time_bound

# --- the tableau parser --------------------------------------------------------------------------
ATOMS = ["0", "1", "2", "9", "64", "1.5", "1e-9999999", "1e400", "5e-324", "0x10", "1_0", "pi", "sqrt(2)",
         "sqrt(-1)", "sin(1)", "Rational(1, 3)", "Rational(1, 0)", "x", "__import__", "1j", "True", "'a'",
         "9" * 40]


def _expr():
    base = st.sampled_from(ATOMS)
    ops = ["+", "-", "*", "/", "**", "//", "%", "**-"]
    return st.recursive(base, lambda inner: st.one_of(
        st.builds(lambda a, o, b: f"({a}){o}{b}", inner, st.sampled_from(ops), inner),
        st.builds(lambda f, a: f"{f}({a})", st.sampled_from(["sqrt", "sin", "cos", "Rational", "exp", "abs"]), inner),
        st.builds(lambda a: f"-{a}", inner)), max_leaves=12)


def _check_entry(text):
    with time_bound(10):
        try:
            e, exact = _parse_entry(text, "A[0][0]")
        except TableauError as exc:
            assert str(exc).startswith("A[0][0]") and "\n" not in str(exc)
            return
        val = complex(sympy.N(e, 20))
    assert val.imag == 0 or abs(val.imag) <= 1e-25 * (1 + abs(val.real))
    assert math.isfinite(val.real) and abs(val.real) <= MAX_MAGNITUDE


@settings(max_examples=150)
@given(_expr())
def test_structured_expressions_parse_or_one_error(text):
    _check_entry(text)


@settings(max_examples=150)
@given(st.text(alphabet="0123456789.eE+-*/()_ ,sqrtincopRal²٣", max_size=60))
def test_arbitrary_text_parses_or_one_error(text):
    _check_entry(text)


_json = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-10 ** 400, 10 ** 400),
                               st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12)),
                     lambda inner: st.lists(inner, max_size=4), max_leaves=20)


@settings(max_examples=60)
@given(st.fixed_dictionaries({k: _json for k in ("c", "A", "A_hat", "A_tilde", "b", "b_hat", "b_tilde")}))
def test_arbitrary_json_tableau_loads_or_one_error(d):
    with time_bound(10):
        try:
            tab = from_json_dict(d)
        except TableauError as exc:
            assert "\n" not in str(exc)
            return
    assert 1 <= tab.s <= 20


# --- the command line ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    hostile = {"deep.json": "[" * 100000, "bigint.json": '{"c": [' + "9" * 5000 + "]}", "empty.json": "",
               "notjson.json": "{c: 1}",
               "huge_s.json": json.dumps({k: [0] * 30 for k in ("c", "b", "b_hat", "b_tilde")} | {"A": [], "A_hat": [], "A_tilde": []}),
               "euler.json": json.dumps({"c": [0], "A": [[0]], "A_hat": [[1]], "A_tilde": [[1]], "b": [1], "b_hat": [1],
                                         "b_tilde": [1]}),
               "imag.json": json.dumps({"c": [0], "A": [["sqrt(-1)*10**-64*10**-64"]], "A_hat": [[1]],
                                        "A_tilde": [[1]], "b": [1], "b_hat": [1], "b_tilde": [1]})}
    for name, text in hostile.items():
        (d / name).write_text(text)
    (d / "adir").mkdir()
    return d


def _integrate_argv(f):
    return st.tuples(
        st.sampled_from(["skate", "particle", "robot", "nonsense", "", "²"]),
        st.sampled_from(["gauss-1", "euler-i", "lobatto-iiia-iiib-2", "gauss-²", "gauss-100", "gauss-0", "custom", "x"]),
        st.sampled_from(["0.5", "0.25", "1", "nan", "inf", "-0.5", "0", "1e200", "1e-300", "x", "²", "0x1", ""]),
        st.sampled_from(["1", "0.5", "nan", "1e300", "-1", "", "1e-320"]),
        st.sampled_from(["o.json", "/dev/null", "adir", "sub/o.json"]),
        st.sampled_from([[], ["--dps", "20"], ["--dps", "4"], ["--dps", "x"], ["--dps", "-1"]]),
        st.sampled_from([[], ["--tableau", "euler.json"], ["--tableau", "deep.json"], ["--tableau", "/dev/zero"],
                         ["--tableau", "adir"], ["--tableau", "huge_s.json"], ["--tableau", "imag.json"]]),
        st.sampled_from([[], ["--max-stages", "0"], ["--max-stages", "x"], ["--max-stages", "25"], ["--project"],
                         ["--newton", "simplified"], ["--newton", "x"], ["--bogus"]]),
    ).map(lambda t: ["integrate", t[0], t[1], "--h", t[2], "--t-end", t[3], "--out", str(f / t[4]),
                     *t[5], *[str(f / a) if a.endswith(".json") or a == "adir" else a for a in t[6]], *t[7]])


def _other_argv(f):
    return st.one_of(
        st.sampled_from([[], ["--version"], ["--bogus"], ["nonsense"], ["integrate"], ["methods", "--max-s", "x"],
                         ["methods", "--max-s", "100"], ["methods", "--max-s", "-1"], ["methods", "--max-s", "1"],
                         ["audit"], ["audit", "--method", "gauss-²"], ["audit", "--method", "gauss-99999999999999"],
                         ["audit", "--dps", "5", "--method", "gauss-1"], ["report", "nonsense"]]),
        st.builds(lambda n: ["audit", str(f / n)], st.sampled_from(["deep.json", "bigint.json", "empty.json",
                                                                    "notjson.json", "huge_s.json", "imag.json",
                                                                    "adir", "missing.json"])),
        st.builds(lambda t: ["report", "energy", "--figure", "4", "--t-end", t],
                  st.sampled_from(["nan", "inf", "1e300", "-1", "0", "x"])),
    )


OUTCOMES = []


@settings(max_examples=30)
@given(st.data())
def test_any_command_line_is_rc0_or_one_line_rc2(files, data):
    argv = data.draw(st.one_of(_integrate_argv(files), _other_argv(files)))
    rc, err = run_cli(argv, seconds=60)
    assert_ok_or_one_line(rc, err, argv)
    OUTCOMES.append((rc, argv[0] if argv else ""))


def test_the_fuzzing_reached_successes_and_errors():
    # the property above is not vacuous: it saw successful runs and user errors
    if not OUTCOMES:
        pytest.skip("run together with test_any_command_line_is_rc0_or_one_line_rc2")
    rcs = {rc for rc, _ in OUTCOMES}
    assert {0, 2} <= rcs, OUTCOMES


@pytest.mark.parametrize("argv", [
    ["audit", "/dev/zero"],
    ["integrate", "skate", "gauss-²", "--h", "0.1", "--t-end", "1", "--out", "o.json"],
    ["integrate", "skate", "gauss-2", "--h", "1e200", "--t-end", "1e200", "--out", "o.json"],
])
def test_real_process_one_line_rc2(tmp_path, argv):
    # the real entry point: what the user's terminal shows, warnings included
    r = subprocess.run([sys.executable, "-m", "ldaspark", *argv], capture_output=True, text=True, timeout=120,
                       cwd=tmp_path, env=dict(os.environ, PYTHONPATH=os.getcwd()))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and r.stderr.startswith("ldaspark: error:"), r.stderr
