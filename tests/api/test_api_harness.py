"""The property harness of the public surface: every name in ``ldaspark.__all__`` and every
numeric option of the CLI, driven one argument at a time with wrong types, shapes and values.

For each exported callable a valid baseline call is given (cheap: the skate, one step); the
harness replaces one argument of it by a drawn value (None, bool, str, bytes, complex, NaN,
inf, negative, 0, huge integers, nested lists, dicts, classes) and asserts that the call
either returns a correct result (finite numbers) or raises an LdasparkError whose message is
one line, never another exception, within a time bound (SIGALRM in the main thread). The
default budget is a few examples per argument; ``exhaustive`` runs many more.
"""
from __future__ import annotations

import concurrent.futures as cf
import math
import os
import signal
import threading

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ldaspark
from ldaspark import LdasparkError

TIME_BOUND = 60          # seconds per call (generous: a refusal takes milliseconds; kernels are
                         # compiled by the module fixture, outside the bound)


#: the checkout (the module runs in a directory of its own: ``_result_file``)
_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


# --- the drawn wrong values ------------------------------------------------------------------
class _Cls:               # a class where a value is expected
    pass


_SCALARS = st.one_of(
    st.sampled_from([None, True, False, "", "abc", "1e400", "nan", b"1", b"", 1j, 1 + 2j, float("nan"),
                     float("inf"), -float("inf"), 0, -1, -3, 0.0, -0.5, 2.5, 10 ** 30, -10 ** 30, 2 ** 64,
                     np.int64(3), np.float64("nan"), np.bool_(True), object(), _Cls, int, type, cf.ThreadPoolExecutor,
                     {}, {"a": 1}, [], [[]], [1, [2, [3]]], (None,), ["x", "y"], {1, 2}]),
    st.integers(min_value=-10 ** 40, max_value=10 ** 40),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=6),
    st.binary(max_size=4),
    st.complex_numbers(max_magnitude=1e6),
)
WRONG = st.one_of(_SCALARS, st.lists(_SCALARS, max_size=4), st.dictionaries(st.text(max_size=3), _SCALARS, max_size=2))


# --- baselines: a valid call of every exported callable ----------------------------------------
def _skate():
    return ldaspark.get_scene("skate")


def _point():
    t0, q0, v0 = _skate().initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


def _result():
    return ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, engine="generic")


def _runspec():
    from ldaspark.ensemble import RunSpec
    q0, v0 = _point()
    return RunSpec(_skate().system, "gauss-2", 0.0, [q0], [v0], 0.1, 2)


def _system_kwargs():
    return dict(L="vx**2/2 + vy**2/2 - y", k=["vx - x*vy"], q=["x", "y"], v=["vx", "vy"])


def _tableau_kwargs():
    g = ldaspark.gauss(1, exact=True)
    return dict(name="t", s=1, exact=g.exact)


def _theory(**kw):
    q0, v0 = _point()
    return dict(system="skate", tableau="gauss-1", t0=0, q0=q0, v0=v0, h="0.1", **kw)


def _q1():
    return [float(x) for x in ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=1, engine="generic").q[-1]]


#: name -> (callable, kwargs factory, checker of a returned value). Each kwarg is mutated in turn.
BASELINES = {
    "LagrangianSystem": (lambda **a: ldaspark.LagrangianSystem(**a), _system_kwargs, None),
    "integrate": (ldaspark.integrate, lambda: dict(system="skate", method="gauss-1", h=0.1, n_steps=2,
                                                   engine="generic", save_every=1, dps=None, tol=None,
                                                   newton="auto", max_stages=None, dense_output=False,
                                                   params=None, energy_jump=None, project=False, guard=True),
                  "result"),
    "Newton": (lambda **a: ldaspark.integrate("skate", "gauss-1", h=0.1, n_steps=2, engine="generic",
                                              newton=ldaspark.Newton(**a)),
               lambda: dict(kind="auto", tol=None, max_iter=None, predictor="auto", linear_solver="auto",
                            reuse="auto"), "result"),
    "fast_integrate": (ldaspark.fast_integrate, lambda: dict(scene_or_system="skate", method="gauss-2", h=0.1,
                                                             n_steps=2, every=1, tol=None, max_iter=50), "fast"),
    "gauss": (ldaspark.gauss, lambda: dict(s=1, exact=False, max_stages=None), None),
    "lobatto_iiia_iiib": (ldaspark.lobatto_iiia_iiib, lambda: dict(s=2, exact=False, max_stages=None), None),
    "lobatto_iiia_iiib_iiid": (ldaspark.lobatto_iiia_iiib_iiid, lambda: dict(s=2, exact=False, max_stages=None),
                               None),
    "euler_i": (ldaspark.euler_i, lambda: dict(exact=True), None),
    "euler_ii": (ldaspark.euler_ii, lambda: dict(exact=True), None),
    "SparkTableau": (lambda **a: ldaspark.SparkTableau(**a).arrays(), _tableau_kwargs, None),
    "load_tableau": (ldaspark.load_tableau,
                     lambda: dict(path=os.path.join(_ROOT, "examples", "tableaux", "gauss2.json"), max_stages=None),
                     None),
    "get_method": (ldaspark.get_method, lambda: dict(name="gauss-1", exact=False, max_stages=None), None),
    "get_scene": (ldaspark.get_scene, lambda: dict(name="mp-particles", ic=1), None),
    "discrete_lagrangian": (ldaspark.discrete_lagrangian,
                            lambda: dict(system="skate", tableau="gauss-1", t0=0, q0=_point()[0], t1="0.1", q1=_q1(),
                                         dps=16), None),
    "theorem1_residuals": (ldaspark.theorem1_residuals, lambda: _theory(dps=16, max_refine=0), "dict"),
    "check_symmetry": (ldaspark.check_symmetry, lambda: _theory(dps=16), "dict"),
    "classify_wellposedness": (ldaspark.classify_wellposedness, lambda: _theory(dps=(16, 20), h_factors=(1, "1/2")),
                               None),
    "flow_jacobian": (ldaspark.flow_jacobian, lambda: dict(system="skate", method="gauss-1", q0=None, v0=None, h=0.1,
                                                           t0=0, dps=None, coords=[0], rates=None, params=None,
                                                           how="ift", tol=None), "flow"),
    "run_many": (ldaspark.run_many, lambda: dict(specs=[_runspec()], executor=None, max_workers=None, chunk=1,
                                                 progress=None, where=cf.ThreadPoolExecutor(1)), None),
    "save_result": (ldaspark.save_result, lambda: dict(result=_result(), path="/tmp/ldaspark-harness.json"), None),
    "load_result": (ldaspark.load_result, lambda: dict(path="/tmp/ldaspark-harness.json"), "result"),
    "plot.energy": (lambda **a: ldaspark.plot.energy(**a), lambda: dict(result=_result(), relative=True), None),
    "plot.constraint": (lambda **a: ldaspark.plot.constraint(**a), lambda: dict(result=_result()), None),
    "plot.trajectory": (lambda **a: ldaspark.plot.trajectory(**a), lambda: dict(result=_result(), i=0, j=1), None),
}
#: exported names that are not callables taking user values, with the reason
NOT_DRIVEN = {
    "LdasparkError": "the exception class itself",
    "Result": "a plain record the engines fill; its readers (save_result, plot.*) are driven with it",
    "__version__": "a string",
    "plot": "a module: its functions are driven as plot.energy, plot.constraint, plot.trajectory",
}
#: (name, argument) pairs that still fail in this branch for reasons owned elsewhere (result files)
KNOWN: set = set()     # (name, argument) pairs known to fail; none left


def test_every_exported_name_is_driven():
    driven = {n.split(".")[0] for n in BASELINES} | set(NOT_DRIVEN)
    assert set(ldaspark.__all__) <= driven, set(ldaspark.__all__) - driven
    # negative control: a name left out is noticed
    assert "integrate" not in ({n.split(".")[0] for n in BASELINES if n != "integrate"} | set(NOT_DRIVEN))


def _alarm(signum, frame):
    raise TimeoutError(f"no answer within {TIME_BOUND} s")


def call_bounded(fn, kwargs):
    """fn(**kwargs) with SIGALRM after TIME_BOUND seconds (main thread only)."""
    assert threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(TIME_BOUND)
    try:
        return fn(**kwargs)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _finite(a) -> bool:
    arr = np.asarray(a, dtype=object).reshape(-1)
    return all(isinstance(x, (int, float, np.integer, np.floating)) and math.isfinite(float(x))
               or type(x).__name__ == "mpf" and math.isfinite(float(x)) for x in arr)


def check_returned(kind, out) -> None:
    """A returned value is a correct one: no NaN or complex number in it."""
    if kind in ("result", "fast"):
        for name in ("t", "q", "v", "energy"):
            assert _finite(getattr(out, name)), f"{name} not finite"
    elif kind == "flow":
        assert _finite(out.J) and _finite(out.full)
    elif kind == "dict":
        for key, val in out.items():
            if isinstance(val, (int, float)) and not isinstance(val, bool):
                assert math.isfinite(val), key


def assert_clean(name, kwargs):
    fn, _, kind = BASELINES[name]
    try:
        out = call_bounded(fn, kwargs)
    except LdasparkError as exc:
        msg = str(exc)
        assert msg and "\n" not in msg, f"{name}: not one line: {msg!r}"
        return "refused"
    check_returned(kind, out)
    return "accepted"


@pytest.fixture(scope="module", autouse=True)
def _result_file(tmp_path_factory):
    # the module runs in a directory of its own: a drawn path that is valid (save_result's path
    # drawn as a short text) writes there, never into the checkout the tests run from
    home = os.getcwd()
    os.chdir(tmp_path_factory.mktemp("harness-cwd"))
    ldaspark.save_result(_result(), "/tmp/ldaspark-harness.json")
    ldaspark.fast_integrate("skate", "gauss-2", h=0.1, n_steps=2)      # compile (or load) the kernels once
    _runspec()
    import matplotlib
    matplotlib.use("Agg")
    try:
        yield
    finally:
        os.chdir(home)


CASES = [(name, arg) for name, (_, make, _) in BASELINES.items() for arg in make()]


@pytest.mark.parametrize("name", list(BASELINES))
def test_baseline_is_valid(name):
    fn, make, kind = BASELINES[name]
    assert assert_clean(name, make()) == "accepted"


#: arguments whose valid values scale the work: a drawn valid count above WORK_BOUND is a long
#: correct run, not a finding (the counts' own upper bounds are checked with 10**30 and 2**64)
WORK_ARGS = {("integrate", "n_steps"), ("integrate", "save_every"), ("fast_integrate", "n_steps"),
             ("fast_integrate", "max_iter"), ("fast_integrate", "every")}
WORK_BOUND = 1000


#: arguments that are the caller's own callbacks: a callable drawn there runs as the caller's code
#: (its own exceptions are the caller's); only non-callables are drawn
USER_CALLBACKS = {("run_many", "progress")}


def _long_valid_run(name, arg, value) -> bool:
    if (name, arg) in USER_CALLBACKS and callable(value):
        return True
    return ((name, arg) in WORK_ARGS and isinstance(value, (int, np.integer)) and not isinstance(value, bool)
            and WORK_BOUND < value <= 10 ** 9)


def _sweep(name, arg, data):
    from hypothesis import assume
    if (name, arg) in KNOWN:
        pytest.xfail("path and result checks of save_result / load_result belong to the result-file work")
    kwargs = BASELINES[name][1]()
    kwargs[arg] = data.draw(WRONG, label=f"{name}({arg}=...)")
    assume(not _long_valid_run(name, arg, kwargs[arg]))
    assert_clean(name, kwargs)


@pytest.mark.parametrize("name,arg", CASES, ids=[f"{n}-{a}" for n, a in CASES])
@settings(max_examples=4, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_one_wrong_argument(name, arg, data):
    _sweep(name, arg, data)


@pytest.mark.exhaustive
@pytest.mark.parametrize("name,arg", CASES, ids=[f"{n}-{a}" for n, a in CASES])
@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data())
def test_one_wrong_argument_exhaustive(name, arg, data):
    _sweep(name, arg, data)


def test_harness_catches_a_raw_exception():
    """Negative control: a function that raises TypeError on a bad value fails the check."""
    BASELINES["_control"] = (lambda x: 1 / x if x != 0 else [][1], lambda: dict(x=1), None)
    try:
        with pytest.raises(IndexError):
            assert_clean("_control", dict(x=0))
        with pytest.raises(AssertionError):
            # LdasparkError escapes a line break in its message (core.errors.one_line): an error
            # class that prints two lines anyway is what the check must catch
            class _TwoLines(LdasparkError):
                def __str__(self):
                    return "two\nlines"
            BASELINES["_control"] = (lambda x: (_ for _ in ()).throw(_TwoLines("x")), lambda: {}, None)
            assert_clean("_control", dict(x=0))
    finally:
        BASELINES.pop("_control", None)


# --- the command line: every int / float option of every subcommand ---------------------------------
def _numeric_options():
    import argparse

    from ldaspark.cli import build_parser
    out = []

    def walk(p, path):
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for n, sp in a.choices.items():
                    walk(sp, path + [n])
            elif a.option_strings and a.choices is None and (a.type in (int, float) or
                                                              getattr(a.type, "__module__", "") == "ldaspark.cli"):
                out.append((tuple(path), a.option_strings[0], a.dest))
    walk(build_parser("*"), [])
    return out


_BASE_ARGV = {("integrate",): ["integrate", "skate", "gauss-1", "--h", "0.1", "--t-end", "0.1", "--out",
                               "/tmp/ldaspark-harness-cli.json"],
              ("audit",): ["audit", "--method", "gauss-1"]}
BAD_NUMBERS = ["0", "-3", "nan", "inf", "-inf", "abc", "", "1e400", "2.5", str(10 ** 30), "0x10"]
VALID_REALS = ("2.5", str(10 ** 30))      # valid for a real option (a time), not for a count


def test_cli_numeric_options_enumerated():
    opts = _numeric_options()
    names = {(p, o) for p, o, _ in opts}
    assert (("report",), "--workers") in names and (("report", "convergence"), "--t-end") in names
    assert len(opts) >= 15


@pytest.mark.parametrize("path,opt,dest", _numeric_options(), ids=lambda x: str(x))
def test_cli_numeric_option_refuses_wrong_values(path, opt, dest, capsys, tmp_path, monkeypatch):
    from ldaspark.cli import main
    monkeypatch.chdir(tmp_path)           # a value let through must not rewrite the repository's reports/
    base = _BASE_ARGV.get(path, list(path))
    for bad in BAD_NUMBERS:
        if dest == "ic" and bad == "0" or dest in ("t_end", "t_long") and bad in VALID_REALS:
            continue                      # index 0 is valid; so are real times
        try:                              # argparse's own errors exit, the commands' return 2
            code = call_bounded(lambda: main(base + [opt, bad]), {})
        except SystemExit as exc:
            code = exc.code
        err = capsys.readouterr().err.strip()
        assert code == 2, (path, opt, bad, err)
        assert err.startswith("ldaspark: error:") and "\n" not in err, (path, opt, bad, err)


@pytest.mark.parametrize("addr", ["x://y", "tcp://", "inproc://", "tcp://[::1", "tcp://:8786", "tcp://h:0",
                                  "tcp://h:99999", "tcp://h:abc", "tcp://a b:1", "tcp://h/x"])
def test_cli_scheduler_refuses_malformed_addresses_at_once(addr, capsys, tmp_path, monkeypatch):
    from ldaspark.cli import main
    monkeypatch.chdir(tmp_path)
    code = call_bounded(lambda: main(["report", "--scheduler", addr, "--outdir", str(tmp_path)]), {})
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("ldaspark: error:") and "\n" not in err, err


def _subcommands_and_choice_options():
    import argparse

    from ldaspark.cli import build_parser
    cmds, choices = [], []

    def walk(p, path):
        for a in p._actions:
            if isinstance(a, argparse._SubParsersAction):
                for n, sp in a.choices.items():
                    cmds.append(tuple(path + [n]))
                    walk(sp, path + [n])
            elif a.option_strings and a.choices is not None:
                choices.append((tuple(path), a.option_strings[0]))
    walk(build_parser("*"), [])
    return cmds, choices


def _exit_code(argv):
    from ldaspark.cli import main
    try:
        return call_bounded(lambda: main(argv), {})
    except SystemExit as exc:
        return exc.code


@pytest.mark.parametrize("path", _subcommands_and_choice_options()[0], ids=lambda p: " ".join(p))
def test_cli_every_subcommand_refuses_an_unknown_option(path, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code = _exit_code(list(path) + ["--no-such-option", "1"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("ldaspark: error:") and "\n" not in err, (path, err)


@pytest.mark.parametrize("path,opt", _subcommands_and_choice_options()[1], ids=lambda x: str(x))
def test_cli_every_choice_option_refuses_an_unknown_value(path, opt, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    base = _BASE_ARGV.get(path, list(path))
    for bad in ("no-such-choice", "", "0", "\u00b5"):
        code = _exit_code(base + [opt, bad])
        err = capsys.readouterr().err.strip()
        assert code == 2 and err.startswith("ldaspark: error:") and "\n" not in err, (path, opt, bad, err)


def test_cli_subcommands_enumerated():
    cmds, choices = _subcommands_and_choice_options()
    assert {("integrate",), ("report",), ("verify",), ("audit",), ("mutants",), ("report", "energy")} <= set(cmds)
    assert (("integrate",), "--engine") in choices


@pytest.mark.parametrize("pos", [1, 2])
@pytest.mark.parametrize("bad", ["no-such", "", "\u00b5", "x" * 5000, "gauss-0", "gauss-99999999999999999999"])
def test_cli_integrate_positionals_refuse_wrong_names(pos, bad, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = list(_BASE_ARGV[("integrate",)])
    argv[pos] = bad
    code = _exit_code(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("ldaspark: error:") and "\n" not in err, (bad[:20], err)
