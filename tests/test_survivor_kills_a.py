"""Tests answering surviving generated mutants (``ldaspark mutants --generated``) in
executors.py, core/validate.py, lab/reports/stability_stiff.py, lab/reports/peers.py,
lab/claims/ledger.py and lab/claims/claims_general.py: each checks one rule on an input where the
mutated computation gives another verdict or number. The expensive computations (integrations,
BVP solves, timed loops) are replaced by stand-ins (monkeypatch) where the rule under test is
the reduction or choice made on their results. Cost: ~2 s."""
import concurrent.futures as cf
import json
import os
import pathlib
import types

import mpmath
import numpy as np
import pytest

from ldaspark.core.errors import InputError
from ldaspark import executors as workers
from ldaspark.executors import MAX_CHECKPOINT_DEPTH, MAX_CHECKPOINT_LINE, Checkpoint

ROOT = pathlib.Path(__file__).resolve().parents[1]
KEY = bytes(range(32))


# --- executors.py ----------------------------------------------------------------------------
def test_local_place_with_two_jobs_is_a_process_pool_of_two():
    place = workers._Place("local", 2, None)
    try:
        assert place.local_pool
        assert not isinstance(place.executor, workers.InlineExecutor)
        assert place.executor._max_workers == 2
    finally:
        place.close()


def test_renewed_local_pool_keeps_the_number_of_workers():
    place = workers._Place(None, 2, None)
    try:
        place.renew()
        assert place.local_pool
        assert place.executor._max_workers == 2
    finally:
        place.close()


def test_stop_pool_shuts_the_pool_down():
    for ex in (workers.make_process_pool(1), cf.ProcessPoolExecutor(1)):
        workers._stop_pool(ex)
        with pytest.raises(RuntimeError):
            ex.submit(int, 1)


def test_stop_pool_uses_the_pools_own_terminate_workers():
    calls = []

    class Pool:
        def terminate_workers(self):
            calls.append("terminate_workers")

        def shutdown(self, wait=True, cancel_futures=False):
            calls.append("shutdown")

    workers._stop_pool(Pool())
    assert calls == ["terminate_workers"]


def test_source_fingerprint_does_not_depend_on_the_order_of_config_keys():
    a = workers.source_fingerprint({"a": 1, "b": 2})
    b = workers.source_fingerprint({"b": 2, "a": 1})
    assert a == b
    assert a != workers.source_fingerprint({"a": 1, "b": 3})


def test_read_key_returns_the_32_bytes_of_a_good_key_file(tmp_path):
    path = tmp_path / "k"
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    os.write(fd, KEY.hex().encode() + b"\n")
    os.close(fd)
    assert workers._read_key(str(path)) == KEY


@pytest.mark.parametrize("text, depth", [("[[1]]", 2), ('{"a": [1, {"b": "]]"}]}', 3), ("1", 0), ("[]", 1)])
def test_json_depth_counts_nesting_from_the_first_character(text, depth):
    assert workers._json_depth(text) == depth


def test_record_mac_does_not_depend_on_dict_order(tmp_path):
    cp = Checkpoint(tmp_path / "c.jsonl", "fp", key=KEY)
    assert cp._mac("u", {"a": 1, "b": 2}) == cp._mac("u", {"b": 2, "a": 1})
    assert workers._canonical({"b": 2, "a": 1}) == b'{"a":1,"b":2}'


def test_writer_bound_admits_a_value_of_exactly_the_bound(tmp_path):
    cp = Checkpoint(tmp_path / "c.jsonl", "fp", key=KEY)
    n = MAX_CHECKPOINT_LINE - 200                 # the canonical text: the string and its 2 quotes
    assert cp._why_not("u", "x" * (n - 2), None) == ""
    assert "more than the reader's bound" in cp._why_not("u", "x" * (n - 1), None)


def test_reader_depth_bound_admits_a_line_of_exactly_the_bound(tmp_path):
    """A line nested MAX_CHECKPOINT_DEPTH deep passes the reader's parse bound; its value (one
    level less) is then refused by the writer's tighter bound, with that bound's reason."""
    cp = Checkpoint(tmp_path / "c.jsonl", "fp", key=KEY)
    value = 0
    for _ in range(MAX_CHECKPOINT_DEPTH - 1):
        value = [value]
    raw = cp._line("u", value).encode()
    assert workers._json_depth(raw.decode()) == MAX_CHECKPOINT_DEPTH
    assert cp._parse(raw, None) == (None, "the value is nested more deeply than the reader's bound")
    deeper = cp._line("u", [value]).encode()
    assert cp._parse(deeper, None) == (None, "nested more deeply than the reader's bound")


def test_checkpoint_line_of_exactly_the_reader_bound_is_resumed(tmp_path):
    path = tmp_path / "c.jsonl"
    cp = Checkpoint(path, "fp", key=KEY, say=lambda m: None)
    line = cp._line("u", {"x": 1}).rstrip("\n")
    line = line[:-1] + " " * (MAX_CHECKPOINT_LINE - len(line) - 1) + "}\n"    # JSON whitespace
    assert len(line.encode()) == MAX_CHECKPOINT_LINE
    path.write_text(json.dumps({"fingerprint": "fp"}) + "\n" + line + cp._line("w", 2))
    notes = []
    got = Checkpoint(path, "fp", key=KEY, say=notes.append).load()
    assert got == {"u": {"x": 1}, "w": 2}
    assert notes == []


# --- core/validate.py ---------------------------------------------------------------------------
from ldaspark.core import validate as V  # noqa: E402


def test_real_number_refuses_an_mpmath_complex():
    with pytest.raises(InputError, match="must be a real number"):
        V.real_number(mpmath.mpc(1, 2), "h")
    with pytest.raises(InputError, match="must be a real number"):
        V.real_number(mpmath.mpc(1, 0), "h")


def test_real_number_decimal_string_zero_is_not_positive():
    with pytest.raises(InputError, match="must be positive"):
        V.real_number("0", "h", positive=True)
    with pytest.raises(InputError, match="must be positive"):
        V.real_number(" 0.000 ", "h", positive=True)
    assert V.real_number("1e-400", "h", positive=True) == "1e-400"


def test_describe_marks_a_cut_repr_with_dots():
    r61 = "a" * 59                              # repr: 61 characters, cut to 60
    assert V._describe(r61) == f"str '{'a' * 59}..."
    r60 = "a" * 58                              # repr: 60 characters, whole
    assert V._describe(r60) == f"str '{'a' * 58}'"
    with pytest.raises(InputError, match=r"\.\.\.$"):
        V.count(r61, "n_steps")


def test_count_bound_is_written_plainly_below_a_million():
    with pytest.raises(InputError, match=r"between 1 and 3, got 4$"):
        V.count(4, "stages", lo=1, hi=3)
    with pytest.raises(InputError, match=r"between 1 and 1e\+06, got 0$"):
        V.count(0, "n", lo=1, hi=10 ** 6)


def test_check_executor_returns_the_executor():
    with cf.ThreadPoolExecutor(1) as ex:
        assert V.check_executor(ex) is ex
    assert V.check_executor(None) is None


def test_point_takes_only_the_missing_v0_from_the_scene():
    from ldaspark.models.scenes import get_scene
    sc = get_scene("pendulum")
    ts, qs, vs = sc.initial(None)
    t0, q0, v0 = V.point(sc.system, 0.0, [0.6, -0.8], None, scene=sc)
    assert (t0, q0) == (0.0, [0.6, -0.8])
    assert list(v0) == list(vs)


def test_step_advances_judges_the_spacing_at_the_end_of_the_run():
    # h = 1 advances t = 1, but not t = 2**53 + 1 reached after 2**53 steps
    V.step_advances(1.0, 1.0, n_steps=1)
    with pytest.raises(InputError, match="does not advance t"):
        V.step_advances(1.0, 1.0, n_steps=2 ** 53)


def test_step_advances_needs_two_spacings_in_float64():
    # t0 + h != t0, but h is one spacing only: t0 + 2h rounds (ties to even) onto t0 + h's neighbours
    assert 2.0 ** 52 + 1.0 != 2.0 ** 52
    with pytest.raises(InputError, match="does not advance t"):
        V.step_advances(2.0 ** 52, 1.0, n_steps=1)
    V.step_advances(2.0 ** 52, 2.0, n_steps=1)


def test_step_advances_in_digits_needs_two_units_of_the_last_digit():
    with pytest.raises(InputError, match="in 30 digits"):
        V.step_advances(1e30, 1.0, n_steps=1, dps=30)
    V.step_advances(1e30, 100.0, n_steps=1, dps=30)


# --- lab/reports/stability_stiff.py -----------------------------------------------------------------
from ldaspark.lab.reports import stability_stiff as SS  # noqa: E402


def test_stiff_sweep_grids_are_positive_and_strictly_monotone():
    assert all(h > 0 for h in SS.HW) and all(a < b for a, b in zip(SS.HW, SS.HW[1:]))
    assert all(h > 0 for h in SS.FLOOR_H) and all(a > b for a, b in zip(SS.FLOOR_H, SS.FLOOR_H[1:]))


def test_classify_growth_needs_more_than_the_bounds():
    row = {"outcome": "ok", "dE_growth": SS.DE_GROWTH, "max_rel_dE": 1e-3}
    assert SS.classify(row) == "bounded"
    assert SS.classify({**row, "dE_growth": SS.DE_GROWTH * 1.01}) == "growing"
    assert SS.classify({**row, "dE_growth": 10.0, "max_rel_dE": 1e-8}) == "bounded"
    assert SS.classify({**row, "dE_growth": 10.0, "max_rel_dE": 2e-8}) == "growing"


def test_dps_extreme_reports_the_largest_component_difference(monkeypatch):
    import ldaspark.core.spark as spark
    import ldaspark.models.scenes as scenes

    class Scene:
        system = None

        @staticmethod
        def initial(dps):
            return 0, [0, 0], [0, 0]

    def fake_integrate(system, tab, t0, q0, v0, h, n_steps, dps):
        with mpmath.workdps(dps):
            eps = mpmath.mpf(0) if dps == 30 else mpmath.mpf(1)
            q = [mpmath.mpf(1), mpmath.mpf(2) + eps * mpmath.mpf("1e-12")]
            v = [mpmath.mpf(3) + eps * mpmath.mpf("1e-20"), mpmath.mpf(4)]
        return types.SimpleNamespace(q=[q], v=[v], stats={"mean_iterations": 2.0})

    monkeypatch.setattr(scenes, "get_scene", lambda name: Scene)
    monkeypatch.setattr(spark, "integrate", fake_integrate)
    (row,) = SS.dps_extreme((30,), n=1)
    assert row["ref_dps"] == 70
    assert row["log10_diff"] == pytest.approx(-12.0, abs=1e-9)


# --- lab/reports/peers.py ---------------------------------------------------------------------------
from ldaspark.lab.reports import peers as P  # noqa: E402


class _Clock:
    """time.process_time stand-in: returns the given instants in turn."""

    def __init__(self, instants):
        self.instants = list(instants)

    def process_time(self):
        return self.instants.pop(0)


def test_cpu_min_takes_the_fastest_repeat(monkeypatch):
    # repeats of 0.3, 0.1, 0.2 s
    monkeypatch.setattr(P, "time", _Clock([0.0, 0.3, 1.0, 1.1, 2.0, 2.2]))
    best, out = P._cpu_min(lambda: "r", repeats=3, short=0.5)
    assert best == pytest.approx(0.1)
    assert out == "r"


def test_time_rhs_takes_the_fastest_repeat(monkeypatch):
    pytest.importorskip("numba")
    import numba

    @numba.njit
    def g(t, y, yp, W):
        yp[-1] = t

    monkeypatch.setattr(P, "time", _Clock([0.0, 3.0, 10.0, 11.0, 20.0, 22.0]))
    ns = P._time_rhs(g, np.zeros(2), np.zeros(1), calls=1000, repeats=3)
    assert ns == pytest.approx(1.0 / 1000 * 1e9)


def test_rhs_choice_takes_the_faster_form(monkeypatch):
    system = types.SimpleNamespace(name="kills-a-fake", n=1, m=1)
    mod = types.SimpleNamespace(HAS_CLOSED=True, CLOSED_INFO={}, rhs_into_solve="solve", rhs_into_closed="closed")
    monkeypatch.setattr(P, "_module", lambda s: mod)
    monkeypatch.setattr(P, "_RHS_CHOICE", {})
    monkeypatch.setattr(P, "_time_rhs", lambda g, y, W: {"solve": 80.0, "closed": 30.0}[g])
    out = P.rhs_choice(system, [0.0, 0.0])
    assert out["form"] == "closed"
    assert out["ns_per_call"] == {"solve": 80.0, "closed": 30.0}


def test_peer_section_names_the_rhs_choice_when_any_study_measured_it():
    d = json.loads((ROOT / "reports" / "peers.json").read_text())
    with_rhs = [i for i, st in enumerate(d["studies"]) if "rhs" in st]
    assert len(d["studies"]) >= 2 and with_rhs
    for i, st in enumerate(d["studies"]):
        if i != with_rhs[0]:
            st.pop("rhs", None)                 # one study measured the choice, the others not
    text = "\n".join(P.section(d))
    assert "the faster, measured per scene, of the closed form" in text
    for st in d["studies"]:
        st.pop("rhs", None)
    assert "the faster, measured per scene, of the closed form" not in "\n".join(P.section(d))


# --- lab/claims/ledger.py ---------------------------------------------------------------------------
from ldaspark.lab.claims import ledger as LG  # noqa: E402


def _symmetry_result(minus, plus):
    return {"seconds": 0.4, "symmetry-Ld": 1e-40, "wellposed": LG.WELLPOSED, "tangent_dim": (1, 1),
            "fd_restricted_norm": (1.0, 1.0), "symmetry-fd-unrestricted": (0.0, 0.0),
            "symmetry-fd-plus": 1e-40, "symmetry-fd-minus": 1e-40, "symmetry-Phi": 1e-40,
            "fd_plus_identity_norms": plus, "fd_minus_identity_norms": minus}


def test_symmetry_fd_record_is_vacuous_only_when_every_restricted_force_vanishes(monkeypatch):
    scene = types.SimpleNamespace(name="s", system=None)
    tab = types.SimpleNamespace(name="m")
    monkeypatch.setattr(LG, "check_symmetry", lambda *a, **k: _symmetry_result([0.0, 0.5], [0.0, 0.0]))
    recs = {r["claim"]: r for r in LG.symmetry_records(scene, tab, "pass", 0, [0], [0], "base", None)}
    assert recs["symmetry-fd-minus"]["status"] == "pass"
    assert recs["symmetry-fd-plus"]["status"] == "not-applicable"
    assert recs["symmetry-fd-plus"]["note"].startswith("vacuous")


def test_constraint_residuals_are_the_largest_over_the_steps(monkeypatch):
    n = 3
    ks = [0.0, 2e-3, 1e-3, 5e-4]                       # k(t_i) per step

    def fake_integrate(system, tab, t0, q0, v0, h, n_steps, dps, newton):
        assert n_steps == n
        q = [np.array([0.1 * i]) for i in range(n + 1)]
        return types.SimpleNamespace(t=[0.1 * i for i in range(n + 1)], q=q,
                                     v=[np.array([0.0])] * (n + 1), constraint=[np.array([k]) for k in ks])

    # the secant velocity's constraint: 3, 7, 5 at steps 1..3
    system = types.SimpleNamespace(constraint=lambda bk, t, q, v: np.array([[0, 3.0, 7.0, 5.0][round(t * 10)]]))
    scene = types.SimpleNamespace(system=system)
    monkeypatch.setattr(LG, "perturbed_initial", lambda sc, dps: (0, [0.0], [0.0]))
    monkeypatch.setattr(LG, "integrate", fake_integrate)
    k, sec, eps = LG.constraint_residuals(scene, None, n_steps=n, dps=None)
    assert k == pytest.approx(2e-3)
    assert sec == pytest.approx(7.0)


def test_holonomic_order_takes_the_larger_of_the_two_covectors(monkeypatch):
    # the pendulum's constraint |q| = 1 at q = (1, 0): tangent variations are along (0, 1)
    def fake_lagrangian(S, tab, t0, q0, t1, q1, dps, x_guess):
        h = float(t1)
        return types.SimpleNamespace(wellposed=LG.WELLPOSED,
                                     f_d_minus=np.array([mpmath.mpf(5 * h), mpmath.mpf(h ** 3)], dtype=object),
                                     f_d_plus=np.array([mpmath.mpf(h), mpmath.mpf(2 * h ** 3)], dtype=object))

    monkeypatch.setattr(LG, "base_point", lambda S, tab, t0, q0, v0, h, dps: (mpmath.mpf(h), list(q0), None))
    monkeypatch.setattr(LG, "discrete_lagrangian", fake_lagrangian)
    out = LG.holonomic_order(None, hs=("0.1", "0.05"), dps=30)
    assert out["tangential"] == pytest.approx([2e-3, 2 * 0.05 ** 3])
    assert out["full"] == pytest.approx([0.5, 0.25])
    assert out["p_tangential"] == pytest.approx(3.0)


# --- lab/claims/claims_general.py -------------------------------------------------------------------
def test_order_records_share_the_piece_time_per_record(monkeypatch):
    from ldaspark.lab.claims import claims_general as CG
    clock = iter([100.0, 106.0])
    monkeypatch.setattr(CG, "time", types.SimpleNamespace(time=lambda: next(clock)))

    def rec(var):
        return {"observed_order": 2.0, "claimed_order": 2, "pairwise_orders": [2.0], "method": "gauss-1",
                "scene": "s", "dps": None, "variable": var, "errors": [1e-3, 2.5e-4], "reference": "r"}
    monkeypatch.setattr(CG, "scene_orders", lambda name, methods: [rec("q"), rec("v"), rec("lambda")])
    out = CG.piece_records(("orders", "s"))
    assert [r["point"] for r in out] == ["order-q", "order-v"]
    assert [r["seconds"] for r in out] == [2.0, 2.0]
