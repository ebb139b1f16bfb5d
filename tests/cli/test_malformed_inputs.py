"""Property tests: each public CLI command this module covers (integrate, methods, audit) and the
result-file reader and writer, fed malformed neighbours of each of their inputs, end in one
LdasparkError (the CLI: one line on stderr, exit 2), never another exception or a traceback
(docs/reliability.md "Every bad input ends in one LdasparkError"). Hypothesis, ``ci`` profile."""
import contextlib
import io
import json
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ldaspark
from ldaspark.cli import main
from ldaspark.core.errors import LdasparkError

_SETTINGS = settings(suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

# neighbours of a JSON value: the wrong type, booleans, huge and deep values, strings of numbers
LEAVES = st.one_of(st.booleans(), st.none(), st.integers(min_value=-10 ** 400, max_value=10 ** 400),
                   st.floats(allow_nan=False, allow_infinity=False), st.text(max_size=8),
                   st.sampled_from(["nan", "1e999", "0x10", "\u0663", "", "1/2", "-0"]),
                   st.just([]), st.just({}), st.just([[1.0, 2.0], [3.0]]), st.just({"a": [True]}))


@pytest.fixture(scope="module")
def result():
    return ldaspark.integrate("particle", "gauss-1", t_span=(0, 1), h=0.5, engine="generic")


@pytest.fixture(scope="module")
def valid_json(result, tmp_path_factory):
    p = tmp_path_factory.mktemp("v") / "r.json"
    ldaspark.save_result(result, p)
    return json.loads(p.read_text())


def _paths(x, prefix=()):
    yield prefix
    if isinstance(x, dict):
        for k, v in x.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(x, list):
        for i, v in enumerate(x[:3]):
            yield from _paths(v, prefix + (i,))


def _set(x, path, value):
    if not path:
        return value
    x[path[0]] = _set(x[path[0]], path[1:], value)
    return x


def _loads_or_refuses(path):
    try:
        res = ldaspark.load_result(path)
    except LdasparkError as exc:
        assert len(str(exc).splitlines()) == 1, str(exc)
        return None
    assert all(np.all(np.isfinite(np.asarray(getattr(res, k), dtype=float))) for k in ("t", "q", "v")) \
        if res.dps is None else True
    return res


@_SETTINGS
@given(data=st.data())
def test_the_reader_on_a_json_result_with_one_value_replaced(tmp_path, valid_json, data):
    paths = list(_paths(valid_json))
    where = data.draw(st.sampled_from(paths))
    value = data.draw(LEAVES)
    d = _set(json.loads(json.dumps(valid_json)), where, value)
    p = tmp_path / "m.json"
    try:
        p.write_text(json.dumps(d))
    except ValueError:              # an integer of more than 4300 digits: not JSON Python writes
        return
    res = _loads_or_refuses(p)
    if isinstance(value, bool) and where and where[0] in ("t", "q", "v", "energy", "constraint") and len(where) > 1:
        assert res is None          # a boolean where a number belongs is never read as 1.0 / 0.0


@_SETTINGS
@given(cut=st.floats(0, 1), junk=st.sampled_from([b"", b"\xff", b"\xc3\x28", b"\x00", b"[" * 100000, b"]"]),
       ext=st.sampled_from([".json", ".npz", ".h5"]))
def test_the_reader_on_truncated_and_corrupted_bytes(tmp_path, result, cut, junk, ext):
    good = tmp_path / f"good{ext}"
    ldaspark.save_result(result, good)
    raw = good.read_bytes()
    bad = tmp_path / f"bad{ext}"
    k = int(cut * len(raw))
    bad.write_bytes(raw[:k] + junk + raw[k + len(junk):] if ext == ".json" else raw[:k] + junk)
    _loads_or_refuses(bad)


def test_the_reader_on_deep_nesting_and_invalid_utf8(tmp_path):
    for raw in (b"[" * 100000 + b"]" * 100000, b'{"t": ' + b"[" * 100000 + b"]" * 100000 + b"}", b"\xff\xfe{}",
                b'{"t": [1.0], "scene": "\xc3\x28"}'):
        p = tmp_path / "x.json"
        p.write_bytes(raw)
        with pytest.raises(LdasparkError):
            ldaspark.load_result(p)


@_SETTINGS
@given(attr=st.sampled_from(["h", "dps", "message", "scene", "params", "stats", "save_every"]), value=LEAVES,
       ext=st.sampled_from([".json", ".npz", ".h5"]))
def test_the_writer_on_a_result_with_one_attribute_replaced(tmp_path, result, attr, value, ext):
    import copy
    res = copy.copy(result)
    setattr(res, attr, value)
    p = tmp_path / f"w{ext}"
    try:
        ldaspark.save_result(res, p)
    except LdasparkError as exc:
        assert len(str(exc).splitlines()) == 1
        return
    _loads_or_refuses(p)            # what was written is read back or refused, never a traceback


def test_a_400_digit_integer_step_is_written_and_read_back(tmp_path, result):
    import copy
    res = copy.copy(result)
    res.h = 10 ** 400
    for ext in (".json", ".npz", ".h5"):
        ldaspark.save_result(res, tmp_path / f"h{ext}")
        assert ldaspark.load_result(tmp_path / f"h{ext}").h == 10 ** 400


def _cli(argv):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main(argv)
        except SystemExit as exc:           # argparse's own usage errors
            rc = exc.code
    return rc, err.getvalue()


def _one_error(rc, err):
    assert rc in (0, 2), (rc, err)
    if rc == 2:
        lines = err.splitlines()
        assert len(lines) == 1 and lines[0].startswith("ldaspark: error:"), err


NUMBERS = st.sampled_from(["0.5", "0", "-0.5", "nan", "inf", "1e999", "", "abc", "0x1", "\u0661", "1e-300", "True",
                           " 0.5 ", "5e-324", "1/2", "9" * 5000])
COUNTS = st.sampled_from(["1", "0", "-1", "1.5", "abc", "", "99999999999999999999", "\u0661", "True"])


@_SETTINGS
@given(h=NUMBERS, t_end=st.sampled_from(["1", "nan", "-1", "1e999", "x"]),
       dps=st.sampled_from([None, "15", "16", "2001", "-1", "1e3", "abc", "99999999999999999999"]),
       every=st.sampled_from([None, "1", "0", "-1", "1.5", "x"]))
def test_cli_integrate_on_malformed_numbers(tmp_path, h, t_end, dps, every):
    argv = ["integrate", "particle", "gauss-1", "--engine", "generic", "--h", h, "--t-end", t_end,
            "--out", str(tmp_path / "o.json")]
    argv += ["--dps", dps] if dps is not None else []
    argv += ["--every", every] if every is not None else []
    _one_error(*_cli(argv))


TABLEAUX = st.sampled_from([b"", b"\xff\xfe", b"[" * 100000 + b"]" * 100000, b"[]", b"null", b'{"c": [true]}',
                            b'{"name": "m", "c": [true], "A": [["1/2"]], "A_hat": [["1/2"]], "A_tilde": [["1/2"]], '
                            b'"b": ["1"], "b_hat": ["1"], "b_tilde": ["1"]}', b'{"c": 1e999}', b"{" * 50,
                            b'{"name": "m", "c": ["1/2"], "A": [["__import__(\'os\')"]], "A_hat": [["1/2"]], '
                            b'"A_tilde": [["1/2"]], "b": ["1"], "b_hat": ["1"], "b_tilde": ["1"]}'])


@_SETTINGS
@given(content=TABLEAUX, command=st.sampled_from(["integrate", "audit"]))
def test_cli_integrate_and_audit_on_malformed_tableau_files(tmp_path, content, command):
    p = tmp_path / "t.json"
    p.write_bytes(content)
    argv = (["integrate", "particle", "custom", "--tableau", str(p), "--h", "0.5", "--t-end", "1",
             "--out", str(tmp_path / "o.json")] if command == "integrate" else ["audit", str(p), "--quick"])
    rc, err = _cli(argv)
    assert rc == 2
    _one_error(rc, err)


@_SETTINGS
@given(max_s=st.sampled_from(["0", "6", "-1", "x", "", "1"]),     # "1": a valid one, cheap (s = 1 rows)
       target=st.sampled_from([None, "dir", "/dev/full", "missing/dir/x.json", "ok.json"]))
def test_cli_methods_on_malformed_options_and_targets(tmp_path, max_s, target):
    argv = ["methods", "--max-s", max_s]
    if target is not None:
        (tmp_path / "dir").mkdir(exist_ok=True)
        argv += ["--json", target if target.startswith("/") else str(tmp_path / target)]
    _one_error(*_cli(argv))


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_methods_to_a_full_stdout_is_one_line_exit_2():
    import subprocess
    import sys
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    with open("/dev/full", "w") as full:
        p = subprocess.run([sys.executable, "-m", "ldaspark", "methods", "--max-s", "1"], stdout=full, stderr=subprocess.PIPE,
                           env=dict(os.environ, PYTHONPATH=root), timeout=120, text=True)
    assert p.returncode == 2 and p.stderr.splitlines() == ["ldaspark: error: cannot write the output: No space "
                                                           "left on device"], p.stderr
