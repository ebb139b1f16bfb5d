"""Rules of ``ldaspark.lab.reports.systems`` fed inputs on which the right rule and a plausible neighbour give
different answers (a wrong comparison, one side of a pair, a ratio upside down, a field left
out, a mutated computation). The expensive inner computations are replaced by small
stand-ins where the rule under test is what is applied to their results."""
import json
import os
from types import SimpleNamespace
import numpy as np
import pytest
from ldaspark.core.errors import InputError, LdasparkError
from ldaspark.lab.reports import peers, summary, systems
from hypothesis import given, settings
from hypothesis import strategies as st


# =============================================================================================
# systems
# =============================================================================================
def _quarter_series(q0, q3, n=100):
    """|e| = q0 on the first three quarters, q3 on the last (boundedness's quarters overlap by one
    sample: the last quarter starts at index 3n/4)."""
    e = np.full(n, q0)
    e[3 * n // 4:] = q3
    return np.linspace(0.0, 1.0, n), e


def _inv(bounded=True, roundoff=False, drift=False, mx=1e-6, ratio=1.0):
    return {"max": mx, "quarters": [mx, mx, mx, mx], "ratio": ratio, "roundoff": roundoff, "bounded": bounded,
            "drift": drift, "t": [0.0, 1.0, 2.0], "abs_err": [0.0, 1e-9, mx]}


def _sysrec(name, g2, l3, ctrl, orders=None, kmax=(1e-16, 2e-16, 1e-15), kbound=1e-14, cost=10.0):
    o = orders or {m: {"claimed": p, "q": float(p), "v": float(p)} for m, p in systems.ORDER_METHODS}

    def run(inv, k):
        return {"T": 500.0, "h": 0.1, "steps": 5000, "status": 0, "t_end_reached": 500.0, "max_abs_k": k,
                "k_bound": kbound, "invariants": inv}
    return {"name": name, "n": 3, "m": 1, "form": "mechanical", "description": "d", "source": "s",
            "invariants": list(g2), "closed_forms": [], "from_mechanics": name != "contact-oscillator",
            "t_compile": 0.5, "us_per_step_gauss2": cost, "order_reference": "closed form", "orders": o,
            "runs": {"gauss-2": run(g2, kmax[0]), "lobatto-iiia-iiib-3": run(l3, kmax[1]), "euler-i": run(ctrl, kmax[2])}}


def test_bounded_drift_and_roundoff_thresholds():
    base = 2.0 ** -10
    for ratio, bounded, drift in ((1.5, True, False), (1.75, False, False), (2.0, False, True), (1.0, True, False)):
        r = systems._bounded(*_quarter_series(base, ratio * base), 100, 1.0)
        assert (r["bounded"], r["drift"], r["roundoff"]) == (bounded, drift, False) and r["ratio"] == ratio
    # round-off: max <= 100 eps sqrt(N) (1 + |I0|); here N = 64, I0 = -3: 3200 eps
    lim = 100 * systems.EPS * 8 * 4
    at = systems._bounded(*_quarter_series(lim / 4, lim), 64, -3.0)
    above = systems._bounded(*_quarter_series(lim / 4, lim * 1.0001), 64, -3.0)
    assert at["roundoff"] and at["bounded"] and not at["drift"] and at["max"] == lim
    assert not above["roundoff"] and not above["bounded"] and above["drift"]
    # a first quarter of zeros: ratio infinite, reported as None, a drift
    z = systems._bounded(*_quarter_series(0.0, 1.0), 100, 0.0)
    assert z["ratio"] is None and z["drift"] and not z["bounded"]


def test_row_verdict_needs_both_symmetric_methods():
    rec = _sysrec("suslov", {"E": _inv(roundoff=True, mx=1e-15), "J": _inv(bounded=False, mx=3e-3)},
                  {"E": _inv(roundoff=False, mx=1e-9), "J": _inv(mx=2e-3)},
                  {"E": _inv(drift=True, ratio=4.25), "J": _inv()}, kmax=(2e-15, 7e-15, 0.5))
    row = systems._row(rec)
    assert "E: 1.0e-09 (bounded)" in row[-2] and "J: 3.0e-03 (NOT bounded)" in row[-2]
    assert row[-1] == "drift in E (ratio 4.25)" and row[7] == "7.0e-15"           # Euler I's k left out
    rec["runs"]["lobatto-iiia-iiib-3"]["invariants"]["E"]["roundoff"] = True
    assert "E: 1.0e-09 (round-off)" in systems._row(rec)[-2]
    rec["runs"]["euler-i"]["invariants"]["E"]["drift"] = False
    assert systems._row(rec)[-1].startswith("no drift (max 1.0e-06, 1.0e-06")


def test_observations_name_what_fails_and_only_that():
    good = _sysrec("chaplygin-sleigh", {"E": _inv()}, {"E": _inv()}, {"E": _inv()}, cost=5.0)
    bad = _sysrec("suslov", {"E": _inv()}, {"E": _inv(bounded=False)}, {"E": _inv(drift=True, ratio=3.0)},
                  orders={"gauss-2": {"claimed": 4, "q": 4.25, "v": 3.5}, "lobatto-iiia-iiib-2":
                          {"claimed": 2, "q": None, "v": 2.0}}, kmax=(1.0, 0.0, 0.0), cost=40.0)
    mid = _sysrec("tilted-disk", {"E": _inv(bounded=False)}, {"E": _inv()}, {"E": _inv(drift=True)}, cost=20.0)
    res = {"chaplygin-sleigh": good, "suslov": bad, "tilted-disk": mid}
    obs = systems._observations(res, list(res))
    assert obs[0] == ("* Symmetric methods, long-time: NOT bounded: suslov lobatto-iiia-iiib-3 E over [0, 500] "
                      "(max per quarter 1.0e-06, 1.0e-06, 1.0e-06, 1.0e-06), tilted-disk gauss-2 E over [0, 500] "
                      "(max per quarter 1.0e-06, 1.0e-06, 1.0e-06, 1.0e-06).")
    assert obs[1].startswith("  `suslov`: the Suslov flow") and not obs[2].startswith("  `")   # no note for the disk
    assert obs[2].startswith("* Control (Euler I) drifts on `suslov`, `tilted-disk`; no drift on `chaplygin-sleigh`")
    assert obs[3] == "* Orders: off by more than 0.3: suslov gauss-2 3.50, suslov lobatto-iiia-iiib-2 -."
    assert obs[4] == "* Constraint: max |k| ABOVE the round-off bound on suslov."
    assert obs[5].startswith("* Compiled cost per Gauss-2 step from 5 us (`chaplygin-sleigh`) to 40 us (`suslov`)")
    only = systems._observations({"chaplygin-sleigh": good}, ["chaplygin-sleigh"])
    assert only[0].endswith("every invariant bounded or at round-off.")
    assert only[1].startswith("* Control (Euler I) drifts on ; no drift on `chaplygin-sleigh`: there the flow")
    assert only[2].startswith("* Orders: every") and only[3].startswith("* Constraint: max |k| below")
    drifting = systems._observations({"tilted-disk": mid}, ["tilted-disk"])
    assert drifting[1] == "* Control (Euler I) drifts on `tilted-disk`."


def test_observables_series_and_initial_state(monkeypatch):
    sc = SimpleNamespace(params={"rho": 2})
    assert systems._observables("chaplygin-sleigh", sc) == {}
    (f,) = systems._observables("ball-turntable-rheonomic", sc).values()
    assert f(None, np.array([[3.0, 4.0, 9.0]]), None).tolist() == [3.0]
    sc = SimpleNamespace(invariant_values=lambda t, q, v: {"E": np.array([2.0, 2.5, 1.0])})
    res = SimpleNamespace(t=np.arange(3.0), q=np.array([[3.0, 4.0]] * 3), v=None)
    out, I0 = systems._series(sc, res, {"r": lambda t, q, v: t * 2})
    assert out["E"].tolist() == [0.0, 0.5, -1.0] and I0 == {"E": 2.0, "r": 0.0} and out["r"].tolist() == [0, 2, 4]
    import ldaspark.models.scenes as scenes
    monkeypatch.setattr(scenes, "get_scene", lambda name: SimpleNamespace(initial=lambda: (0.0, [1], (0, 0, 0, 0, 0))))
    assert systems._initial("tilted-disk")[2] == [0, 0, 0, 0.3, 0]
    assert systems._initial("suslov")[2] == (0, 0, 0, 0, 0)


def test_thin_plot_markdown_and_json(tmp_path):
    inv = _inv()
    inv["t"], inv["abs_err"] = list(np.arange(250.0)), list(np.arange(250.0))
    rec = _sysrec("suslov", {"E": inv}, {"E": _inv()}, {"E": _inv()})
    th = systems._thin(rec, points=100)
    assert th["runs"]["gauss-2"]["invariants"]["E"]["t"] == list(np.arange(0.0, 250.0, 3.0))
    assert len(rec["runs"]["gauss-2"]["invariants"]["E"]["t"]) == 250                  # a copy
    assert th["runs"]["euler-i"]["invariants"]["E"]["t"] == [0.0, 1.0, 2.0]
    res = {"suslov": rec, "contact-oscillator": _sysrec("contact-oscillator", {"E": _inv()}, {"E": _inv()},
                                                        {"E": _inv()})}
    j = systems._json(res, None)
    assert list(j["systems"]) == ["suslov", "contact-oscillator"] and j["bicycle"] is None
    assert systems._json(res, {"error": "x"})["bicycle"] == {"error": "x"}
    md = systems.markdown(res, clock=SimpleNamespace(wall=3.0, cpu=4.0), command="cmd")
    assert "_Written by `cmd`: 3 s wall, 4 s CPU" in md
    assert "(L and k)" in md and "via `LagrangianSystem.from_mechanics`" in md
    assert "_Written" not in systems.markdown(res)
    figs = []
    import pytest as _pt
    mp = _pt.MonkeyPatch()
    mp.setattr(systems, "atomic_save_figure", lambda fig, path, dpi: figs.append((fig, path)))
    try:
        systems.plot(res, "p1.png")
        systems.plot({"suslov": rec}, "p2.png")
    finally:
        mp.undo()
    (two, p2), (one, p1) = figs
    assert p2 == "p1.png" and len(two.axes) == 2 and len(one.axes) == 1
    # one panel per system, each as tall: the figure grows with the number of systems
    assert two.get_size_inches()[1] == 2 * one.get_size_inches()[1]
    ax = one.axes[0]
    assert "suslov" in ax.get_title() and ax.get_xlabel() == "t" and ax.get_yscale() == "log"
    lines = ax.get_lines()
    assert len(lines) == 3 and [ln.get_linestyle() for ln in lines] == ["-", "--", ":"]
    # |I - I0| floored at 1e-17 for the log axis (the zero at t = 0 is drawn at the floor, not dropped)
    y = lines[1].get_ydata()
    assert y[0] == 1e-17 and y[-1] == 1e-6 and list(lines[1].get_xdata()) == [0.0, 1.0, 2.0]


def test_jobs_build_and_the_command_line(monkeypatch, tmp_path):
    here = os.path.join(os.path.dirname(systems.__file__), "systems_bicycle.py")
    assert systems.bicycle_available() == os.path.exists(here)
    monkeypatch.setattr(systems, "bicycle_available", lambda: False)
    assert systems.jobs(systems=("suslov",), t_long=7.0) == [(("suslov",), "system_job", ("suslov", 7.0), 4.0)]
    monkeypatch.setattr(systems, "bicycle_available", lambda: True)
    both = systems.jobs(systems=("suslov",))
    assert both[-1][:2] == (("bicycle",), "bicycle_job")
    # the scheduler's cost estimates: positive, the bicycle section the longest job
    assert all(c > 0 for *_, c in both) and both[-1][3] > both[0][3]
    ran = []

    def job(name, t_long):
        ran.append((name, t_long))
        return _sysrec(name, {"E": _inv()}, {"E": _inv()}, {"E": _inv()})
    monkeypatch.setattr(systems, "system_job", job)
    monkeypatch.setattr(systems, "bicycle_job", lambda outdir: {"markdown": "bike here", "json": {"b": 1}})
    monkeypatch.setattr(systems, "plot", lambda res, path: ran.append(("plot", sorted(res))))
    out = tmp_path / "rep"
    (out / "figures").mkdir(parents=True)
    res = systems.build(str(out), systems=("suslov",), t_long=9.0)
    assert set(res) == {("suslov",), ("bicycle",)} and ran == [("suslov", 9.0), ("plot", ["suslov"])]
    assert "bike here" in (out / systems.REPORT).read_text()
    assert json.loads((out / systems.JSON).read_text())["bicycle"] == {"b": 1}
    built = []
    monkeypatch.setattr(systems, "build", lambda outdir, s, t: built.append((s, t)))
    args = SimpleNamespace(outdir="o", systems=" suslov, ,tilted-disk", t_long=1.0)   # 1.0 = 10 h: allowed
    assert systems.run(args) == 0 and built == [(("suslov", "tilted-disk"), 1.0)]
    assert systems.run(SimpleNamespace(outdir="o", systems=None, t_long=50.0)) == 0 and built[-1][0] == systems.SYSTEMS
    with pytest.raises(InputError, match="unknown system"):
        systems.run(SimpleNamespace(outdir="o", systems="suslov,bogus", t_long=50.0))
    for bad in (0.99, float("nan"), float("inf")):
        with pytest.raises(InputError, match="--t-long"):
            systems.run(SimpleNamespace(outdir="o", systems=None, t_long=bad))
    monkeypatch.setattr(systems, "build", lambda outdir: built.append(("default", outdir)))
    systems.run_default("z")
    assert built[-1] == ("default", "z")


def _close(x, rel=1e-9, abs=0.0):
    """pytest.approx without its absolute default of 1e-12, which would equate any two tiny residuals."""
    return pytest.approx(x, rel=rel, abs=abs)


@settings(deadline=None)
@given(first=st.floats(1e-8, 1e-3), factor=st.floats(0.05, 20.0))
def test_boundedness_is_last_quarter_over_first(first, factor):
    import numpy as np

    from ldaspark.lab.reports.energy import boundedness
    from ldaspark.lab.reports.systems import _bounded, BOUNDED_RATIO, DRIFT_RATIO
    n = 401
    t = np.linspace(0.0, 1.0, n)
    e = np.full(n, first)
    e[3 * n // 4 + 2:] = first * factor                               # only the last quarter changes
    e[0] = 0.0
    b = boundedness(t, e)
    # the last quarter's slice starts two samples before the change: its max is max(factor, 1) x first
    assert b["last_over_first_quarter"] == _close(max(factor, 1.0), rel=1e-12)
    r = _bounded(t, e, n - 1, 0.0)          # round-off threshold 100 eps sqrt(400) ~ 4e-13 < first
    assert not r["roundoff"]
    assert r["bounded"] == (b["last_over_first_quarter"] <= BOUNDED_RATIO)
    assert r["drift"] == (b["last_over_first_quarter"] >= DRIFT_RATIO)
