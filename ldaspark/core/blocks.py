"""Helpers of the block-by-block Newton matrix of (21) (``SparkMethod._jacobian_blocks``):
stage blocks d X_j / d V_k = delta_jk X_v(j) + h a_jk X_q(j) and their combinations with the
tableau coefficients, skipping zero coefficients and structurally zero blocks (None)."""
from __future__ import annotations


def stage_blocks(Xv, Xq, A, h, col=None):
    """D[j][k] = delta_jk Xv[j] + h a_jk Xq[j] (None where both vanish); with ``col`` only
    the column k = col, as a list over j."""
    s = len(Xv)

    def one(j, k):
        blk = Xv[j] if j == k else None
        if A[j, k] and Xq[j] is not None:
            t = Xq[j] * (A[j, k] * h)
            blk = t if blk is None else blk + t
        return blk
    if col is not None:
        return [one(j, col) for j in range(s)]
    return [[one(j, k) for k in range(s)] for j in range(s)]


def combine(first, terms_h, h, terms):
    """first - h sum_j c_j X_j - sum_j d_j Y_j over the nonzero coefficients and blocks
    (None if everything vanishes); ``first`` may be None."""
    acc = None
    for c, X in terms_h:
        if c and X is not None:
            acc = X * c if acc is None else acc + X * c
    out = None if acc is None else -(acc * h)
    for c, Y in terms:
        if c and Y is not None:
            out = -(Y * c) if out is None else out - Y * c
    if first is None:
        return out
    return first if out is None else first + out
