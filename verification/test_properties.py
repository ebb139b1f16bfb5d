"""Property tests (hypothesis): random tableaux with random A, random nonzero b, b_hat = b,
A_hat from (22b) (a_hat_ji = b_i (b_j - a_ij) / b_j), random A_tilde and b_tilde: Theorem 1
holds; perturb one entry of A_hat and it fails. Exact rational entries, checked at 30 digits
(finite differences at 50)."""
from fractions import Fraction

from hypothesis import given, settings, strategies as st

from ldaspark.analysis.discrete import theorem1_residuals
from ldaspark.analysis.conditions import check_22a, check_22b
from ldaspark.models.scenes import get_scene
from ldaspark.core.tableau_file import from_json_dict

SCENE = get_scene("particle")
GAUSS_A = {1: [[Fraction(1, 2)]], 2: [[Fraction(1, 4), Fraction(1, 4)], [Fraction(3, 4), Fraction(1, 4)]]}


def _small():
    return st.fractions(min_value=Fraction(-1, 10), max_value=Fraction(1, 10), max_denominator=50)


@st.composite
def tableaux(draw):
    s = draw(st.sampled_from([1, 2]))
    A = [[GAUSS_A[s][i][j] + draw(_small()) for j in range(s)] for i in range(s)]
    b = [Fraction(1, s) + draw(_small()) for _ in range(s)]
    b = [x if x != 0 else Fraction(1, 3) for x in b]
    Ah = [[b[i] * (b[j] - A[i][j]) / b[j] for i in range(s)] for j in range(s)]   # (22b) solved
    At = [[Fraction(1, 2 * s) + draw(_small()) * 3 for _ in range(s)] for _ in range(s)]
    bt = [Fraction(1, s) + draw(_small()) for _ in range(s)]
    c = [sum(r) for r in A]
    d = {"c": c, "A": A, "A_hat": Ah, "A_tilde": At, "b": b, "b_hat": b, "b_tilde": bt}
    d = {k: [[str(x) for x in r] if isinstance(r, list) else str(r) for r in v] for k, v in d.items()}
    if s == 2:
        d["omega"] = [[str(b[0]), str(b[1])]]
    return from_json_dict(d, name="random")


def _residual(tab):
    t0, q0, v0 = SCENE.initial(50)
    r = theorem1_residuals(SCENE.system, tab, t0, q0, v0, "0.1", dps=30)
    return max(r["theorem1-q0"], r["theorem1-q1"])


@settings(max_examples=8)
@given(tableaux())
def test_theorem1_random_tableaux(tab):
    assert check_22a(tab) and check_22b(tab)
    assert _residual(tab) <= 1e-15


@settings(max_examples=6)
@given(tableaux(), st.data())
def test_theorem1_fails_when_A_hat_perturbed(tab, data):
    i = data.draw(st.integers(0, tab.s - 1))
    j = data.draw(st.integers(0, tab.s - 1))
    bad = tab.with_entry("A_hat", i, j, "1/20")
    assert not check_22b(bad)
    assert _residual(bad) >= 1e-6
