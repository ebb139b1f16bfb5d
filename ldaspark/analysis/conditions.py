"""Listing of the built-in methods with their claimed order and whether (22) and (23) hold
(checked exactly on the coefficients, not asserted)."""
from __future__ import annotations

from ..core.tableau import SparkTableau

from ..core.families import builtin_method_names, get_method


def check_22a(tab: SparkTableau) -> bool:
    """(22a) b_hat_i = b_i, exactly."""
    K, e = tab.field_entries()
    return all(e["b_hat"][i] == e["b"][i] for i in range(tab.s))


def check_22b(tab: SparkTableau) -> bool:
    """(22b) b_hat_i a_ij + b_j a_hat_ji - b_hat_i b_j = 0, exactly."""
    K, e = tab.field_entries()
    b, bh, A, Ah = e["b"], e["b_hat"], e["A"], e["A_hat"]
    s = tab.s
    return all(bh[i] * A[i][j] + b[j] * Ah[j][i] - bh[i] * b[j] == K.zero for i in range(s) for j in range(s))


def check_23(tab: SparkTableau) -> bool:
    """(23a-d) symmetry conditions, exactly."""
    K, e = tab.field_entries()
    s = tab.s
    r = lambda i: s - 1 - i
    if any(e["c"][r(i)] + e["c"][i] != K.one for i in range(s)):
        return False
    for M, bv in (("A", "b"), ("A_hat", "b_hat"), ("A_tilde", "b_tilde")):
        for i in range(s):
            for j in range(s):
                if e[M][r(i)][r(j)] + e[M][i][j] != e[bv][j] or e[bv][r(j)] != e[bv][j]:
                    return False
    return True


def method_table(max_s: int = 4) -> list[dict]:
    rows = []
    for name in builtin_method_names(max_s):
        tab = get_method(name, exact=True)
        rows.append({"method": name, "s": tab.s, "order": tab.claimed_order,
                     "22": check_22a(tab) and check_22b(tab), "23": check_23(tab)})
    return rows
