"""Verdicts at the precision the data carries: a JSON number is a decimal text known to its digits
(and to half an ulp of float64 when it may be a float64's shortest writing); the numerical checks'
allowance for the entries' uncertainty is measured on each scene (``audit_checks.entry_effect``),
not a fixed factor; float64, 17-digit, 40-digit and exact writings of one method get one verdict."""
import json

import pytest

from ldaspark.cli import main
from ldaspark.core.numbers import JsonNumber
from ldaspark.core.tableau_file import load_tableau
from ldaspark.lab.theory import audit as au
from ldaspark.lab.theory import audit_checks as ac

from audit_writings import WRITINGS, builtin, nodepy_method, adjoint, write, written


def _file(tmp_path, name, kind):
    c, A, b, Ah, At = builtin(name)
    return write(tmp_path / f"{name}-{kind}.json", written(c, A, b, kind, Ah, At, name=name))


def test_json_numbers_are_decimal_texts_with_their_digits(tmp_path):
    p = tmp_path / "t.json"
    p.write_text('{"c": [0.1127016653792583], "A": [[0.5]], "A_hat": [[0.5]], "A_tilde": [[0.5]], '
                 '"b": [1.0], "b_hat": [1.0], "b_tilde": [1.0]}')
    tab = load_tableau(p)
    assert isinstance(tab.sources["c"][0], JsonNumber) and tab.precision_kind() == "float"
    assert not tab.is_exact and tab.source_digits == 15 and "JSON numbers" in tab.precision_text()
    ball = tab.ball_entries(40)["c"][0]
    # half a unit in the 16th significant digit (5e-17) plus half an ulp (0.113 * 2^-53 = 1.25e-17)
    # plus the rounding of a float64 computation, cond(V) = 1 ulp of c's largest entry for one node
    assert tab.float_computation_ulps() == 1.0 and 7.4e-17 < float(ball.rad()) < 7.6e-17
    p.write_text(p.read_text().replace("0.1127016653792583", "0.1127016653792583346207417272" + "1" * 12))
    tab = load_tableau(p)
    assert tab.source_digits == 40 and float(tab.ball_entries(60)["c"][0].rad()) < 1e-40


def test_theorem1_allowance_is_measured_on_the_scene(tmp_path):
    """Gauss-4 as float64 JSON numbers on the skate: the residual (~1e-14) is above the numerical
    tolerance (1e-15) but within what the entries' half-ulps contribute there, measured (a response
    of ~3e3 per unit change); the old fixed 1e3 x the (22b) residual (8e-15) failed it. Control:
    A_hat moved by 1e-12 violates (22b) beyond the entries' precision: no allowance, Theorem 1 fails."""
    tab = load_tableau(_file(tmp_path, "gauss-4", "float64"))
    ch, _ = au.theorem1_checks(tab, True, False, 30, True, ("skate",), (1.0, 0.0))
    c = ch[0]
    assert c.status == au.PASS and c.residual > 1e-15 and "precision of the entries: holds to 1" in c.detail
    assert c.residual < c.tolerance < 1e-6
    bad = tab.with_entry("A_hat", 0, 1, "1e-12")
    C = {x.name: x for x in au.algebraic_checks(bad, *au.decide_arith(bad, 30)[:2], 30)[0]}
    assert C["22b"].status == au.FAIL
    ch, _ = au.theorem1_checks(bad, False, False, 30, True, ("skate",), au.entry_tolerances(list(C.values())))
    assert ch[0].status == au.FAIL and ch[0].tolerance < 1e-14


def test_the_entries_floor_of_the_convergence_check_is_measured(tmp_path):
    """6-digit Lobatto IIIA-B-3: the finest error (1e-6 at h = 1/8) is within ENTRY_FLOOR x what
    the entries' uncertainty changes there, so the slope comes from coarser steps (h = 1/2, 1/4):
    4.06 vs 4. The exact writing has no such floor."""
    c, A, b, Ah, At = builtin("lobatto-iiia-iiib-3")
    tab = load_tableau(write(tmp_path / "l6.json", written(c, A, b, "6", Ah, At)))
    ch, f = ac.convergence_checks(tab, 4, 30, True)
    r = f["convergence:skate"]
    assert r["entry_floor"] > r["errors"][-1] and r["N"][0] == 2 and ch[0].status == ac.PASS
    tab = load_tableau(write(tmp_path / "le.json", written(c, A, b, "exact", Ah, At)))
    assert ac._entry_floor_measured(tab, "skate", 8, 1, None) == (0.0, 0.0)


def test_faster_than_predicted_is_reported_not_failed():
    """Gauss-2 measured against a prediction of 3 (its order is 4): above, reported; against 5:
    below, fails."""
    from ldaspark.core.families import get_method
    tab = get_method("gauss-2")
    ch, _ = ac.convergence_checks(tab, 3, 30, True)
    up = [c for c in ch if c.name.startswith("convergence:")]
    assert all(c.status == ac.PASS and "faster than the trees predict" in c.detail for c in up)
    ch, _ = ac.convergence_checks(tab, 5, 30, True)
    assert all(c.status == ac.FAIL for c in ch if c.name.startswith("convergence:"))


CASES = [("gauss-3", None), ("gauss-4", None), ("gauss-5", None),
         ("RadauIIA3", "adjoint"), ("LobattoIIIC3", "adjoint"), ("LobattoIIIC4", "adjoint")]


def _case_file(tmp_path, name, pair, kind):
    if pair is None:
        return _file(tmp_path, name, kind)
    import nodepy.runge_kutta_method as rk
    c, A, b = nodepy_method(rk.loadRKM(name))
    return write(tmp_path / f"{name}-{kind}.json", written(c, A, b, kind, adjoint(A, b), name=f"{name} + adjoint"))


@pytest.mark.exhaustive
@pytest.mark.parametrize("name,pair", CASES)
def test_every_writing_gets_the_verdict_of_the_exact_one(name, pair, tmp_path):
    """The four writings of Gauss-3/4/5 and of the Radau IIA / Lobatto IIIC adjoint pairs: the same
    exit code (0) and the same pass/fail of every check as the exact writing."""
    codes, status = {}, {}
    for kind in WRITINGS:
        out = tmp_path / f"{kind}.out.json"
        codes[kind] = main(["audit", str(_case_file(tmp_path, name, pair, kind)), "--quick", "--json", str(out)])
        status[kind] = {c["name"]: c["status"] for c in json.loads(out.read_text())["checks"]
                        if c["status"] in ("pass", "fail")}
    assert codes == {k: 0 for k in WRITINGS}
    assert all(status[k] == status["exact"] for k in WRITINGS)


def test_no_allowance_when_the_moved_tableau_cannot_be_solved(monkeypatch, tmp_path):
    """The allowance is measured or absent: when a moved tableau's solve fails, the scene is judged
    at the numerical tolerance (a residual of 1e-13 fails), and with the measurement (a response of
    1e3 per unit change: allowance ~1e-11) it passes."""
    from ldaspark.core.errors import LdasparkError
    from ldaspark.analysis import discrete
    fake = {"theorem1-q0": 1e-13, "theorem1-q1": 1e-13, "fd_error": 1e-30, "dps": 30, "wellposed": "well-posed",
            "rank_deficiency": 0, "dps_fd": 50, "without_forces_q0": 1.0}
    monkeypatch.setattr(discrete, "theorem1_residuals", lambda *a, **k: dict(fake))
    tab = load_tableau(_file(tmp_path, "gauss-2", "float64"))

    def fails(*a):
        raise LdasparkError("Newton did not converge")
    monkeypatch.setattr(au, "entry_effect", fails)
    ch, _ = au.theorem1_checks(tab, True, False, 30, True, ("skate",), (1.0, 0.0))
    assert ch[0].status == au.FAIL and ch[0].tolerance == pytest.approx(1e-15)
    monkeypatch.setattr(au, "entry_effect", lambda tab, radii, f: (1e-11, 1e3))
    ch, _ = au.theorem1_checks(tab, True, False, 30, True, ("skate",), (1.0, 0.0))
    assert ch[0].status == au.PASS and ch[0].tolerance == pytest.approx(1e-11)


def test_an_allowance_as_large_as_the_forces_leaves_the_scene_undecided(monkeypatch, tmp_path):
    """A measured allowance at least as large as what the forces f_d contribute (the residual
    without them) cannot tell Theorem 1 from the claim without the forces: the scene is not decided.
    Before, Lobatto IIIA-IIIB 4 printed to 8 places passed mp-particles at a tolerance of 1.0 (the
    forces' part 7.7e-5) and Gauss-5 to 10 digits the robot at 2e-2 (the forces' part 3.9e-7): checks
    that pass on the fault. Control: forces of size 1 and the same allowance: decided, pass."""
    from ldaspark.analysis import discrete
    fake = {"theorem1-q0": 1e-8, "theorem1-q1": 1e-8, "fd_error": 1e-30, "dps": 30, "wellposed": "well-posed",
            "rank_deficiency": 0, "dps_fd": 50, "without_forces_q0": 3.9e-7}
    monkeypatch.setattr(discrete, "theorem1_residuals", lambda *a, **k: dict(fake))
    monkeypatch.setattr(au, "entry_effect", lambda tab, radii, f: (2e-2, 4.7e5))
    tab = load_tableau(_file(tmp_path, "gauss-2", "float64"))
    ch, _ = au.theorem1_checks(tab, True, False, 30, True, ("robot",), (1.0, 0.0))
    assert ch[0].status == au.SKIP and "not decided" in ch[0].detail and "forces" in ch[0].detail
    # no scene decided, by the entries' digits: not a pass, and no failure of the tableau either
    assert ch[1].name == "theorem1" and ch[1].status == au.INFO and "precision of the entries" in ch[1].detail
    fake["without_forces_q0"] = 1.0
    ch, _ = au.theorem1_checks(tab, True, False, 30, True, ("robot",), (1.0, 0.0))
    assert ch[0].status == au.PASS and ch[0].tolerance == pytest.approx(2e-2) and ch[1].status == au.PASS
