"""The root finder as an option object (``ldaspark.Newton``, ``ldaspark.core.rootfinder``): every
field on every engine is honoured (the counters or the results change as documented) or refused
in one line naming the engine and the field; the old kind names still work."""
import warnings

import numpy as np
import pytest

import ldaspark
from ldaspark import Newton
from ldaspark.core.errors import InputError
from ldaspark.core.rootfinder import SUPPORT

# pendulum, gauss-2, h = 0.5: Newton needs several iterations per step, and "auto" takes fresh
# matrices on both engines, so that the kinds part (measured: generic auto/simplified/full
# njev 90/26/98, iterations 119/291/98; compiled njev 29/20/102, iterations 268/422/102)
RUN = dict(n_steps=20, h=0.5, guard=False)


def run(engine, newton, scene="pendulum", method="gauss-2", **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ldaspark.integrate(scene, method, engine=engine, newton=newton, **dict(RUN, **kw))


@pytest.fixture(scope="module", params=["generic", "compiled"])
def base(request):
    return request.param, run(request.param, "auto")


def test_kinds_change_the_counters_as_documented(base):
    engine, auto = base
    full, simp, mixed = (run(engine, Newton(kind=k)) for k in ("full", "simplified", "mixed"))
    assert auto.status == full.status == simp.status == 0
    # full: a matrix at every iterate; simplified: one matrix per step (fewer matrices, more iterations)
    assert full.njev > simp.njev and full.newton_iterations < simp.newton_iterations
    if engine == "generic":
        # auto takes fresh matrices where the iteration slows: between the two
        assert full.njev > auto.njev > simp.njev and full.newton_iterations < auto.newton_iterations
        assert auto.newton_iterations < simp.newton_iterations
    else:
        # auto on a small mechanical system is the quasi-Newton iteration (issue 48): the multiplier
        # matrix once per step, a Newton matrix only at a step it hands to the Newton chain
        # (measured: 3 Jacobians, 2 fallbacks in 20 steps against simplified's 20)
        assert auto.stats["root_finder"]["runs"] == "quasi" and simp.stats["root_finder"]["runs"] == "simplified"
        assert auto.stats["quasi_steps"] + auto.stats["quasi_fallbacks"] == 20
        assert auto.stats["quasi_steps"] > auto.stats["quasi_fallbacks"] and auto.njev < simp.njev
    # mixed is full Newton in float64 (documented): the same counters
    assert (mixed.njev, mixed.newton_iterations) == (full.njev, full.newton_iterations)
    # the same trajectory to the Newton tolerance (each variant converges to round-off; 20
    # steps of a contracting map: 1e-10 is 1e5 unit round-offs)
    assert np.max(np.abs(full.q[-1] - auto.q[-1])) < 1e-10
    assert full.stats["root_finder"]["kind"] == "full" and auto.stats["root_finder"]["kind"] == "auto"


def test_what_ran_names_full_for_mixed_in_float64():
    """``stats["root_finder"]["runs"]`` names what ran on the compiled engine (module docstring of
    ``core.rootfinder``); "mixed" in float64 is full Newton (its counters are full Newton's,
    ``test_kinds_change_the_counters_as_documented``), but "runs" said "mixed". The kind asked for
    stays "mixed"; control: "full" and "simplified" name themselves."""
    runs = {k: run("compiled", Newton(kind=k), n_steps=3) for k in ("mixed", "full", "simplified")}
    for k, r in runs.items():
        assert r.status == 0 and r.engine == "compiled" and r.stats["root_finder"]["kind"] == k, (k, r.stats)
    assert runs["mixed"].stats["root_finder"]["runs"] == "full"
    assert runs["full"].stats["root_finder"]["runs"] == "full"
    assert runs["simplified"].stats["root_finder"]["runs"] == "simplified"


def test_old_kind_names_map_to_the_option_object(base):
    engine, auto = base
    by_name = run(engine, "full")
    by_object = run(engine, Newton(kind="full"))
    assert (by_name.njev, by_name.newton_iterations) == (by_object.njev, by_object.newton_iterations)
    assert (by_name.njev, by_name.newton_iterations) != (auto.njev, auto.newton_iterations)


def test_tol_and_max_iter_are_honoured(base):
    engine, auto = base
    loose = run(engine, Newton(tol=1e-6))
    assert loose.newton_iterations < auto.newton_iterations
    # tol through integrate's own keyword is the same option; two different values are refused
    same = run(engine, "auto", tol=1e-6)
    assert same.newton_iterations == loose.newton_iterations
    with pytest.raises(InputError, match="disagree"):
        run(engine, Newton(tol=1e-6), tol=1e-8)
    # one iteration per step cannot converge at h = 0.5 (auto needs 119 / 268 for 20 steps)
    short = run(engine, Newton(max_iter=1, kind="full"))
    assert short.status < 0 and auto.status == 0


def test_predictor_zero_changes_the_iterations(base):
    engine, auto = base
    zero = run(engine, Newton(predictor="zero"))
    assert zero.status == 0 and zero.newton_iterations != auto.newton_iterations
    assert zero.stats["root_finder"]["predictor"] == "zero"


def test_quasi_honours_the_predictor_extrapolate():
    """Newton(kind="quasi", predictor="extrapolate") runs the linear extrapolation of the last two
    steps' unknowns (the kernels' code 2), not the quasi iteration's default collocation
    predictor: it was mapped to the default with "auto" (both code 2), accepted and ignored.
    General form (L not quadratic in v); measured 203 iterations with the collocation predictor,
    242 with the extrapolation in 40 steps."""
    from ldaspark.compiled import quasi, runner
    from ldaspark.models.scenes import get_scene
    kw = dict(scene="relativistic", h=0.05, n_steps=40)
    auto = run("compiled", Newton("quasi"), **kw)
    ext = run("compiled", Newton("quasi", predictor="extrapolate"), **kw)
    sc = get_scene("relativistic")
    t0, q0, v0 = sc.initial(None)
    cs = runner.compile_system(sc.system)
    lin = quasi.run_quasi(cs, "gauss-2", float(t0), np.array(q0, float), np.array(v0, float), 0.05, 40, predictor=2)
    col = quasi.run_quasi(cs, "gauss-2", float(t0), np.array(q0, float), np.array(v0, float), 0.05, 40)
    assert lin.stats["newton_iterations"] != col.stats["newton_iterations"]     # the two predictors part here
    assert ext.newton_iterations == lin.stats["newton_iterations"], (ext.newton_iterations, lin.stats)
    assert auto.newton_iterations == col.stats["newton_iterations"]
    assert ext.stats["root_finder"]["runs"] == "quasi"


def test_generic_refuses_what_it_does_not_run():
    for field, val in (("predictor", "extrapolate"), ("linear_solver", "sparse"), ("reuse", True)):
        with pytest.raises(InputError, match=f"engine 'generic' refuses Newton {field}="):
            run("generic", Newton(**{field: val}))
    # what it runs: the dense LU without reuse, the same as its default
    a, b = run("generic", Newton(linear_solver="dense", reuse=False)), run("generic", "auto")
    assert (a.njev, a.newton_iterations) == (b.njev, b.newton_iterations)


def test_compiled_runs_its_kernel_settings():
    auto = run("compiled", "auto")
    prev = run("compiled", Newton(predictor="previous"))
    ext = run("compiled", Newton(predictor=2))                 # the kernels' code for "extrapolate"
    # "auto" runs the quasi iteration here with its collocation predictor; "extrapolate" is run
    # as named, the linear extrapolation (measured 294 iterations against 281)
    assert ext.stats["root_finder"]["predictor"] == "extrapolate" and ext.stats["root_finder"]["runs"] == "quasi"
    assert ext.newton_iterations != auto.newton_iterations
    # on the kernels' Newton the linear extrapolation is the default predictor: the same counters
    s_auto, s_ext = run("compiled", "simplified"), run("compiled", Newton("simplified", predictor="extrapolate"))
    assert (s_ext.newton_iterations, s_ext.njev) == (s_auto.newton_iterations, s_auto.njev)
    assert prev.newton_iterations != auto.newton_iterations
    # matrix reuse where the previous step's matrix contracts fast (the skate at h = 0.1;
    # measured 93 LUs in 100 steps against 100)
    plain = run("compiled", "simplified", scene="skate", h=0.1, n_steps=100)    # one LU per step
    reuse = run("compiled", Newton(reuse=True), scene="skate", h=0.1, n_steps=100)
    assert reuse.stats["reuse_matrix"] is True and plain.stats["reuse_matrix"] is False
    assert reuse.nlu < reuse.stats["steps"] <= plain.nlu            # a step without its own LU
    dense = run("compiled", Newton(linear_solver="dense"), scene="mp-particles-nh", h=0.05)
    sparse = run("compiled", Newton(linear_solver="sparse"), scene="mp-particles-nh", h=0.05)
    assert (dense.stats["linear_solver"], sparse.stats["linear_solver"]) == ("dense", "sparse")
    with pytest.raises(InputError, match="mechanical form"):      # the block LU needs the mechanical form
        run("compiled", Newton(linear_solver="sparse"), scene="relativistic")


def test_the_semi_implicit_kernel_and_the_comparators_refuse_in_one_line():
    for field, val in (("kind", "full"), ("linear_solver", "sparse"), ("reuse", True)):
        with pytest.raises(InputError, match=f"engine 'compiled-lf2' refuses Newton {field}="):
            run("compiled", Newton(**{field: val}), scene="skate", method="lobatto-iiia-iiib-2-leapfrog", h=0.1)
    for field, val in (("kind", "full"), ("predictor", "zero"), ("linear_solver", "sparse"), ("reuse", True)):
        with pytest.raises(InputError, match=f"engine 'comparator' refuses Newton {field}="):
            run("generic", Newton(**{field: val}), scene="skate", method="gauss-irk-2", h=0.1)
    # what they run: tol and max_iter
    lf = run("compiled", "auto", scene="pendulum", method="lobatto-iiia-iiib-2-leapfrog", h=0.1)
    lf0 = run("compiled", Newton(predictor="zero"), scene="pendulum", method="lobatto-iiia-iiib-2-leapfrog", h=0.1)
    assert lf.stats["engine"] == "compiled-lf2" and lf0.newton_iterations > lf.newton_iterations
    cmp_ = run("generic", "auto", scene="pendulum", method="gauss-irk-2")
    cmp1 = run("generic", Newton(max_iter=1), scene="pendulum", method="gauss-irk-2")
    assert cmp_.status == 0 and cmp1.status < 0


def test_a_spark_lobatto2_run_leaves_the_semi_implicit_kernel_for_another_kind():
    # lobatto-iiia-iiib-2 runs the semi-implicit kernel (25); with kind="full" it runs on the SPARK
    # kernel, which honours it (the same method (21))
    a = run("compiled", "auto", scene="pendulum", method="lobatto-iiia-iiib-2", h=0.1)
    b = run("compiled", "full", scene="pendulum", method="lobatto-iiia-iiib-2", h=0.1)
    assert a.stats["kernel"] == "lf2" and b.stats["kernel"] == "spark"
    assert np.max(np.abs(a.q[-1] - b.q[-1])) < 1e-10


def test_bad_fields_are_refused_when_built():
    for kw in ({"kind": "newton"}, {"tol": -1.0}, {"max_iter": 0}, {"predictor": 3}, {"predictor": True},
               {"linear_solver": "lu"}, {"reuse": "yes"}):
        with pytest.raises(InputError):
            Newton(**kw)
    with pytest.raises(InputError, match="newton"):
        ldaspark.integrate("skate", "gauss-1", n_steps=2, h=0.1, newton=3)
    assert Newton("full") == "full" and Newton("full") != "auto" and Newton(predictor=0).predictor == "zero"


def test_every_engine_declares_every_field():
    fields = {"kind", "tol", "max_iter", "predictor", "linear_solver", "reuse"}
    assert all(set(sup) == fields for sup in SUPPORT.values())
    # the quasi-Newton kind runs on the compiled engine only: refused on the generic one
    with pytest.raises(InputError, match="quasi"):
        run("generic", Newton(kind="quasi"))
    assert "quasi" in SUPPORT["compiled"]["kind"] and "quasi" not in SUPPORT["generic"]["kind"]


def test_a_newton_object_takes_the_tol_given_to_integrate(base):
    # integrate(newton=Newton(kind=...), tol=x) is Newton(kind=..., tol=x): the loose tolerance
    # shows in the counters (pendulum, full Newton: 98 / 102 iterations at the default, 81 / 83
    # at 1e-6) and in stats["root_finder"]
    engine, _ = base
    full = run(engine, Newton(kind="full"))
    given = run(engine, Newton(kind="full"), tol=1e-6)
    inside = run(engine, Newton(kind="full", tol=1e-6))
    assert given.newton_iterations == inside.newton_iterations < full.newton_iterations
    assert given.stats["root_finder"]["tol"] == 1e-6 and full.stats["root_finder"]["tol"] is None


def test_a_comparator_honours_tol():
    # the comparator engine receives the tolerance (gauss-irk-2 on the pendulum at h = 0.5: 109
    # iterations at the default, 80 at 1e-4; the end points agree to ~tol^2)
    tight = run("generic", "auto", scene="pendulum", method="gauss-irk-2")
    loose = run("generic", Newton(tol=1e-4), scene="pendulum", method="gauss-irk-2")
    assert tight.status == loose.status == 0
    assert loose.newton_iterations < tight.newton_iterations
    assert 0 < np.max(np.abs(np.asarray(loose.q[-1], float) - np.asarray(tight.q[-1], float))) < 1e-4


def test_the_quasi_kind_honours_max_iter():
    # newton kind "quasi" on the compiled engine: its fallback Newton chain takes max_iter too;
    # one iteration cannot solve a pendulum step at h = 0.5 (quasi converges with the default 50)
    ok = run("compiled", Newton(kind="quasi"))
    short = run("compiled", Newton(kind="quasi", max_iter=1))
    assert ok.status == 0 and ok.stats["root_finder"]["kind"] == "quasi"
    assert short.status < 0 and "step 0" in short.message


def test_max_iter_limits_each_attempt_and_the_compiled_chain_has_more_of_them():
    """Newton.max_iter said "iterations per step before the step fails", which only the generic
    engine does: on the compiled engine each attempt of its chain gets max_iter, the last being the
    generic full Newton step (``compiled.rescue``). Pendulum, gauss-2, h = 0.2, max_iter = 6: the
    generic "auto" step 0 stops at 6 iterations (residual ~3e-10); the compiled run converges with up
    to 16 iterations in a step (quasi-Newton, simplified, full Newton: 6 + 6 + 4 measured); the
    docstring now says so."""
    opts = dict(n_steps=30, h=0.2, guard=False)
    gen = ldaspark.integrate("pendulum", "gauss-2", engine="generic", newton=Newton(max_iter=6), **opts)
    assert gen.status == -1 and "after 6 iterations" in gen.message
    com = ldaspark.integrate("pendulum", "gauss-2", engine="compiled", newton=Newton(max_iter=6), **opts)
    assert com.status == 0 and 6 < com.stats["max_iterations"] <= 3 * 6
    doc = " ".join(Newton.__doc__.split())
    assert "each limited to max_iter" in doc and "Iterations per step before the step fails" not in doc
