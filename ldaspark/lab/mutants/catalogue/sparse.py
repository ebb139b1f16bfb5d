"""Mutants of the block-sparse Newton linear algebra of the compiled SPARK kernel:
compiled/sparse.py (ordering and fill), compiled/kernels_sparse.py (assembly, block LU, Schur
complement), compiled/runner.py (the dense fallback); tests/compiled/test_sparse_newton.py."""
from ..mutant import _m

TSN = "tests/compiled/test_sparse_newton.py"

MUTANTS = (
    _m("sparse-assemble-Rq-dropped", "compiled/kernels_sparse.py",
       "acc += h2 * wh * A[j, k] * H[j, a, bb] + h * wt * A[j, k] * Rq[j, a, bb]",
       "acc += h2 * wh * A[j, k] * H[j, a, bb]",
       "block Newton matrix without the d(K^T Lambda)/dq term of (21b, d)", "compiled", TSN),
    _m("sparse-assemble-dv-identity", "compiled/kernels_sparse.py",
       "            blk[s, s] = mab\n", "            blk[s, s] = 1.0 if a == bb else 0.0\n",
       "block Newton matrix with d(21d)/dv1 = I instead of M", "compiled", TSN),
    _m("sparse-assemble-21f-kq-dropped", "compiled/kernels_sparse.py",
       "C[rf + mm, cb + k] = h * bw[k] * kq1[mm, bb]", "C[rf + mm, cb + k] = 0.0",
       "d(21f)/dV_k = h b_k k_q(t1, q1, v1) left out of the constraint rows C", "compiled", TSN),
    _m("sparse-schur-sign", "compiled/kernels_sparse.py",
       "                acc -= C[p, r] * W[r, q]", "                acc += C[p, r] * W[r, q]",
       "Schur complement of the multipliers C A^-1 B instead of -C A^-1 B", "compiled", TSN),
    _m("sparse-fill-lower-missing", "compiled/sparse.py",
       "            rows[r].add(c)\n            rows[c].add(r)\n", "            rows[r].add(c)\n",
       "filled pattern without the lower (L) part of the fill: the block LU drops couplings", "compiled", TSN),
    _m("sparse-natural-order", "compiled/sparse.py",
       "return len(g[x])            # the degree in the elimination graph", "return x",
       "elimination in the natural order instead of minimum degree (fill on a star: n^2 blocks)", "compiled", TSN),
    _m("sparse-pivot-check-off", "compiled/kernels_sparse.py",
       "if not (abs(piv) > PIVOT_RTOL * big):", "if False:",
       "no small-pivot test in the diagonal blocks (a zero block pivot gives inf, not a dense fallback)",
       "compiled", TSN),
    _m("sparse-dense-fallback-skipped", "compiled/runner.py",
       "if retry_dense and stats[mt.FAILED_STEP] >= 0 and stats[mt.FAILURE] == mt.FAIL_SINGULAR:",
       "if False:",
       "auto keeps the block LU's singular-matrix failure instead of repeating the run with the dense LU",
       "compiled", TSN),
)
