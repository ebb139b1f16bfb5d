"""The step-acceptance guard (``ldaspark.core.guard``) on the members of ``run_many`` (and the
deprecated ``ensemble_integrate``): every member is judged as its single ``integrate`` run is, on
its saved samples and, for save_every > 1, on the prefix run again with every step kept."""
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import ldaspark
from ldaspark.core import guard
from ldaspark.core.errors import InputError
from ldaspark.ensemble import RunSpec, run_many
from tests.core.test_guard import START, WELL

Q0, V0 = [[1.2, 0.0], [1.1, 0.0]], [[1.5, 0.0], [1.4, 0.0]]
KEYS = ("guard", "guard_flagged", "guard_confirmed", "guard_unverified")


def _single(q0, v0, every):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ldaspark.integrate(WELL, "gauss-1", engine="compiled",
                                  **dict(START, q0=q0, v0=v0, n_steps=12, save_every=every))


@pytest.mark.parametrize("every", [1, 4])
def test_run_many_members_get_the_guard_of_their_single_runs(every):
    # the double well at h = 2.5 has steps the guard flags (energy changes beyond the previous
    # steps') and confirms (the safe start finds the same root): the counters are those of the
    # single runs, also when the flagged steps fall between saved samples (every = 4)
    singles = [_single(q, v, every) for q, v in zip(Q0, V0)]
    assert sum(r.stats["guard_flagged"] for r in singles) >= 1
    spec = RunSpec(WELL, "gauss-1", START["t0"], Q0, V0, START["h"], 12, every)
    with ThreadPoolExecutor(1) as ex:
        (ens,) = run_many([spec], where=ex)
        (off,) = run_many([spec], where=ex, guard=False)
    for st, one in zip(ens.stats, singles):
        assert {k: st[k] for k in KEYS} == {k: one.stats[k] for k in KEYS}
    assert [st["guard"] for st in off.stats] == [False, False]
    assert np.array_equal(ens.q, off.q)


def test_run_many_stops_on_a_member_with_another_root(monkeypatch):
    # a safe root that never agrees (negative control of the wiring): the flagged step of the
    # member is reported with the spec and the member named; guard=False returns the run
    monkeypatch.setattr(guard, "same_root", lambda *a: False)
    spec = RunSpec(WELL, "gauss-1", START["t0"], Q0, V0, START["h"], 12)
    with ThreadPoolExecutor(1) as ex:
        with pytest.raises(guard.RootMismatchError, match=r"run_many: spec 0 \(gauss-1\), member 0: step \d+ "):
            run_many([spec], where=ex)
        (off,) = run_many([spec], where=ex, guard=False)
    assert off.q.shape == (2, 13, 2)


def test_run_many_guard_is_a_flag():
    spec = RunSpec(WELL, "gauss-1", START["t0"], Q0, V0, START["h"], 3)
    with pytest.raises(InputError, match="guard"):       # checked before any work is sent
        run_many([spec], guard="yes")


def test_the_guard_reruns_a_member_from_its_own_t0():
    # the guard's rerun of a member (every step kept, to locate a flagged interval) is the
    # member's own run from t0: on a rheonomic system (L and k depend on t) from t0 != 0, the
    # rerun's first steps equal those of the member run with every step kept, bit for bit
    from verification.general_fixtures import rheonomic_initial, rheonomic_system
    t0, q0, v0 = rheonomic_initial()
    sysm = rheonomic_system()
    q0, v0 = np.asarray(q0, float), np.asarray(v0, float)
    assert float(t0) != 0.0
    sampled = RunSpec(sysm, "gauss-2", t0, [q0], [v0], 0.1, 8, 4)
    every = RunSpec(sysm, "gauss-2", t0, [q0], [v0], 0.1, 8, 1)
    with ThreadPoolExecutor(1) as ex:
        (ens,) = run_many([every], where=ex, guard=False)
        run_many([sampled], where=ex, guard=False)            # sets up the path its tasks ran
    again = sampled.rerun(q0, v0, 8)
    assert np.array_equal(np.asarray(again.t), ens.t) and np.array_equal(np.asarray(again.q), ens.q[0])


@pytest.mark.parametrize("every", [1, 3])
def test_run_many_judges_comparator_members_as_their_single_runs(every):
    # guard=True on a spec of a comparator of Fig. 4 (the leapfrog form of (25)) was accepted and
    # not run: its members said guard: False, while the single integrate run of the same member
    # judges its steps with the comparator's own step (``ComparatorSafeRoot``). On the double well
    # at h = 0.8 the single runs flag and confirm 3 and 4 steps in 6; the members' counters are
    # theirs (integers compared exactly: the flags are decided on the same float64 energies, the
    # member being its single run bit for bit), also with samples 3 steps apart (the guard's rerun).
    # Control: guard=False says guard: False.
    method, kw = "lobatto-iiia-iiib-2-leapfrog", dict(START, h=0.8, n_steps=6, save_every=every)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        singles = [ldaspark.integrate(WELL, method, engine="compiled", **dict(kw, q0=q, v0=v)) for q, v in zip(Q0, V0)]
    assert [r.stats["guard_flagged"] for r in singles] == [3, 4]
    spec = RunSpec(WELL, method, START["t0"], Q0, V0, 0.8, 6, every)
    with ThreadPoolExecutor(1) as ex:
        (ens,) = run_many([spec], where=ex)
        (off,) = run_many([spec], where=ex, guard=False)
    assert [{k: st[k] for k in KEYS} for st in ens.stats] == [{k: r.stats[k] for k in KEYS} for r in singles]
    assert [st["guard"] for st in off.stats] == [False, False]
    assert np.array_equal(ens.q, np.array([r.q for r in singles]))


def test_run_many_stops_on_a_comparator_member_with_another_root(monkeypatch):
    # the wiring of the comparator's safe root: one that never agrees names the spec and member
    monkeypatch.setattr(guard, "same_root", lambda *a: False)
    spec = RunSpec(WELL, "lobatto-iiia-iiib-2-leapfrog", START["t0"], Q0, V0, 0.8, 6)
    with ThreadPoolExecutor(1) as ex:
        with pytest.raises(guard.RootMismatchError, match=r"run_many: spec 0 \(lobatto-iiia-iiib-2-leapfrog\), "
                                                          r"member 0: step \d+ "):
            run_many([spec], where=ex)
