"""Hostile tableau files, entries and method names end within seconds with one TableauError
line (exit 2 at the command line): bounded entry size, nesting depth, nested exponents,
scientific exponents, magnitude, file size (regular files only) and stages (s <= 20 unless
raised). Controls: legitimate entries and a raised --max-stages still work."""
import json
import os

import pytest
import sympy

from ldaspark.core.errors import TableauError
from ldaspark.core.families import get_method
from ldaspark.core.numbers import _parse_entry, parse_exact_string
from ldaspark.core.tableau_file import from_json_dict, load_tableau

from run_helpers import assert_ok_or_one_line, run_cli, time_bound

HOSTILE = [
    ("1e-9999999", "scientific notation"),
    ("1e+401", "scientific notation"),
    ("((((9**64)**64)**64)**64)**64", "exponents multiplying"),
    ("sin((((9**64)**64)**64)**64)", "exponents multiplying"),
    ("(9**8)**9", "exponents multiplying"),
    ("sin(10**7)", "argument of sin"),
    ("cos(1e300)", "argument of cos"),
    ("-" * 60 + "1", "nested deeper"),
    ("sqrt(" * 33 + "2" + ")" * 33, "nested deeper"),
    ("9" * 201, "longer than 200"),
    ("sqrt(-1)*10**-64*10**-64", "not a real number"),
    ("10**64*10**64*10**64*10**64*10**64", "exceeds 1e\\+300"),
    ("1/(1-1)", "division by zero"),
    ("__import__('os')", "unknown name"),
]


@pytest.mark.parametrize("text, why", HOSTILE)
def test_hostile_entry_is_one_error_within_seconds(text, why):
    with time_bound(20), pytest.raises(TableauError, match=why):
        _parse_entry(text, "A[0][0]")


@pytest.mark.parametrize("text, value", [
    ("1/4 - sqrt(3)/6", sympy.Rational(1, 4) - sympy.sqrt(3) / 6), ("1e-30", sympy.Rational(1, 10 ** 30)),
    ("(9**8)**8", sympy.Integer(9) ** 64), ("sqrt(2)**64", sympy.Integer(2) ** 32),
    ("cos(pi/7)", sympy.cos(sympy.pi / 7)), ("1e300", sympy.Integer(10) ** 300), ("-(-(-1))", -1),
])
def test_legitimate_entries_near_the_bounds_still_parse(text, value):
    assert sympy.simplify(parse_exact_string(text) - value) == 0


def test_4000_digit_integer_is_an_error_not_inf():
    with pytest.raises(TableauError, match="digits exceeds"):
        _parse_entry(10 ** 4000, "c[0]")
    assert _parse_entry(10 ** 299, "c[0]")[0] == 10 ** 299              # control


def _tab(s):
    z = [[0] * s for _ in range(s)]
    return {"c": [0] * s, "A": z, "A_hat": z, "A_tilde": z, "b": [1] * s, "b_hat": [1] * s, "b_tilde": [1] * s}


def test_stage_count_is_bounded_unless_raised(tmp_path):
    with time_bound(20), pytest.raises(TableauError, match="s = 1800 stages, more than the limit 20"):
        from_json_dict({"c": [0] * 1800, "A": [], "A_hat": [], "A_tilde": [], "b": [], "b_hat": [], "b_tilde": []})
    with pytest.raises(TableauError, match="s = 21 stages"):
        get_method("gauss-21")
    assert get_method("gauss-21", max_stages=21).s == 21                 # raised: accepted (lazy)
    p = tmp_path / "t21.json"
    p.write_text(json.dumps(_tab(21)))
    with pytest.raises(TableauError, match="s = 21"):
        load_tableau(p)
    with pytest.raises(TableauError, match="omega is singular"):         # gets past the bound
        load_tableau(p, max_stages=21)


@pytest.mark.parametrize("name, match", [
    ("gauss-100", "s = 100 stages"), ("gauss-99999999999999999999", "20 digits, beyond the stage limit"),
    ("gauss-²", "unknown method"), ("lobatto-iiia-iiib-٣", "unknown method"), ("gauss-", "unknown method"),
])
def test_method_names(name, match):
    with time_bound(20), pytest.raises(TableauError, match=match):
        get_method(name)


def test_large_file_is_refused_before_reading(tmp_path):
    p = tmp_path / "big.json"
    with open(p, "wb") as f:
        f.truncate(26 * 2 ** 20)                 # 26 MB (sparse): refused by its size
    with time_bound(20), pytest.raises(TableauError, match="bytes, more than"):
        load_tableau(p)


@pytest.mark.parametrize("argv_tail, match", [
    (["/dev/zero"], "not a regular file"),
    (["."], "not a regular file"),
    (["--method", "gauss-²"], "unknown method"),
    (["--method", "gauss-100"], "s = 100 stages"),
])
def test_audit_special_files_and_names_one_line(argv_tail, match):
    rc, err = run_cli(["audit", *argv_tail], seconds=30)
    assert_ok_or_one_line(rc, err)
    assert rc == 2 and match in err


@pytest.mark.parametrize("content, match", [
    ("[" * 100000, "nested too deeply"),
    ('{"c": [' + "9" * 5000 + "]}", "not valid JSON: an integer literal has too many digits"),
    ('{"c": [1], "A": [["sqrt(-1)*10**-64*10**-64"]], "A_hat": [[1]], "A_tilde": [[1]], "b": [1], "b_hat": [1], '
     '"b_tilde": [1]}', "not a real number"),
    ('{"c": [1], "A": [["1e-9999999"]], "A_hat": [[1]], "A_tilde": [[1]], "b": [1], "b_hat": [1], "b_tilde": [1]}',
     "scientific notation"),
    (b"\xff\xfe{", "cannot read"),
])
def test_audit_hostile_files_one_line(tmp_path, content, match):
    p = tmp_path / "t.json"
    (p.write_bytes if isinstance(content, bytes) else p.write_text)(content)
    rc, err = run_cli(["audit", str(p)], seconds=30)
    assert_ok_or_one_line(rc, err)
    assert rc == 2 and match in err


@pytest.mark.parametrize("t_end", ["nan", "inf", "-inf", "1e300", "0"])
def test_report_energy_fig4_bad_t_end_one_line(t_end):
    rc, err = run_cli(["report", "energy", "--figure", "4", "--t-end", t_end], seconds=60)
    assert_ok_or_one_line(rc, err)
    assert rc == 2


def test_huge_step_prints_one_line_and_no_runtime_warning(tmp_path):
    import warnings
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        rc, err = run_cli(["integrate", "skate", "gauss-2", "--h", "1e200", "--t-end", "1e200",
                           "--out", str(tmp_path / "o.json")])
    assert rc == 2 and err.count("\n") == 1 and not [x for x in w if issubclass(x.category, RuntimeWarning)]
    assert not os.path.exists(tmp_path / "o.json")


def test_ctrl_c_in_a_lazy_import_is_one_line(monkeypatch):
    # Ctrl-C while a command's module imports: one line, exit 130 (also when an extension module's
    # import turns the KeyboardInterrupt into an ImportError, as numpy's does)
    import importlib
    import signal
    real = importlib.import_module

    def interrupted(name, *a, **k):
        if name == "ldaspark.lab.theory.audit":
            try:
                signal.raise_signal(signal.SIGINT)
            except KeyboardInterrupt:
                raise ImportError("PyCapsule_Import could not import module") from None
        return real(name, *a, **k)
    monkeypatch.setattr(importlib, "import_module", interrupted)
    # SIGINT may be inherited as ignored (a shell's background job): install Python's handler
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        rc, err = run_cli(["audit", "--method", "gauss-1"])
    finally:
        signal.signal(signal.SIGINT, old)
    assert rc == 130 and err == "ldaspark: interrupted\n"


def test_import_error_without_ctrl_c_is_not_hidden(monkeypatch):
    # negative control: a genuine ImportError is not mistaken for an interrupt
    import importlib
    real = importlib.import_module

    def broken(name, *a, **k):
        if name == "ldaspark.lab.theory.audit":
            raise ImportError("genuinely missing")
        return real(name, *a, **k)
    monkeypatch.setattr(importlib, "import_module", broken)
    with pytest.raises(ImportError, match="genuinely missing"):
        run_cli(["audit", "--method", "gauss-1"])
