"""Round 4 of the reliability work, roots 3-7: the exported functions outside ``integrate`` check
their input, silent wrong numbers are refused with the reason, functions the engines cannot
translate are refused when the system is built, malformed Dask addresses are one line at once,
and valid input that was refused is accepted. Every refusal has a valid neighbour that works."""
from __future__ import annotations

import concurrent.futures as cf
import os
import subprocess
import sys
from fractions import Fraction

import mpmath
import numpy as np
import pytest
import sympy

import ldaspark
from ldaspark import LdasparkError
from ldaspark.core.errors import InputError, SystemDefinitionError

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _skate_point():
    t0, q0, v0 = ldaspark.get_scene("skate").initial(None)
    return [float(x) for x in q0], [float(x) for x in v0]


def _one_line(exc_info):
    msg = str(exc_info.value)
    assert msg and "\n" not in msg
    return msg


# --- root 3: exported functions outside the validation layer ------------------------------------
def _fj(**kw):
    h = kw.pop("h", 0.1)
    return ldaspark.flow_jacobian("skate", "gauss-2", None, None, h, **kw)


@pytest.mark.parametrize("h", ["abc", 1j, True, 0, float("nan"), float("inf"), None, [0.1]])
def test_flow_jacobian_refuses_a_bad_step(h):
    with pytest.raises(InputError) as ei:
        _fj(h=h)
    assert "h" in _one_line(ei)


def test_flow_jacobian_valid_neighbours():
    full = _fj()
    assert np.all(np.isfinite(full.J)) and full.J.shape == (6, 6)
    assert np.allclose(_fj(h="0.1").J, full.J)             # a decimal string is a number
    B = np.eye(6)[:, :2]
    r = _fj(tangent=B, select=[0, 1])
    assert np.allclose(r.J, full.full[[0, 1]][:, [0, 1]])
    assert _fj(coords=[0, 1]).J.shape == (2, 2)


def test_flow_jacobian_refuses_nan_t0_and_tangent():
    with pytest.raises(InputError, match="t0"):
        _fj(t0=float("nan"))
    B = np.eye(6)[:, :2]
    B[0, 0] = np.nan
    with pytest.raises(InputError, match="tangent"):
        _fj(tangent=B, select=[0, 1])


@pytest.mark.parametrize("select", [[0, 99], [0, -1], [0, 1.5], [0, 0], [0, True], "01"])
def test_flow_jacobian_refuses_bad_select(select):
    with pytest.raises(InputError, match="select"):
        _fj(tangent=np.eye(6)[:, :2], select=select)


def test_flow_jacobian_refuses_duplicate_coordinates():
    with pytest.raises(InputError, match="twice"):
        _fj(coords=[0, 0])
    with pytest.raises(InputError, match="twice"):
        _fj(coords=["q1", 0])
    assert _fj(coords=["q1"]).J.shape == (1, 1)


def test_theorem1_and_wellposedness_refuse_h0_and_take_a_scene_name():
    skate = ldaspark.get_scene("skate")
    q0, v0 = _skate_point()
    tab = ldaspark.get_method("gauss-1")
    for fn in (ldaspark.theorem1_residuals, ldaspark.check_symmetry):
        with pytest.raises(InputError, match="h must be nonzero"):
            fn(skate.system, tab, 0, q0, v0, 0, dps=20)
    with pytest.raises(InputError, match="h must be nonzero"):
        ldaspark.classify_wellposedness(skate.system, tab, 0, q0, v0, 0, dps=(16, 20))
    by_name = ldaspark.theorem1_residuals("skate", "gauss-1", 0, None, None, "0.1", dps=20, max_refine=0)
    by_obj = ldaspark.theorem1_residuals(skate.system, tab, 0, q0, v0, "0.1", dps=20, max_refine=0)
    assert by_name["theorem1-q0"] < 1e-15 and by_obj["theorem1-q0"] < 1e-15
    cls = ldaspark.classify_wellposedness("skate", "gauss-1", 0, None, None, "0.1", dps=(16, 20))
    assert "sigma" in cls
    with pytest.raises(InputError, match="system"):
        ldaspark.theorem1_residuals(3, tab, 0, q0, v0, "0.1")
    with pytest.raises(InputError, match="h_factors"):
        ldaspark.classify_wellposedness("skate", "gauss-1", 0, None, None, "0.1", dps=(16, 20), h_factors=(1,))


def test_runspec_and_run_many_check_their_arguments():
    from ldaspark.ensemble import RunSpec
    q0, v0 = _skate_point()
    with pytest.raises(InputError, match="system"):
        RunSpec(3, "gauss-2", 0, [q0], [v0], 0.1, 2)
    spec = RunSpec("skate", "gauss-2", 0, [q0], [v0], 0.1, 2)        # a scene name, as integrate takes
    assert spec.system is ldaspark.get_scene("skate").system
    with pytest.raises(InputError, match="list of RunSpec"):
        ldaspark.run_many(3)
    with pytest.raises(InputError, match="progress"):
        ldaspark.run_many([spec], progress=3)
    with pytest.raises(InputError, match="max_workers"):
        ldaspark.run_many([spec], max_workers=0)
    with pytest.raises(InputError, match="class"):
        ldaspark.run_many([spec], executor=cf.ThreadPoolExecutor)
    with pytest.raises(InputError, match="class"):
        ldaspark.run_many([spec], where=cf.ThreadPoolExecutor)
    seen = []
    with cf.ThreadPoolExecutor(1) as ex:
        out = ldaspark.run_many([spec], executor=ex, progress=lambda k, n: seen.append((k, n)))
    assert out[0].q.shape == (1, 3, 3) and seen == [(1, 1)]


@pytest.mark.parametrize("name,ic", [(["skate"], None), (3, None), ("mp-particles", True), ("mp-particles", "3"),
                                     ("mp-particles", 2.5), ("mp-particles", -1), ("skate", 1)])
def test_get_scene_refuses_bad_name_and_ic(name, ic):
    with pytest.raises(InputError):
        ldaspark.get_scene(name, ic)


def test_get_scene_valid_neighbours():
    a = ldaspark.get_scene("mp-particles", 2)
    b = ldaspark.get_scene("mp-particles", np.int64(2))
    assert a is b and a.params["j"] == 2


@pytest.mark.parametrize("argv", [["report", "--workers", "0"], ["report", "--workers", "-3"],
                                  ["report", "convergence", "--t-end", "nan"],
                                  ["report", "convergence", "--t-end", "inf"],
                                  ["report", "convergence", "--t-end", "-1"],
                                  ["report", "convergence", "--workers", "0"]])
def test_cli_bad_counts_and_times_exit_2_with_one_line(argv, capsys, tmp_path, monkeypatch):
    from ldaspark.cli import main
    monkeypatch.chdir(tmp_path)           # a value let through must not rewrite the repository's reports/
    with pytest.raises(SystemExit) as ei:
        main(argv)
    err = capsys.readouterr().err.strip()
    assert ei.value.code == 2 and err.startswith(f"ldaspark: error: argument {argv[-2]}") and "\n" not in err


def test_cli_valid_counts_and_times_parse():
    from ldaspark.cli import build_parser
    assert build_parser("report").parse_args(["report", "--workers", "3"]).workers == 3
    assert build_parser("report").parse_args(["report", "convergence", "--t-end", "0.5"]).t_end == 0.5
    b = build_parser("integrate").parse_args(["integrate", "mp-particles", "gauss-1", "--h", "1", "--t-end", "1",
                                              "--out", "x.json", "--ic", "0"])
    assert b.ic == 0


# --- root 4: silent wrong numbers --------------------------------------------------------------
X, Y, VX, VY = sympy.symbols("x y vx vy")


def test_mechanical_form_refuses_a_non_symmetric_mass_matrix():
    with pytest.raises(SystemDefinitionError, match="not symmetric") as ei:
        ldaspark.LagrangianSystem.mechanical_form([[1, 0.5], [0, 1]], "x**2/2 + y**2/2", [[1, 1]],
                                                  q=[X, Y], v=[VX, VY])
    _one_line(ei)
    ok = ldaspark.LagrangianSystem.mechanical_form([[1, 0.25], [0.25, 1]], "x**2/2 + y**2/2", [[1, 1]],
                                                   q=[X, Y], v=[VX, VY])
    assert ok.L_vv == sympy.Matrix(ok.mechanical["M"])
    res = ldaspark.integrate(ok, "gauss-1", q0=[0.1, 0.2], v0=[0.5, -0.5], h=0.1, n_steps=3, engine="generic")
    assert res.status == 0


def test_mechanical_m_set_by_hand_is_checked_by_the_compiled_engine_too():
    from ldaspark.compiled.fast import mechanical_parts
    sysm = ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - X ** 2 / 2, [VX + VY], [X, Y], [VX, VY])
    sysm.mechanical = {"M": sympy.Matrix([[1, 1], [0, 1]]), "U": X ** 2 / 2, "K": sympy.Matrix([[1, 1]]),
                       "b": sympy.zeros(1, 1)}
    with pytest.raises(SystemDefinitionError, match="not symmetric"):
        mechanical_parts(sysm)
    sysm.mechanical = {"M": sympy.Matrix([[2, 0], [0, 1]]), "U": X ** 2 / 2, "K": sympy.Matrix([[1, 1]]),
                       "b": sympy.zeros(1, 1)}
    with pytest.raises(SystemDefinitionError, match="L_vv"):
        mechanical_parts(sysm)                   # symmetric, but not the M of L
    sysm.mechanical = {"M": sympy.eye(2), "U": X ** 2 / 2, "K": sympy.Matrix([[1, 1]]), "b": sympy.zeros(1, 1)}
    assert mechanical_parts(sysm)["M"] == sympy.eye(2)


def test_steps_that_do_not_advance_t_are_refused():
    with pytest.raises(InputError, match="does not advance t") as ei:
        ldaspark.integrate("skate", "gauss-1", t0=1e17, h=1, n_steps=64)
    _one_line(ei)
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.integrate("skate", "gauss-1", t0=1.0, h=1e-17, n_steps=2, engine="generic")
    from ldaspark.ensemble import RunSpec
    q0, v0 = _skate_point()
    with pytest.raises(InputError, match="does not advance t"):
        RunSpec("skate", "gauss-2", 1e17, [q0], [v0], 1.0, 4)
    with pytest.raises(InputError, match="does not advance t"):
        ldaspark.integrate("skate", "gauss-1", t0=1, h="1e-25", n_steps=1, dps=20, engine="generic")
    # neighbours: a step the numbers near t resolve, in float64 and at 40 digits
    res = ldaspark.integrate("skate", "gauss-1", t0=1e17, h=64, n_steps=4, engine="generic")
    assert len(set(res.t.tolist())) == 5 and res.status == 0
    res = ldaspark.integrate("skate", "gauss-1", t0=1, h="1e-25", n_steps=1, dps=40, engine="generic")
    assert res.status == 0 and res.t[1] > res.t[0]


def test_string_l_names_must_be_nfkc_normal():
    mu_micro, mu_greek = sympy.Symbol("\u00b5"), sympy.Symbol("\u03bc")
    with pytest.raises(SystemDefinitionError, match="NFKC"):
        ldaspark.LagrangianSystem("\u00b5*vx**2/2 + vy**2/2", ["vx - vy"], [X, Y], [VX, VY], params=[mu_greek])
    with pytest.raises(SystemDefinitionError, match="NFKC"):
        ldaspark.LagrangianSystem("\uff58*vx**2/2 + vy**2/2", ["vx - vy"], [X, Y], [VX, VY])
    with pytest.raises(SystemDefinitionError, match="NFKC normalisation"):
        ldaspark.LagrangianSystem(mu_micro * VX ** 2 / 2 + mu_greek * VY ** 2, [VX - VY], [X, Y], [VX, VY],
                                  params=[mu_micro, mu_greek])
    ok = ldaspark.LagrangianSystem("\u03bc*vx**2/2 + vy**2/2", ["vx - vy"], [X, Y], [VX, VY], params=[mu_greek])
    assert ok.L.free_symbols == {mu_greek, VX, VY}


def test_parameter_declarations_are_checked():
    L = "a*vx**2/2 + vy**2/2"
    for bad in (dict(params={"a": True}), dict(params={"a": np.bool_(False)}), dict(params=["x"]),
                dict(params=["t"]), dict(params=["a", "a"]), dict(params={"a": float("nan")})):
        with pytest.raises(SystemDefinitionError):
            ldaspark.LagrangianSystem(L, ["vx - vy"], [X, Y], [VX, VY], **bad)
    ok = ldaspark.LagrangianSystem(L, ["vx - vy"], [X, Y], [VX, VY], params={"a": 2.0})
    with pytest.raises(SystemDefinitionError, match="bool"):
        ok.with_params(a=True)
    with pytest.raises(InputError, match="bool"):
        ldaspark.integrate(ok, "gauss-1", q0=[0, 0], v0=[1, 1], h=0.1, n_steps=1, params={"a": True})
    res = ldaspark.integrate(ok, "gauss-1", q0=[0, 0], v0=[1, 1], h=0.1, n_steps=1, engine="generic",
                             params={"a": 3})
    assert res.status == 0


@pytest.mark.parametrize("span", [{0: 0, 1: 1}, {0, 1}, "01", 1.0])
def test_t_span_must_be_a_pair(span):
    with pytest.raises(InputError, match="t_span"):
        ldaspark.integrate("skate", "gauss-1", t_span=span, h=0.5, engine="generic")


def test_t_span_valid_neighbours():
    for span in ((0, 1), [0, 1], np.array([0.0, 1.0])):
        assert len(ldaspark.integrate("skate", "gauss-1", t_span=span, h=0.5, engine="generic").t) == 3


def test_ensemble_members_terminal_events_are_on_the_batched_result():
    def at_015(t, q, v):
        return t - 0.15
    at_015.terminal = True
    q0, v0 = _skate_point()
    res = ldaspark.integrate("skate", "gauss-1", q0=[q0, q0], v0=[v0, v0], h=0.1, n_steps=4, events=at_015,
                             engine="generic")
    assert list(res.status) == [1, 1]
    assert len(res.t_events) == 1 and len(res.t_events[0]) == 2
    for k, m in enumerate(res.members):
        assert np.array_equal(res.t_events[0][k], m.t_events[0]) and np.allclose(m.t_events[0], [0.15])
        assert np.array_equal(res.q_events[0][k], m.q_events[0])
    plain = ldaspark.integrate("skate", "gauss-1", q0=[q0, q0], v0=[v0, v0], h=0.1, n_steps=2, engine="generic")
    assert plain.t_events == [] and list(plain.status) == [0, 0]


# --- root 5: functions the engines cannot translate; two symbols with one name ----------------
@pytest.mark.parametrize("f,name", [(sympy.besselj(0, X), "besselj"), (sympy.polygamma(0, X + 3), "polygamma"),
                                    (sympy.LambertW(X), "LambertW"), (sympy.zeta(X + 3), "zeta"),
                                    (sympy.conjugate(X), "conjugate"), (sympy.floor(X) * X, "floor"),
                                    (sympy.gamma(X + 3), "gamma"), (sympy.Function("f")(X), "f"),
                                    (sympy.Derivative(sympy.sin(X * Y), X), "erivative")])
def test_untranslatable_functions_refused_at_build(f, name):
    with pytest.raises(SystemDefinitionError) as ei:
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - f, [VX - VY], [X, Y], [VX, VY])
    assert name in _one_line(ei)


def test_untranslatable_function_in_k_is_named_with_where():
    with pytest.raises(SystemDefinitionError, match=r"k\[0\] contains the function zeta"):
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2, [VX - sympy.zeta(X + 3) * VY], [X, Y], [VX, VY])


@pytest.mark.parametrize("dps", [None, 20])
def test_translated_functions_still_run(dps):
    U = sympy.sin(X) + sympy.Abs(Y) + sympy.Piecewise((X ** 2, X > 0), (0, True)) + sympy.atan2(X, Y + 3) \
        + sympy.erf(X) + sympy.Heaviside(X) * X ** 2
    sysm = ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - U, [VX - VY / 2], [X, Y], [VX, VY])
    res = ldaspark.integrate(sysm, "gauss-1", q0=[0.5, 0.5], v0=[0.5, 1], h=0.1, n_steps=2, engine="generic",
                             dps=dps)
    assert res.status == 0


def test_two_symbols_with_one_name_refused_at_build():
    x_real = sympy.Symbol("x", real=True)
    with pytest.raises(SystemDefinitionError, match="same name") as ei:
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - x_real ** 2, [VX - VY], [X, Y], [VX, VY])
    assert "'x'" in _one_line(ei)
    with pytest.raises(SystemDefinitionError, match="same name"):
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - sympy.Dummy("y") ** 2, [VX - VY], [X, Y], [VX, VY])
    lam0 = sympy.Symbol("lam0")                   # the name of the first multiplier
    with pytest.raises(SystemDefinitionError, match="multipliers"):
        ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2, [VX - VY], [lam0, Y], [VX, VY])
    ok = ldaspark.LagrangianSystem(VX ** 2 / 2 + VY ** 2 / 2 - X ** 2, [VX - VY], [X, Y], [VX, VY])
    assert ldaspark.integrate(ok, "gauss-1", q0=[0.5, 0.5], v0=[1, 1], h=0.1, n_steps=1, engine="generic").status == 0


# --- root 6: malformed Dask addresses -------------------------------------------------------------
BAD_ADDRESSES = ["x://y", "tcp://", "inproc://", "tcp://[::1", "tcp://:8786", "tcp://h:0", "tcp://h:99999",
                 "tcp://h:abc", "tcp://h:", "tcp://a b:1", "tcp://h/x", "tcp://u@h:1", "inproc://1.2.3.4/1/1"]


@pytest.fixture
def no_client(monkeypatch):
    """distributed.Client replaced by a recorder: a malformed address must be refused before any
    Client exists (a Client waits for its connect timeout, then complains again in __del__)."""
    distributed = pytest.importorskip("distributed")
    made = []
    monkeypatch.setattr(distributed, "Client", lambda *a, **k: made.append(a) or pytest.fail("Client created"))
    return made


@pytest.mark.parametrize("addr", BAD_ADDRESSES)
def test_malformed_addresses_refused_at_once(addr, no_client):
    from ldaspark.ensemble import RunSpec
    from ldaspark.executors import check_where
    with pytest.raises(InputError, match="malformed Dask scheduler address") as ei:
        check_where(addr)
    _one_line(ei)
    q0, v0 = _skate_point()
    spec = RunSpec("skate", "gauss-2", 0, [q0], [v0], 0.1, 2)
    with pytest.raises(InputError, match="malformed"):
        ldaspark.run_many([spec], where=addr)
    assert no_client == []


def test_well_formed_addresses_pass_the_check():
    from ldaspark.executors import check_where
    for addr in ("tcp://127.0.0.1:8786", "tcp://scheduler", "tls://host.example:8786", "tcp://[::1]:8786",
                 "ws://h:1", f"inproc://10.0.0.1/{os.getpid()}/3"):
        check_where(addr)


def test_ledger_refuses_a_malformed_address_before_work(no_client, monkeypatch):
    from ldaspark.lab.claims import ledger
    built = []
    monkeypatch.setattr(ledger, "_ledger_tabs", lambda *a: built.append(a) or [])
    with pytest.raises(InputError, match="malformed"):
        ledger.run_ledger(where="tcp://")
    assert built == [] and no_client == []      # refused before the tableaux are built


@pytest.mark.parametrize("argv", [["report", "--scheduler", "tcp://[::1"], ["verify", "--scheduler", "x://y"],
                                  ["mutants", "--scheduler", "tcp://"]])
def test_cli_scheduler_one_line_no_traceback_at_exit(argv, tmp_path):
    p = subprocess.run([sys.executable, "-m", "ldaspark", *argv, "--outdir", str(tmp_path)], cwd=ROOT,
                       capture_output=True, text=True, timeout=120,
                       env={**os.environ, "PYTHONPATH": ROOT})
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "malformed" in lines[0], p.stderr      # no "Exception ignored in ..." after it


# --- root 7: valid input that was refused --------------------------------------------------------
def test_dense_output_at_mpf_and_fraction_times():
    res = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=3, dense_output=True, engine="generic")
    ref = res.sol(0.05)
    for t in (mpmath.mpf("0.05"), Fraction(1, 20), sympy.Rational(1, 20), np.float32(0.05)):
        q, v = res.sol(t)
        assert np.allclose(q, ref[0], atol=1e-7) and np.allclose(v, ref[1], atol=1e-7)
    q, _ = res.sol([mpmath.mpf("0.05"), Fraction(1, 10)])
    assert q.shape == (2, 3)
    for bad in ("0.05", mpmath.mpf("nan"), Fraction(10 ** 400, 1), [mpmath.mpc(1, 1)], True):
        with pytest.raises(InputError):
            res.sol(bad)


def test_dense_output_of_a_dps_run_at_its_own_times():
    res = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=2, dps=20, dense_output=True, engine="generic")
    assert isinstance(res.t[1], mpmath.mpf)
    q, _ = res.sol(res.t[1])
    assert np.allclose(q, [float(x) for x in res.q[1]], atol=1e-12)


def test_numpy_integers_wherever_ints_are_taken():
    a = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=np.int64(2), max_stages=np.int64(3),
                           save_every=np.int32(1), engine="generic")
    b = ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=2, max_stages=3, engine="generic")
    assert np.array_equal(a.q, b.q)
    assert ldaspark.get_method("gauss-3", max_stages=np.int64(3)).s == 3
    assert ldaspark.gauss(np.int64(2)).s == 2
    with pytest.raises(LdasparkError, match="max_stages"):
        ldaspark.get_method("gauss-3", max_stages=np.float64(3))
    with pytest.raises(LdasparkError, match="max_stages"):
        ldaspark.integrate("skate", "gauss-2", h=0.1, n_steps=1, max_stages=np.bool_(True))


@pytest.mark.parametrize("length", [243, 255])
def test_cli_out_with_a_long_name(length, tmp_path):
    from ldaspark.cli import main
    out = tmp_path / ("r" * (length - 5) + ".json")
    assert len(out.name) == length
    assert main(["integrate", "skate", "gauss-1", "--h", "0.1", "--t-end", "0.2", "--engine", "generic",
                 "--out", str(out)]) == 0
    assert ldaspark.load_result(str(out)).q.shape == (3, 3)


# --- found by the harness's sweeps ------------------------------------------------------------
def test_check_symmetry_at_rest_and_at_a_huge_step():
    at_rest = ldaspark.check_symmetry("skate", "gauss-1", 0, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], "0.1", dps=16)
    assert at_rest["symmetry-fd-unrestricted"] == (0.0, 0.0)      # was a ZeroDivisionError
    big = ldaspark.check_symmetry("skate", "gauss-1", 0, None, None, 6932, dps=16)   # was a broadcast ValueError
    assert all(np.isfinite(big[k]) for k in ("symmetry-Ld", "symmetry-Phi"))


def test_theory_checks_at_steps_beyond_range_are_errors_not_numbers():
    q0, _ = _skate_point()
    with pytest.raises(LdasparkError, match="not finite"):
        ldaspark.theorem1_residuals("skate", "gauss-1", 0, None, None, -1.2e146, dps=16, max_refine=0)
    with pytest.raises(LdasparkError, match="float64 range"):
        ldaspark.discrete_lagrangian("skate", "gauss-1", 5e165, q0, "0.1", q0, dps=16)
    ok = ldaspark.theorem1_residuals("skate", "gauss-1", 0, None, None, "1/10", dps=16, max_refine=0)
    assert ok["theorem1-q0"] < 1e-10
