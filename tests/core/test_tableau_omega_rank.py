"""The rank of omega (21e) is decided at the precision the entries carry, by singular values at
enough digits against the entries' uncertainty (``tableau.omega_rank``): right for the
Vandermonde-type default rows b_j c_j^(i-1) at any stage count (a 30-digit Gaussian elimination
called Gauss-6 rank 4)."""
import json

import mpmath
import pytest

from ldaspark.core.errors import TableauError
from ldaspark.core.families import gauss
from ldaspark.core.tableau import omega_rank
from ldaspark.core.tableau_file import from_json_dict, load_tableau
from ldaspark.lab.theory import audit_checks as ac


def _printed(tab, digits, omega=False):
    """``tab``'s entries as decimal strings of ``digits`` digits (omega too when asked)."""
    ent = tab.mp_entries(digits + 10)
    with mpmath.workdps(digits + 10):
        S = lambda x: mpmath.nstr(x[0] if isinstance(x, list) else x, digits)
        d = {k: [S(x) for x in v] if k in ("c", "b", "b_hat", "b_tilde") else [[S(x) for x in r] for r in v]
             for k, v in ent.items() if omega or k != "omega"}
    d["name"] = f"{tab.name} ({digits} digits)"
    return d


@pytest.mark.parametrize("s", [6, 7, 9])
def test_gauss_default_omega_has_rank_s_minus_1(s):
    r = omega_rank(gauss(s))
    assert r["rank"] == s - 1 and r["sigma"][s - 2] > 10 * r["bound"]


@pytest.mark.exhaustive
@pytest.mark.parametrize("s", range(6, 21))
def test_gauss_default_omega_has_rank_s_minus_1_up_to_20(s):
    r = omega_rank(gauss(s))
    assert r["rank"] == s - 1 and r["sigma"][s - 2] > 10 * r["bound"]


@pytest.mark.parametrize("s", [6, 7])
def test_gauss_6_and_7_files_in_40_digits_load(s, tmp_path):
    p = tmp_path / f"gauss{s}.json"
    p.write_text(json.dumps(_printed(gauss(s), 40)))
    tab = load_tableau(p)
    chk = ac.check_omega(tab, None, None, 30)
    assert tab.s == s and chk.status == ac.PASS and chk.residual > chk.tolerance


def test_a_rank_deficiency_within_the_entries_precision_is_refused():
    """omega of Gauss-6 in 40 digits with its last row replaced by the one before plus 1e-45
    (below the 40 digits given): singular to that precision; plus 1e-30 (above it): rank 5."""
    d = _printed(gauss(6), 40, omega=True)
    near = [list(r) for r in d["omega"]]
    with mpmath.workdps(60):
        near[4] = [mpmath.nstr(mpmath.mpf(x) + mpmath.mpf("1e-45"), 50) for x in near[3]]
        far = [list(r) for r in d["omega"]]
        far[4] = [mpmath.nstr(mpmath.mpf(x) + mpmath.mpf("1e-30") * (j + 1), 50) for j, x in enumerate(far[3])]
    with pytest.raises(TableauError, match="omega is singular"):
        from_json_dict(dict(d, omega=near))
    assert omega_rank(from_json_dict(dict(d, omega=far)))["rank"] == 5


def test_exact_equal_rows_are_singular_and_float64_rows_carry_half_an_ulp():
    d = {"c": ["1/2", "1/2", "1/2"], "A": [["1/6"] * 3] * 3, "A_hat": [["1/6"] * 3] * 3,
         "A_tilde": [["1/6"] * 3] * 3, "b": ["1/3"] * 3, "b_hat": ["1/3"] * 3, "b_tilde": ["1/3"] * 3,
         "omega": [["1", "2", "3"], ["1", "2", "3"]]}
    with pytest.raises(TableauError, match="omega is singular"):
        from_json_dict(d)
    d["omega"] = [[1.0, 2.0, 3.0], [1.0, 2.0, 3.0 + 2 ** -51]]      # differs by 4 ulps
    with pytest.raises(TableauError, match="omega is singular"):   # within float64's half ulps
        from_json_dict(d)
    d["omega"] = [[1.0, 2.0, 3.0], [1.0, 2.0, 3.001]]
    assert omega_rank(from_json_dict(d))["rank"] == 2


@pytest.mark.exhaustive
@pytest.mark.parametrize("s", [6, 7])
def test_gauss_6_and_7_files_in_40_digits_pass_the_audit(s, tmp_path):
    from ldaspark.cli import main
    p = tmp_path / f"gauss{s}.json"
    p.write_text(json.dumps(_printed(gauss(s), 40)))
    assert main(["audit", str(p), "--quick", "--json", str(tmp_path / "out.json")]) == 0
