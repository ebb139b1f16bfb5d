"""Block-sparse Newton linear algebra of the SPARK method (21) for mechanical systems at large n
(structure and cost: ``sparse``). Called by the entry point ``kernels.spark_sparse_run`` through
the ``kernels.evaluate``, ``kernels.factor`` and ``kernels.increment`` dispatch.

The workspace ``sp`` (built by ``kernels.sparse_workspace``) holds, in order: perm, pattern_ptr,
pattern_col, pattern_slot, row_ptr, col_pos, diag_slot (``sparse.NewtonStructure``), the block
values val (blocks, s + 1, s + 1), the inverses of the factored diagonal blocks Dinv (n, s + 1,
s + 1), B ((s + 1) n, s m), C (s m, (s + 1) n), W = A^-1 B, S = -C W and its pivots, two right-hand
sides, a block scratch, the row map ``where`` and a vector scratch. Unknowns of degree of freedom
a sit at (s + 1) perm[a] + i: Z_ia for i < s, dv_a for i = s.
"""
import numba
import numpy as np

from .newton import lu_factor, lu_solve, matrix_finite, norm_inf

#: a diagonal block whose pivot is below PIVOT_RTOL times its largest entry counts as singular
#: (the blocks are not pivoted against each other: such a pivot means the block order is unfit
#: for this matrix, and the caller falls back to the dense LU with partial pivoting)
PIVOT_RTOL = 1e-13


@numba.njit(cache=True, _nrt=False)
def sparse_assemble(tab, h, M, H, Rq, KK, kq, K1, kq1, sp):
    """The blocks of A, and B, C (see ``sparse``) from Hess U, d(K^T Lambda)/dq, K and k_q at the
    stages and K, k_q at the end point: the entries of ``kernels_mech.spark_jacobian`` and
    ``newton.constraint_rows``, placed by degree of freedom."""
    c, A, Ah, At, bw, bh, bt, om = tab
    perm, pptr, pcol, pslot = sp[0], sp[1], sp[2], sp[3]
    val, B, C = sp[7], sp[9], sp[10]
    s, n, m = A.shape[0], M.shape[0], K1.shape[0]
    b = s + 1
    h2 = h * h
    val[:, :, :] = 0.0
    for a in range(n):
        for e in range(pptr[a], pptr[a + 1]):
            bb = pcol[e]
            blk = val[pslot[e]]
            mab = M[a, bb]
            for i in range(b):
                for k in range(s):
                    acc = mab if i == k else 0.0
                    for j in range(s):
                        wh = Ah[i, j] if i < s else bh[j]
                        wt = At[i, j] if i < s else bt[j]
                        acc += h2 * wh * A[j, k] * H[j, a, bb] + h * wt * A[j, k] * Rq[j, a, bb]
                    blk[i, k] = acc
            blk[s, s] = mab
    for a in range(n):
        ra = perm[a] * b
        for i in range(b):
            for k in range(s):
                wt = At[i, k] if i < s else bt[k]
                for l in range(m):
                    B[ra + i, k * m + l] = wt * KK[k, l, a]
    rf = (s - 1) * m
    for bb in range(n):
        cb = perm[bb] * b
        for l in range(s - 1):
            for mm in range(m):
                for k in range(s):
                    acc = om[l, k] * KK[k, mm, bb]
                    for j in range(s):
                        acc += h * om[l, j] * A[j, k] * kq[j, mm, bb]
                    C[l * m + mm, cb + k] = acc
                C[l * m + mm, cb + s] = 0.0
        for mm in range(m):
            for k in range(s):
                C[rf + mm, cb + k] = h * bw[k] * kq1[mm, bb]
            C[rf + mm, cb + s] = K1[mm, bb]


@numba.njit(cache=True, _nrt=False)
def block_inverse(blk, out, tmp):
    """out = blk^-1 (Gauss-Jordan with partial pivoting on the copy tmp); False when a pivot is
    below PIVOT_RTOL times the block's largest entry."""
    b = blk.shape[0]
    big = 0.0
    for i in range(b):
        for k in range(b):
            tmp[i, k] = blk[i, k]
            out[i, k] = 1.0 if i == k else 0.0
            big = max(big, abs(blk[i, k]))
    for col in range(b):
        p = col
        for i in range(col + 1, b):
            if abs(tmp[i, col]) > abs(tmp[p, col]):
                p = i
        piv = tmp[p, col]
        if not (abs(piv) > PIVOT_RTOL * big):
            return False
        if p != col:
            for k in range(b):
                t1 = tmp[col, k]
                tmp[col, k] = tmp[p, k]
                tmp[p, k] = t1
                t2 = out[col, k]
                out[col, k] = out[p, k]
                out[p, k] = t2
        inv = 1.0 / piv
        for k in range(b):
            tmp[col, k] *= inv
            out[col, k] *= inv
        for i in range(b):
            if i != col:
                f = tmp[i, col]
                if f != 0.0:
                    for k in range(b):
                        tmp[i, k] -= f * tmp[col, k]
                        out[i, k] -= f * out[col, k]
    return True


@numba.njit(cache=True, _nrt=False)
def block_lu(sp):
    """Block LU of A in place (up-looking, rows in elimination order): val[e] of a block left of
    the diagonal becomes L_rc = A_rc U_cc^-1, right of it U_rd; Dinv[r] = U_rr^-1. False if a
    diagonal block is singular at PIVOT_RTOL."""
    rptr, cpos, dslot = sp[4], sp[5], sp[6]
    val, Dinv, tmp, where = sp[7], sp[8], sp[16], sp[17]
    n = rptr.shape[0] - 1
    b = val.shape[1]
    for r in range(n):
        for e in range(rptr[r], rptr[r + 1]):
            where[cpos[e]] = e
        for e in range(rptr[r], dslot[r]):
            c = cpos[e]
            Lrc = val[e]
            Dc = Dinv[c]
            for i in range(b):
                for k in range(b):
                    acc = 0.0
                    for l in range(b):
                        acc += Lrc[i, l] * Dc[l, k]
                    tmp[i, k] = acc
            for i in range(b):
                for k in range(b):
                    Lrc[i, k] = tmp[i, k]
            for f in range(dslot[c] + 1, rptr[c + 1]):
                Ucd = val[f]
                T = val[where[cpos[f]]]
                for i in range(b):
                    for l in range(b):
                        li = Lrc[i, l]
                        if li != 0.0:
                            for k in range(b):
                                T[i, k] -= li * Ucd[l, k]
        if not block_inverse(val[dslot[r]], Dinv[r], tmp):
            return False
    return True


@numba.njit(cache=True, _nrt=False)
def subtract_block_product(blk, y, oy, dst, od):
    """dst[od:od + b] -= blk @ y[oy:oy + b] for one b x b block."""
    b = blk.shape[0]
    for i in range(b):
        acc = 0.0
        for k in range(b):
            acc += blk[i, k] * y[oy + k]
        dst[od + i] -= acc


@numba.njit(cache=True, _nrt=False)
def block_solve(sp, y):
    """y <- A^-1 y with the factors of ``block_lu`` (forward with L, backward with U and Dinv)."""
    rptr, cpos, dslot = sp[4], sp[5], sp[6]
    val, Dinv, vb = sp[7], sp[8], sp[18]
    n = rptr.shape[0] - 1
    b = val.shape[1]
    for r in range(n):
        o = r * b
        for e in range(rptr[r], dslot[r]):
            subtract_block_product(val[e], y, cpos[e] * b, y, o)
    for r in range(n - 1, -1, -1):
        o = r * b
        for i in range(b):
            vb[i] = y[o + i]
        for e in range(dslot[r] + 1, rptr[r + 1]):
            subtract_block_product(val[e], y, cpos[e] * b, vb, 0)
        D = Dinv[r]
        for i in range(b):
            acc = 0.0
            for k in range(b):
                acc += D[i, k] * vb[k]
            y[o + i] = acc


@numba.njit(cache=True, _nrt=False)
def sparse_factor(stats, G, sp):
    """Checks and factors the Newton matrix held in sp (as ``newton.factor_newton``: 1 factored,
    -1 not finite, -2 singular): block LU of A, W = A^-1 B, S = -C W and its LU."""
    val, B, C, W, S, spiv, ry = sp[7], sp[9], sp[10], sp[11], sp[12], sp[13], sp[14]
    stats[3] += 1
    nb = val.shape[0]
    ok = np.isfinite(norm_inf(G)) and matrix_finite(B) and matrix_finite(C)
    for e in range(nb):
        if not ok:
            break
        ok = matrix_finite(val[e])
    if not ok:
        return -1
    stats[4] += 1
    if not block_lu(sp):
        return -2
    ny, sm = B.shape[0], B.shape[1]
    for col in range(sm):
        for r in range(ny):
            ry[r] = B[r, col]
        block_solve(sp, ry)
        for r in range(ny):
            W[r, col] = ry[r]
    for p in range(sm):
        for q in range(sm):
            acc = 0.0
            for r in range(ny):
                acc -= C[p, r] * W[r, q]
            S[p, q] = acc
    if sm > 0 and not lu_factor(S, spiv):
        return -2
    return 1


@numba.njit(cache=True, _nrt=False)
def sparse_increment(sp, G, x):
    """Simplified Newton update x += -J^-1 G with the factors in sp (as ``newton.newton_increment``;
    G is overwritten); returns |dx|_inf. y1 = A^-1 r_y, Lambda = S^-1 (r_Lambda - C y1),
    y = y1 - W Lambda."""
    perm, C, W, S, spiv, ry, rl = sp[0], sp[10], sp[11], sp[12], sp[13], sp[14], sp[15]
    n = perm.shape[0]
    b = sp[7].shape[1]
    s = b - 1
    sm = W.shape[1]
    sn = s * n
    for a in range(n):
        o = perm[a] * b
        for i in range(s):
            ry[o + i] = -G[i * n + a]
        ry[o + s] = -G[sn + a]
    for p in range(sm):
        rl[p] = -G[sn + n + p]
    block_solve(sp, ry)
    ny = ry.shape[0]
    for p in range(sm):
        acc = rl[p]
        for r in range(ny):
            acc -= C[p, r] * ry[r]
        rl[p] = acc
    if sm > 0:
        lu_solve(S, spiv, rl)
    for r in range(ny):
        acc = 0.0
        for p in range(sm):
            acc += W[r, p] * rl[p]
        ry[r] -= acc
    for a in range(n):
        o = perm[a] * b
        for i in range(s):
            d = ry[o + i]
            x[i * n + a] += d
            G[i * n + a] = d
        d = ry[o + s]
        x[sn + sm + a] += d
        G[sn + sm + a] = d
    for p in range(sm):
        x[sn + p] += rl[p]
        G[sn + p] = rl[p]
    return norm_inf(G)
