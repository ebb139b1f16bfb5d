"""The generated-mutant runner (ldaspark/lab/mutants/mutgen.py): each operator kind is generated where
it should be and nowhere else, a mutant changes exactly the text it names, ids survive edits
elsewhere in the file, the committed equivalents list names existing mutants with an argument
each, and ``ldaspark mutants`` refuses in one line, at once, where the repository's tests are
missing (an installed wheel). Cost: ~3 s."""
import os
import pathlib
import shutil
import subprocess
import sys

import mpmath
import pytest

from ldaspark.core.families import get_method
from ldaspark.lab.mutants import mutgen

ROOT = pathlib.Path(__file__).resolve().parents[3]

SRC = '''"""doc 1"""
X = 3
TOL = 1e-9


def f(a, b, xs):
    """doc 2"""
    if a < b and not xs:
        return a + b * 2
    if a is None or b in xs:
        return -a
    y = max(xs[1:3])
    return all(x >= TOL for x in xs) == True


if __name__ == "__main__":
    print(1 + 1)
'''


def _by_kind(ms):
    out = {}
    for m in ms:
        out.setdefault(m.id.split("::")[2], []).append((m.original.strip(), m.replacement.strip()))
    return out


def test_every_operator_kind_is_generated(tmp_path):
    ms = mutgen.generate("x.py", SRC)
    k = _by_kind(ms)
    assert set(k["compare"]) == {("<", "<="), ("is", "is not"), ("in", "not in"), (">=", ">"), ("==", "!=")}
    assert set(k["boolean"]) == {("and", "or"), ("or", "and")}
    assert set(k["arithmetic"]) == {("+", "-"), ("*", "/")}
    assert ("not", "") in k["not-removal"] and ("-", "") in k["negation-removal"]
    assert set(k["constant"]) >= {("3", "(3 + 1)"), ("3", "0"), ("1e-9", "0.0"), ("2", "(2 + 1)"), ("True", "False")}
    assert ("a + b * 2", "None") in k["return"]
    assert set(k["call-swap"]) == {("max", "min"), ("all", "any")}
    assert set(k["slice"]) == {("1", "(1) + 1"), ("3", "(3) + 1")}
    # docstrings and the __main__ block are not mutated
    assert not [m for m in ms if "doc" in m.original or m.line >= 17]
    # every mutant compiles and differs from the source in its splice only
    for m in ms:
        out = m.mutated_source(SRC)
        compile(out, "x.py", "exec")
        assert out != SRC and out[:m.start] == SRC[:m.start] and out[m.start + len(m.replacement):] == SRC[m.end:]
    assert len({m.id for m in ms}) == len(ms)


def test_ids_survive_edits_elsewhere_and_apply_refuses_moved_source(tmp_path):
    a = {m.id for m in mutgen.generate("x.py", SRC)}
    b = {m.id for m in mutgen.generate("x.py", "import os\n\n\n" + SRC)}
    assert a == b
    m = next(m for m in mutgen.generate("x.py", SRC) if m.original == "<")
    pkg = tmp_path / "ldaspark"
    pkg.mkdir()
    (pkg / "x.py").write_text(SRC)
    m.apply(tmp_path)
    assert "a <= b" in (pkg / "x.py").read_text()
    (pkg / "x.py").write_text("# moved\n" + SRC)
    with pytest.raises(mutgen.MutgenError, match="source moved"):
        m.apply(tmp_path)


def test_module_names_and_errors():
    assert mutgen.module_file("ldaspark/core/validate.py") == "core/validate.py"
    assert mutgen.module_file("ldaspark.core.validate") == "core/validate.py"
    assert mutgen.module_file("core/validate.py") == "core/validate.py"
    with pytest.raises(mutgen.MutgenError):
        mutgen.module_file("ldaspark/core/nothing.py")
    with pytest.raises(mutgen.MutgenError, match="does not parse"):
        mutgen.generate("x.py", "def (:\n")


def test_the_equivalents_list_names_existing_mutants_with_an_argument():
    eq = mutgen.load_equivalent()
    files = {k.split("::")[0] for k in eq}
    ids = {m.id for f in files for m in mutgen.generate(f, check=False)}
    stale = sorted(set(eq) - ids)
    assert not stale, f"equivalent mutants no longer generated (update verification/mutants_equivalent.json): {stale}"
    assert all(len(v.strip()) > 10 and "\n" not in v for v in eq.values())


def test_the_equivalents_list_is_checked(tmp_path):
    p = tmp_path / "eq.json"
    p.write_text('{"a": ""}')
    with pytest.raises(mutgen.MutgenError, match="one-line argument"):
        mutgen.load_equivalent(p)
    p.write_text('["a"]')
    with pytest.raises(mutgen.MutgenError):
        mutgen.load_equivalent(p)
    assert mutgen.load_equivalent(tmp_path / "missing.json") == {}


@pytest.mark.parametrize("extra", [[], ["--generated", "ldaspark/core/validate.py"]])
def test_mutants_without_the_repositorys_tests_refuse_at_once(tmp_path, extra):
    """The package alone (as a wheel installs it): one line, exit 2, before any work."""
    shutil.copytree(ROOT / "ldaspark", tmp_path / "ldaspark",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    p = subprocess.run([sys.executable, "-m", "ldaspark", "mutants", "--quick", "--outdir", str(tmp_path / "out"),
                        *extra], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "needs the repository's tests" in lines[0], p.stderr
    assert not (tmp_path / "out").exists()              # nothing done (no timing asserted: CI's CPUs differ)
    # negative control: with the tests beside it the check passes
    from ldaspark.lab.mutants.mutation import CatalogueError, require_tests
    require_tests(ROOT)
    with pytest.raises(CatalogueError):
        require_tests(tmp_path)


def test_the_quick_generated_mutants_still_exist_and_name_a_test():
    ms, targets = mutgen.quick_generated()
    assert len(ms) == len(mutgen.QUICK_GENERATED) >= 3
    for m in ms:
        (test,) = targets[m.id]
        assert (ROOT / test.split("::")[0]).is_file()
        assert m.original != m.replacement


# --- kills of generated mutants that survived the first run ------------------------------------------
# lab/reports/stability_stiff.py: the committed report was computed with the module's grids and rules;
# recomputing the cheap parts from the stored rows ties the constants and the verdicts to it
def _stability():
    import json
    return json.loads((ROOT / "reports" / "stability.json").read_text())


def test_the_stiff_report_was_computed_with_the_modules_grids():
    from ldaspark.lab.reports import stability_stiff as st
    d = _stability()
    rows = d["stiff"]
    assert {(r["scene"], r["method"]) for r in rows} == {(s, m) for s in st.STIFF_SCENES for m in st.STIFF_METHODS}
    for s in st.STIFF_SCENES:
        for m in st.STIFF_METHODS:
            assert [r["hw"] for r in rows if (r["scene"], r["method"]) == (s, m)] == list(st.HW)
    assert all(r["N"] == st.N_STIFF and r["h"] == pytest.approx(r["hw"] / st.OMEGA, rel=1e-12) for r in rows)
    assert sorted({r["h"] for r in d["tiny"]}) == sorted(st.TINY_H)
    assert {r["method"] for r in d["tiny"]} == set(st.TINY_METHODS)
    for f in d["floor"]:
        assert f["h"] == list(st.FLOOR_H)
        assert f["N"] == [int(round(st.FLOOR_T / h)) for h in st.FLOOR_H]


def test_the_stiff_reports_classes_and_linear_predictions_recomputed():
    """classify, why and linear_stability on the stored rows give the stored verdicts (a changed
    threshold or a changed stability matrix disagrees with the committed report somewhere)."""
    from ldaspark.lab.reports import stability_stiff as st
    rows = _stability()["stiff"]
    for r in rows:
        assert st.classify(r) == r["class"], r
        assert st.why(r) == r["why"], r
        rho, R = st.linear_stability(r["method"], r["hw"])
        assert rho == pytest.approx(r["rho"], rel=1e-9, abs=1e-12), r
        assert (R is None) == (r["R"] is None) and (R is None or R == pytest.approx(r["R"], rel=1e-9, abs=1e-12))
    # the rows span every class and reason, so each rule above is exercised both ways
    assert {r["class"] for r in rows} == {"bounded", "growing", "failed"}
    assert {"linear instability", "energy growth", ""} <= {r["why"] for r in rows}


# analysis/flow_jacobian.py
def test_a_rate_may_be_named_after_its_coordinate():
    import ldaspark
    from tests.analysis.test_flow_jacobian import V0, Q0, gyroscopic
    sysm = gyroscopic()
    a = ldaspark.flow_jacobian(sysm, "gauss-1", Q0, V0, "0.1", dps=20, coords=["q1"], rates=["v1", "v2"])
    b = ldaspark.flow_jacobian(sysm, "gauss-1", Q0, V0, "0.1", dps=20, coords=["q1"], rates=["q1", "q2"])
    assert a.select == b.select and (a.J == b.J).all()
    with pytest.raises(mutgen.LdasparkError):          # a coordinate is not named after a rate
        ldaspark.flow_jacobian(sysm, "gauss-1", Q0, V0, "0.1", dps=20, coords=["v1"])


def test_the_default_time_is_zero_and_the_unrestricted_read_out_is_all_of_q_v():
    import ldaspark
    from ldaspark.models.scenes import get_scene
    sc = get_scene("rheonomic-skate")          # L and k depend on t: the initial time matters
    t0, q0, v0 = sc.initial(20)
    a = ldaspark.flow_jacobian(sc.system, "gauss-1", q0, v0, "0.1", dps=20)
    b = ldaspark.flow_jacobian(sc.system, "gauss-1", q0, v0, "0.1", dps=20, t0=0)
    c = ldaspark.flow_jacobian(sc.system, "gauss-1", q0, v0, "0.1", dps=20, t0="0.5")
    assert (a.full == b.full).all()
    assert max(abs(x - y) for x, y in zip(a.full.reshape(-1), c.full.reshape(-1))) > 1e-6   # t0 is seen
    n = sc.system.n
    assert a.select == list(range(2 * n)) and a.tangent is None and a.J.shape == (2 * n, 2 * n)


def test_the_stiff_scenes_are_the_documented_models():
    """The skate (8.2) and the particle (8.1) in U = omega^2 |q|^2 / 2 (resp. omega^2 (q1^2 + q2^2)
    / 2), with consistent initial data and the energy the report's relative errors divide by."""
    import sympy
    from ldaspark.lab.reports.stability_stiff import stiff_scene
    q = sympy.symbols("q1:4")
    v = sympy.symbols("v1:4")
    w2 = 7 ** 2
    T = sum(x ** 2 for x in v) / 2
    want = {"stiff-skate": (T - w2 * sum(x ** 2 for x in q) / 2, sympy.cos(q[2]) * v[1] - sympy.sin(q[2]) * v[0],
                            [1.0, 0.0, 0.5], [0.0, 0.0, 3.5]),
            "stiff-particle": (T - w2 * (q[0] ** 2 + q[1] ** 2) / 2, v[2] - q[1] * v[0], [1.0, 0.0, 0.0], [0.0, 7.0, 0.0])}
    for name, (L, k, q0w, v0w) in want.items():
        s, t0, q0, v0 = stiff_scene(name, 7)
        assert sympy.simplify(s.L - L) == 0, name
        assert sympy.simplify(s.k[0] - k) == 0 and s.m == 1, name
        assert t0 == 0.0 and list(q0) == q0w and list(v0) == v0w, name
        assert float(k.subs(dict(zip(q + v, q0w + v0w)))) == 0.0
    with pytest.raises(ValueError):
        stiff_scene("stiff-nothing", 7)


def test_a_short_stiff_record_splits_at_two_and_missing_stats_count_zero(monkeypatch):
    """Four energies (n = 3): the halves are the first two and the last two (the minimum half
    length 2); fallback counts absent from the engine's stats are 0."""
    from ldaspark.compiled import fast
    from ldaspark.lab.reports import stability_stiff as st
    import types
    import numpy as np
    rel = [0.0, 1e-6, 1e-5, 1e-5]
    sol = types.SimpleNamespace(energy=np.array([2 * (1 + x) for x in rel]), constraint=np.zeros(4),
                                stats={"mean_iterations": 2.0, "max_iterations": 3})
    monkeypatch.setattr(fast, "fast_integrate", lambda *a, **k: sol)
    row = st.stiff_run("stiff-particle", "gauss-2", 0.5, n=3)
    assert row["dE_growth"] == pytest.approx(10.0, rel=1e-6)
    assert row["full_newton_steps"] == 0 and row["generic_steps"] == 0


def test_units_failed_names_five_and_counts_the_rest():
    from ldaspark.executors import UnitsFailed
    e = UnitsFailed({f"u{i}": "boom" for i in range(7)}, {"ok": 1}, kept="ck.jsonl")
    msg = str(e)
    assert msg.startswith("7 work unit(s) failed (1 finished): ")
    assert "u4: boom" in msg and "u5" not in msg and "(and 2 more)" in msg and "ck.jsonl" in msg
    assert "more" not in str(UnitsFailed({f"u{i}": "x" for i in range(5)}, {}))


# executors.py: the executor behind ``where``
def _plus_one(x):
    return x + 1


def test_a_given_executor_is_used_as_is():
    """A thread pool passed as ``where`` runs the units itself (a closure, which a process pool
    could not pickle, runs); "local" with one job runs inline."""
    import concurrent.futures as cf
    from ldaspark.executors import Unit, run_units
    k = 41
    units = [Unit("a", lambda: k + 1)]
    with cf.ThreadPoolExecutor(1) as ex:
        assert run_units(units, where=ex) == {"a": 42}
    assert run_units([Unit("b", _plus_one, (1,))], where="local", jobs=1) == {"b": 2}


def test_a_renewed_pool_keeps_its_size_and_close_waits(monkeypatch):
    import time as _time
    from ldaspark import executors as workers
    made = []
    real = workers.make_process_pool

    def fake(n, mp_context=None, **kw):
        made.append(n)
        return real(n, mp_context=mp_context, **kw)
    monkeypatch.setattr(workers, "make_process_pool", fake)
    place = workers._Place(None, 1, None, inline_single=False)
    place.renew()
    assert made == [1, 1]
    f = place.executor.submit(_time.sleep, 0.5)
    place.close()
    assert f.done()                   # close waits for what was submitted


def test_a_lost_worker_is_retried_exactly_retries_times():
    """An executor whose worker is lost on every try of unit "bad": 1 + retries submissions,
    named with the count; the good unit once."""
    import concurrent.futures as cf
    from concurrent.futures.process import BrokenProcessPool
    from ldaspark.executors import Unit, UnitsFailed, run_units
    calls = []

    class Losing(cf.Executor):
        def submit(self, fn, /, *args, **kwargs):
            f = cf.Future()
            calls.append(args[0] if args else None)
            if args and args[0] == "bad":
                f.set_exception(BrokenProcessPool("worker died"))
            else:
                f.set_result(fn(*args))
            return f
    with pytest.raises(UnitsFailed) as ei:
        run_units([Unit("bad", str, ("bad",)), Unit("good", str, ("good",))], where=Losing(), retries=2)
    assert calls.count("bad") == 3 and calls.count("good") == 1
    assert "worker lost 3 times" in ei.value.failed["bad"] and ei.value.results == {"good": "good"}


# core/validate.py
def test_a_system_missing_one_method_is_refused_at_once():
    import types
    from ldaspark.core.errors import InputError
    from ldaspark.core.families import get_method
    from ldaspark.core.validate import check_system_and_tableau
    full = dict(n=1, m=0, stage=None, momentum=None, energy=None, saddle_matrix=None)
    tab = get_method("gauss-1")
    check_system_and_tableau(types.SimpleNamespace(**full), tab)            # control: all there
    for a in full:
        part = {k: v for k, v in full.items() if k != a}
        with pytest.raises(InputError, match="system must be"):
            check_system_and_tableau(types.SimpleNamespace(**part), tab)
    with pytest.raises(InputError, match="tableau must be"):
        check_system_and_tableau(types.SimpleNamespace(**full), types.SimpleNamespace(arrays=None, s=1.0))


def test_storage_size_is_points_times_numbers_times_bytes(monkeypatch):
    from ldaspark.core import validate as va
    from ldaspark.core.errors import InputError
    monkeypatch.setattr(va, "physical_memory", lambda: 2 * 10 ** 9)         # limit 1e9 bytes
    va.check_storage(10 ** 6, 24)                         # 1e6 * 24 * 40 = 0.96e9: fits
    with pytest.raises(InputError, match=r"needs about 0\.969 GiB, more than 0\.931 GiB"):
        va.check_storage(10 ** 6, 26)                     # 1.04e9: refused, sizes in GiB
    va.check_storage(10 ** 6, 8, mp=True)                 # 1e6 * 8 * 120 = 0.96e9
    with pytest.raises(InputError):
        va.check_storage(10 ** 6, 9, mp=True)
    monkeypatch.setattr(va, "physical_memory", lambda: None)            # unknown: 64 GiB
    va.check_storage(10 ** 8, 17)
    with pytest.raises(InputError):
        va.check_storage(10 ** 8, 18)                     # 7.2e10 > 64 * 2**30 = 6.87e10


def test_positive_and_nonzero_options_of_real_number():
    from ldaspark.core.errors import InputError
    from ldaspark.core.validate import real_number
    assert real_number(0.1, "h", positive=True) == 0.1
    assert real_number("1e-400", "h", positive=True) == "1e-400"      # below float64, still positive
    for bad in (0, -0.1, "-1"):
        with pytest.raises(InputError, match="must be positive"):
            real_number(bad, "h", positive=True)
    assert real_number(-2, "h", nonzero=True) == -2
    with pytest.raises(InputError, match="must be nonzero"):
        real_number(0.0, "h", nonzero=True)
    assert real_number(-3, "h") == -3                                  # control: no option, no check


def test_bad_values_are_described_briefly():
    from ldaspark.core.errors import InputError
    from ldaspark.core.validate import _describe, count
    assert _describe("x") == "str 'x'"
    long = _describe("y" * 100)
    assert long.startswith("str 'yyy") and long.endswith("...") and len(long) == len("str ") + 60 + 3
    with pytest.raises(InputError, match=r"n must be an integer, got float 2\.5"):
        count(2.5, "n")


def test_a_one_step_stiff_record_has_no_second_half(monkeypatch):
    from ldaspark.compiled import fast
    from ldaspark.lab.reports import stability_stiff as st
    import types
    import numpy as np
    sol = types.SimpleNamespace(energy=np.array([2.0, 2.0 * (1 + 1e-6)]), constraint=np.zeros(2),
                                stats={"mean_iterations": 2.0, "max_iterations": 3})
    monkeypatch.setattr(fast, "fast_integrate", lambda *a, **k: sol)
    row = st.stiff_run("stiff-particle", "gauss-2", 0.5, n=1)
    assert row["dE_growth"] == 0.0 and row["max_rel_dE"] == pytest.approx(1e-6)


def test_an_unknown_cpu_count_means_one_worker(monkeypatch):
    from ldaspark import executors as workers
    monkeypatch.setattr(workers.os, "cpu_count", lambda: None)
    place = workers._Place(None, None, None)
    assert isinstance(place.executor, workers.InlineExecutor) and not place.own_pool
    place.close()


def test_check_choice_returns_the_choice_and_refuses_others():
    from ldaspark.core.errors import InputError
    from ldaspark.core.validate import NEWTON_VARIANTS, check_choice
    assert check_choice("full", "newton", NEWTON_VARIANTS) == "full"
    for bad in ("Full", 1, None):
        with pytest.raises(InputError, match="newton must be one of"):
            check_choice(bad, "newton", NEWTON_VARIANTS)


def test_real_vector_takes_vectors_and_ensembles_only():
    from ldaspark.core.errors import InputError
    from ldaspark.core.validate import real_vector
    rows = [[1, "2"], [3.0, 4]]
    assert real_vector(rows, "q0") is rows and real_vector([1, 2], "q0") == [1, 2]
    for bad in ([[[1]]], 1.0, []):
        with pytest.raises(InputError, match="non-empty vector"):
            real_vector(bad, "q0")
    with pytest.raises(InputError, match=r"q0 entry 3"):
        real_vector([[1, 2], [3, "x"]], "q0")
    with pytest.raises(InputError, match=r"q0\[1\]"):
        real_vector([1, "x"], "q0")


def test_a_repeated_symbol_is_named_alone():
    import sympy
    from ldaspark.core.errors import SystemDefinitionError
    from ldaspark.core.validate import check_symbols
    x, z, a, b, c = sympy.symbols("x z a b c")
    with pytest.raises(SystemDefinitionError, match=r"q lists the same symbol twice: x$"):
        check_symbols([x, x, z], [a, b, c])
    check_symbols([x, z], [a, b])                      # control


def test_a_non_finite_initial_point_is_step_zero():
    import types
    from ldaspark.core.backend import Backend
    from ldaspark.core.errors import NonFiniteError
    from ldaspark.core.validate import finite_initial_point
    bk = Backend(None)

    def boom(*a):
        raise ZeroDivisionError("1/x at x = 0")
    for energy in (boom, lambda *a: float("inf")):
        sysm = types.SimpleNamespace(energy=energy, constraint=lambda *a: [0.0])
        with bk.context(), pytest.raises(NonFiniteError) as ei:
            finite_initial_point(sysm, bk, 0.0, [0.0], [0.0])
        assert ei.value.step == 0 and ei.value.time == 0.0
    ok = types.SimpleNamespace(energy=lambda *a: 1.0, constraint=lambda *a: [0.0])
    with bk.context():
        finite_initial_point(ok, bk, 0.0, [0.0], [0.0])          # control


def _close(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


# --- the audit: tolerances, step counts, floors, references (generated mutants of audit*.py) ---------------
def test_the_theorem1_tolerance_is_the_largest_of_its_three_parts():
    import types

    from ldaspark.lab.theory import audit as au
    tab = types.SimpleNamespace(source_digits=None)
    assert au._theorem1_tol(tab, 30, 0.0) == _close(1e-15)                 # 10^(-dps/2)
    assert au._theorem1_tol(tab, 40, 1e-19) == _close(1e-18)               # 10 x FD error
    tab20 = types.SimpleNamespace(source_digits=20)
    # the digits given no longer enter as 10^(3 - 20) = 1e-17: their effect is measured per scene
    assert au._theorem1_tol(tab20, 60, 0.0) == _close(1e-30)
    assert au._theorem1_tol(tab20, 60, 0.0, entry_tol=2e-25) == _close(2e-25)   # given: the largest


def test_theorem1_is_computed_from_initial_values_accurate_beyond_the_working_digits(monkeypatch):
    from ldaspark.lab.theory import audit as au
    from ldaspark.analysis import discrete
    from ldaspark.models.scenes import get_scene
    seen = []

    def fake(system, tab, t0, q0, v0, H, dps):
        seen.append((dps, q0, v0))
        return {"theorem1-q0": 1e-40, "theorem1-q1": 1e-40, "fd_error": 1e-35, "without_forces_q0": 1.0,
                "wellposed": "well-posed", "rank_deficiency": 0, "dps": dps, "dps_fd": dps + 20}
    monkeypatch.setattr(discrete, "theorem1_residuals", fake)
    au.theorem1_checks(get_method("gauss-1"), True, False, 30, True, ("particle",))
    (dps, q0, v0), = seen
    with mpmath.workdps(120):
        _, q, v = get_scene("particle").initial(110)
        assert max(abs(mpmath.mpf(a) - b) for a, b in zip(list(q0) + list(v0), list(q) + list(v))) < \
            mpmath.mpf(10) ** (-dps - 20)


def test_a_tolerance_exactly_at_the_teeth_bound_is_decided(monkeypatch):
    """TEETH is the largest tolerance that still has teeth: at exactly TEETH the scene is decided
    (the full audit does not retry at +20 digits) and no entries' precision note is added."""
    from ldaspark.lab.theory import audit as au
    from ldaspark.analysis import discrete, wellposedness
    calls = []

    def fake(system, tab, t0, q0, v0, H, dps):
        calls.append(dps)
        return {"theorem1-q0": 1e-9, "theorem1-q1": 1e-9, "fd_error": 0.0, "without_forces_q0": 1.0,
                "wellposed": "well-posed", "rank_deficiency": 0, "dps": dps, "dps_fd": dps + 20}
    monkeypatch.setattr(discrete, "theorem1_residuals", fake)
    monkeypatch.setattr(wellposedness, "classify_wellposedness",
                        lambda *a, **k: {"class": "well-posed", "rank_deficiency": 0})
    # dps 12: 10^(-dps/2) = 1e-6 = TEETH exactly
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, False, 12, False, ("particle",), entry_tol=(0.0, 0.0))
    assert calls == [12]
    assert checks[0].status == au.PASS and "decided at dps 12, 32 and h, h/2" in checks[0].detail
    # the entries' allowance is measured (``entry_effect``, replaced here): one above TEETH is still
    # decided, since the numerical part (1e-10 at dps 20) has teeth, and said so; a residual within
    # the numerical part gets no note; a computed built-in has no uncertainty to propagate
    monkeypatch.setattr(au, "entry_radii", lambda tab: {"A": [[1e-20]]})
    monkeypatch.setattr(au, "entry_effect", lambda tab, radii, f: (2 * au.TEETH, 1.0))
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, False, 20, True, ("particle",),
                                   entry_tol=(1e-12, 0.0))
    assert checks[0].status == au.PASS and "precision of the entries" in checks[0].detail
    monkeypatch.undo()
    monkeypatch.setattr(discrete, "theorem1_residuals", fake)
    monkeypatch.setattr(wellposedness, "classify_wellposedness",
                        lambda *a, **k: {"class": "well-posed", "rank_deficiency": 0})
    checks, _ = au.theorem1_checks(get_method("gauss-1"), True, False, 20, True, ("particle",),
                                   entry_tol=(au.TEETH, 0.0))
    assert checks[0].status == au.FAIL and "precision of the entries" not in checks[0].detail


def test_the_step_counts_of_the_convergence_runs():
    from ldaspark.lab.theory import audit_checks as ac
    assert [ac._step_counts(p, False) for p in (1, 2, 3, 4, 6)] == [[16, 32, 64], [8, 16, 32], [4, 8, 16],
                                                                   [4, 8, 16], [4, 8, 16]]
    # quick drops the finest run only where the order is high enough (p >= 3) to see it from two
    assert [ac._step_counts(p, True) for p in (1, 2, 3, 6)] == [[16, 32, 64], [8, 16, 32], [4, 8], [4, 8]]


def test_the_convergence_floor_and_constraint_tolerance(monkeypatch):
    from ldaspark.lab.theory import audit_checks as ac
    seen = []

    def fake(tab, scn, Ns, t_end, dps, floor):
        assert t_end == 1                                          # both scenes on [0, 1]
        seen.append((dps, floor))
        return {"scene": scn, "N": Ns, "t_end": t_end, "errors": [1e-3] * len(Ns), "slopes": [4.0],
                "observed": 4.0, "reference": "fake", "max_constraint": 1e3 * 2.0 ** -52}
    monkeypatch.setattr(ac, "observed_order", fake)
    checks, _ = ac.convergence_checks(get_method("gauss-2"), 4, 30, True)
    assert seen[0] == (None, _close(1e-11))                 # float64: 10^(4 - 15)
    assert {c.name: c.status for c in checks}["constraint"] == ac.PASS   # exactly at 1e3 eps
    seen.clear()
    monkeypatch.setattr(ac, "observed_order", lambda *a: dict(fake(*a), max_constraint=1e3 * 1e-30 * 1.5))
    checks, _ = ac.convergence_checks(get_method("gauss-4"), 8, 30, True)
    assert seen[0] == (30, _close(1e-26))                   # at 30 digits: 10^(4 - 30)
    assert {c.name: c.status for c in checks}["constraint"] == ac.FAIL   # above 1e3 x 10^-30


def test_the_particle_reference_runs_twice_the_finest_steps(monkeypatch):
    import numpy as np

    from ldaspark.lab.theory import audit_checks as ac
    runs = []

    class Sol:
        def __init__(self, N):
            self.q = [np.array([1.0 / N])]
            self.v = [np.array([0.0])]
            self.constraint = np.zeros((1, 1))
    monkeypatch.setattr(ac, "_run", lambda tab, sc, N, t_end, dps: runs.append((tab.name, N)) or Sol(N))
    monkeypatch.setattr(ac, "_err", lambda sol, q, v: abs(float(sol.q[-1][0]) - float(q[0])))
    res = ac.observed_order(get_method("gauss-2"), "particle", [4, 8, 16], 1, None, 1e-12)
    ref = [r for r in runs if r[0] != "gauss-2"]
    assert len(ref) == 1 and ref[0][1] == 32 and "32" in res["reference"]


def test_the_order_checks_name_the_first_failing_tree():
    from ldaspark.lab.theory import audit as au
    from ldaspark.lab.theory import audit_checks as ac
    tab = get_method("gauss-1")
    ar, e, _ = au.decide_arith(tab, 30)
    checks, facts = ac.order_checks(ar, e)
    c = {x.name: x for x in checks}["order:A"]
    assert facts["order:A"] == 2 and "first failing tree" in c.detail


def test_an_exact_decision_asked_for_allows_larger_fields_than_auto():
    from ldaspark.lab.theory import audit as au
    from ldaspark.analysis import order_conditions as oc
    tab = get_method("gauss-3", exact=True)
    ok, why = oc.exact_budget(tab, max_degree=au.EXACT_FORCED_MAX_DEGREE)
    assert ok, why
    # Gauss-4's field (degree 32 by the comment's bound) is within the forced budget
    assert au.EXACT_FORCED_MAX_DEGREE >= 32 and au.EXACT_FORCED_SECONDS >= 30


# --- orders ---------------------------------------------------------------------------------------------------
def test_the_asymptotic_window_may_start_at_the_coarsest_step():
    from ldaspark.lab.theory.orders import asymptotic_window
    assert asymptotic_window([0.1, 0.05, 0.025], [1e-2, 1e-3, 1e-4], 1e-12) == (0, 2)
    assert asymptotic_window([0.1, 0.05, 0.025, 0.0125], [1e-2, 1e-3, 1e-15, 1e-15], 1e-12) == (0, 1)


def test_the_ode_reference_counts_exactly_its_evaluations():
    from ldaspark.models.scenes import get_scene
    from ldaspark.lab.theory.orders import ODEReference

    class Counting(ODEReference):
        calls = 0

        def _rhs(self, t, y):
            self.calls += 1
            return super()._rhs(t, y)
    sc = get_scene("particle")
    t0, q0, v0 = sc.initial(20)
    ref = Counting(sc.system, t0, q0, v0, dps=20)
    assert ref.n_rhs == ref.calls > 0


# --- the flow Jacobian's index lists and the tangent read-out -------------------------------------------------
def test_flow_jacobian_indices_by_number():
    import numpy as np

    from ldaspark.core.errors import InputError
    from ldaspark.models.scenes import get_scene
    from ldaspark.analysis.flow_jacobian import _index
    system = get_scene("skate").system                                 # n = 3
    assert _index([0, 2], system, "q") == [0, 2]
    assert _index([np.int64(1), 0], system, "v") == [1, 0]
    assert _index([], system, "q") == []
    for bad in ([3], [-1], [0, 0]):
        with pytest.raises(InputError):
            _index(bad, system, "q")
    with pytest.raises(InputError):
        _index([True], system, "q")                                    # a bool is not an index


def test_flow_jacobian_tangent_and_select_are_read_as_given():
    import types

    import numpy as np

    from ldaspark.core.errors import InputError
    from ldaspark.models.scenes import get_scene
    from ldaspark.analysis.flow_jacobian import _restriction
    system = get_scene("skate").system                                 # 2n = 6
    bk = types.SimpleNamespace(is_mp=False)
    B = np.arange(12.0).reshape(6, 2)
    got, sel = _restriction(system, bk, 0, None, None, None, None, None, B, (1, 4))
    assert np.array_equal(got, B) and sel == [1, 4]
    assert _restriction(system, bk, 0, None, None, None, None, None, None, None) == (None, None)
    for tangent, select in ((np.zeros((5, 2)), [0, 1]), (np.zeros((7, 2)), [0, 1]), (np.zeros(6), [0]),
                            (B, None), (B, [0]), (B, [0, 1, 2])):
        with pytest.raises(InputError):
            _restriction(system, bk, 0, None, None, None, None, None, tangent, select)
