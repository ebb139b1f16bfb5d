"""Every mpmath run has a work bound fixed before it starts (docs/reliability.md "Every unit of
work is bounded"): ``n_steps * mp_step_cost(dps) <= MP_WORK_MAX``, checked in
``validate.step_advances`` (the time grid of ``ldaspark.integrate`` and the CLI); a refusal names
the estimate, the limit and what to reduce."""
import time

import pytest

import ldaspark
from ldaspark.core.errors import InputError
from ldaspark.cli import main
from ldaspark.core import validate as V


def _fits(dps):
    return int(V.MP_WORK_MAX // V.mp_step_cost(dps))


@pytest.mark.parametrize("dps", [16, 50, 300, 1000, 2000])
def test_the_bound_is_two_sided_at_each_precision(dps):
    n = _fits(dps)
    assert V.check_work(n, dps) <= V.MP_WORK_MAX          # the largest run that fits is accepted
    with pytest.raises(InputError) as ei:
        V.check_work(n + 1, dps)                           # one step more is refused
    msg = str(ei.value)
    assert f"dps = {dps}" in msg and "estimated work" in msg and f"{V.MP_WORK_MAX:.3g}" in msg
    assert f"use at most {n} steps" in msg


def test_the_cost_grows_with_the_digits_and_float64_is_not_bounded_here():
    costs = [V.mp_step_cost(d) for d in (16, 100, 500, 1000, 2000)]
    assert costs == sorted(costs) and 1 < costs[0] < 1.1 and 12 < costs[-1] < 14
    assert V.check_work(V.MAX_STEPS, None) == V.MAX_STEPS     # float64: MAX_STEPS alone


def test_the_api_refuses_dps_2000_with_a_million_steps_before_any_step():
    t = time.process_time()
    with pytest.raises(InputError, match=r"1000000 steps at dps = 2000 .* use at most \d+ steps"):
        ldaspark.integrate("particle", "gauss-2", t0=0, h="0.001", n_steps=10 ** 6, dps=2000, engine="generic")
    # negative control: the same call at float64 is not refused by this bound (it is not run:
    # n_steps beyond MAX_STEPS is refused by the step-count check instead)
    with pytest.raises(InputError, match="n_steps must be"):
        ldaspark.integrate("particle", "gauss-2", t0=0, h="0.001", n_steps=V.MAX_STEPS + 1, engine="generic")
    # refused at the boundary: no step ran (a step at 2000 digits costs ~15 ms)
    assert time.process_time() - t < 5


def test_a_run_within_the_bound_runs():
    res = ldaspark.integrate("particle", "gauss-1", t0=0, h="0.1", n_steps=2, dps=2000, engine="generic")
    assert len(res.t) == 3


def test_the_cli_refuses_in_one_line(capsys, tmp_path):
    rc = main(["integrate", "particle", "gauss-1", "--h", "0.1", "--t-end", "1e6", "--dps", "2000",
               "--out", str(tmp_path / "o.json")])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.splitlines()) == 1 and "estimated work" in err and "use at most" in err
    assert not (tmp_path / "o.json").exists()


def test_a_large_stage_system_at_2000_digits_is_refused_before_any_step(capsys, tmp_path):
    """mp-particles-nh (n = 7, m = 1) with gauss-10 takes ~30 s a step at 2000 digits: 150000
    steps (~54 days) are refused in one line naming the estimate, the limit and what to reduce."""
    t = time.process_time()
    with pytest.raises(InputError) as ei:
        ldaspark.integrate("mp-particles-nh", "gauss-10", n_steps=150000, h=0.1, dps=2000)
    msg = str(ei.value)
    fits = int(V.MP_WORK_MAX // V.mp_step_cost(2000, 10, 7, 1))
    assert len(msg.splitlines()) == 1 and "s = 10 stages, n = 7, m = 1" in msg and "87 unknowns" in msg
    assert "estimated work of 2.8e+08" in msg and f"limit {V.MP_WORK_MAX:.3g}" in msg
    assert f"use at most {fits} steps" in msg and "fewer stages" in msg and 500 < fits < 3000
    # negative control: the digits alone (the old estimate) accepted this run
    assert V.check_work(150000, 2000) <= V.MP_WORK_MAX
    rc = main(["integrate", "mp-particles-nh", "gauss-10", "--h", "0.1", "--t-end", "15000", "--dps", "2000",
               "--out", str(tmp_path / "o.json")])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.splitlines()) == 1 and "87 unknowns" in err and "use at most" in err
    assert not (tmp_path / "o.json").exists()
    assert time.process_time() - t < 5                   # refused before a step (one is ~30 s)


def test_a_small_run_of_the_large_system_is_accepted_and_the_bound_is_two_sided():
    # control of the refusal: a short low-precision run of the same system runs
    res = ldaspark.integrate("mp-particles-nh", "gauss-2", n_steps=2, h=0.1, dps=30, engine="generic")
    assert res.success and len(res.t) == 3
    fits = int(V.MP_WORK_MAX // V.mp_step_cost(2000, 10, 7, 1))
    assert V.check_work(fits, 2000, s=10, n=7, m=1) <= V.MP_WORK_MAX
    with pytest.raises(InputError, match=f"use at most {fits} steps"):
        V.check_work(fits + 1, 2000, s=10, n=7, m=1)


def test_the_estimate_grows_with_the_stages_and_the_coordinates():
    by_s = [V.mp_step_cost(2000, s, 7, 1) for s in (4, 6, 10, 20)]
    by_n = [V.mp_step_cost(2000, 10, n, 1) for n in (3, 7, 20, 50)]
    assert by_s == sorted(by_s) and len(set(by_s)) == 4 and by_n == sorted(by_n) and len(set(by_n)) == 4
    # the calibration: the robot with gauss-3 is one step of the digits' cost; a smaller system
    # keeps that cost (its fixed per-step work does not shrink); gauss-4 on mp-particles-nh is
    # 12-14 robot steps at 2000 digits (measured) and gauss-10 ~150
    d = V.mp_step_cost(2000)
    assert V.mp_step_cost(2000, 3, 4, 2) == d == V.mp_step_cost(2000, 1, 3, 1)
    assert 11 < V.mp_step_cost(2000, 4, 7, 1) / d < 15 and 100 < V.mp_step_cost(2000, 10, 7, 1) / d < 200
    # control: the digits alone do not see the stages (the old estimate, kept without s, n, m)
    assert V.mp_step_cost(2000, None, 7, 1) == V.mp_step_cost(2000, 20, 7, None) == d


def test_a_float64_generic_run_is_bounded_and_the_compiled_one_by_max_steps():
    """The float64 generic engine takes 1-2 ms a step (Python loops): 10**9 steps (MAX_STEPS,
    weeks) were accepted; refused now before any step, naming the compiled engine, while the
    largest run that fits the bound is accepted by the check (two-sided) and the same step count
    on the compiled engine is not refused by it."""
    s, n, m = 2, 3, 1                                      # the particle with gauss-2
    cost = V.FLOAT_GENERIC_STEP_COST * V.mp_step_cost(0, s, n, m)
    fits = int(V.MP_WORK_MAX // cost)
    assert 10 ** 6 < fits < 10 ** 8                        # hours of generic steps, not weeks
    assert V.check_work(fits, None, s=s, n=n, m=m, float_generic=True) <= V.MP_WORK_MAX
    with pytest.raises(InputError, match=r"float64 on the generic engine.*engine='compiled'"):
        V.check_work(fits + 1, None, s=s, n=n, m=m, float_generic=True)
    assert V.check_work(V.MAX_STEPS, None, s=s, n=n, m=m) == V.MAX_STEPS
    t = time.process_time()
    with pytest.raises(InputError, match=rf"{V.MAX_STEPS} steps in float64 on the generic engine"):
        ldaspark.integrate("particle", "gauss-2", t0=0, h=1e-6, n_steps=V.MAX_STEPS, engine="generic",
                           save_every=10 ** 6)
    assert time.process_time() - t < 5
