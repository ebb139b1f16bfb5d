"""The compiled Newton matrix of the mechanical form, assembled block by block, is the same matrix,
bit for bit, as the sum per entry of (21b, d, e, f)'s derivatives (the order of operations the
kernel had before it formed the tableau coefficients once per block); and the operation count of
benchmarks/step_cost.py."""
import os
import sys

import numpy as np
import pytest

from ldaspark.compiled.kernels_mech import mech_workspace, spark_jacobian
from ldaspark.compiled.runner import kernel_spec

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "benchmarks"))


def _per_entry(tab, h, M, KK, H, Rq, kq, K1, kq1):
    """d(21b, d, e, f)/d(Z, Lambda, dv), each entry its own sum over j in plain Python floats."""
    c, A, Ah, At, bw, bh, bt, om = (np.asarray(x) for x in tab)
    s, m, n = kq.shape
    sn, sm = s * n, s * m
    N = sn + sm + n
    J = np.zeros((N, N))
    h2 = h * h
    for i in range(s + 1):
        for k in range(s):
            for a in range(n):
                for b in range(n):
                    acc = float(M[a, b]) if i == k else 0.0
                    for j in range(s):
                        wh = float(Ah[i, j] if i < s else bh[j])
                        wt = float(At[i, j] if i < s else bt[j])
                        acc += h2 * wh * float(A[j, k]) * float(H[j, a, b]) + h * wt * float(A[j, k]) * float(Rq[j, a, b])
                    J[i * n + a, k * n + b] = acc
                wt = float(At[i, k] if i < s else bt[k])
                for l in range(m):
                    J[i * n + a, sn + k * m + l] = wt * float(KK[k, l, a])
    re0, rf0 = sn + n, sn + n + (s - 1) * m
    J[sn:sn + n, sn + sm:] = M
    for l in range(s - 1):
        for mm in range(m):
            for k in range(s):
                for b in range(n):
                    acc = float(om[l, k]) * float(KK[k, mm, b])
                    for j in range(s):
                        acc += h * float(om[l, j]) * float(A[j, k]) * float(kq[j, mm, b])
                    J[re0 + l * m + mm, k * n + b] = acc
    for mm in range(m):
        for k in range(s):
            for b in range(n):
                J[rf0 + mm, k * n + b] = h * float(bw[k]) * float(kq1[mm, b])
        J[rf0 + mm, sn + sm:] = K1[mm]
    return J


@pytest.mark.parametrize("method, n, m", [("gauss-3", 3, 1), ("gauss-4", 4, 2), ("lobatto-iiia-iiib-3", 2, 1)])
def test_block_assembly_is_the_per_entry_sum_bitwise(method, n, m):
    # bitwise, not to a tolerance: the assembly only regroups loops, each entry keeps its products
    # and its sum over j in the same order, so any difference is a changed operation
    tab = kernel_spec(method, "spark")[1]
    s = tab[1].shape[0]
    rng = np.random.default_rng(7)
    M = rng.standard_normal((n, n))
    M = M @ M.T + n * np.eye(n)
    ws = mech_workspace(s, n, m, M)
    KK, H, Rq, kq, K1, kq1 = ws[5], ws[8], ws[9], ws[10], ws[13], ws[15]
    for arr in (KK, H, Rq, kq, K1, kq1):
        arr[...] = rng.standard_normal(arr.shape)
    h = 0.1 * np.pi
    N = s * (n + m) + n
    J = np.full((N, N), np.nan)
    spark_jacobian(tab, h, M, ws, J)
    ref = _per_entry(tab, h, M, KK, H, Rq, kq, K1, kq1)
    assert np.array_equal(J, ref)


def test_operation_count():
    from step_cost import counted
    # skate, gauss-4: N = 4*3 + 4*1 + 3 = 19; one LU 2/3 19^3 + 19^2, two iterations of 2 N^2 + 3 N
    per = {"iterations": 2.0, "njev": 1.0, "nlu": 1.0, "residuals": 1.0}
    N, parts = counted(4, 3, 1, 3, per, (0, 0))
    assert N == 19
    assert parts["lu"] == pytest.approx(2 * 19 ** 3 / 3 + 19 ** 2)
    assert parts["solves"] == 2 * (2 * 19 ** 2 + 3 * 19)
    # assembly: 5 x 4 blocks of 4 sums over j of 4 n^2 + 4 flops, constraint rows 3 x 4 x (4 (2 m n + 2) + m n)
    # and the (21f) row 2 s m n
    assert parts["jacobian"] == 5 * 4 * 4 * (4 * 9 + 4) + 3 * 4 * (4 * (2 * 3 + 2) + 3) + 2 * 4 * 3
    assert parts["total"] == sum(v for k, v in parts.items() if k != "total")
