"""Structure of the SPARK Newton matrix (21) for mechanical systems at large n: the symbolic
analysis (ordering and fill) of the block-sparse factorisation ``kernels_sparse`` carries out.

The Newton matrix of (21b, d, e, f) in the unknowns (Z_1..Z_s, dv | Lambda) is a saddle matrix

    [ A  B ]    A = d(21b, d)/d(Z, dv),  (s + 1) n square;  B = d(21b, d)/dLambda = A~ (x) K^T;
    [ C  0 ]    C = d(21e, f)/d(Z, dv),  s m rows;          d(21e, f)/dLambda = 0,

(k does not depend on the multipliers). With the unknowns of one degree of freedom a, (Z_1a, ...,
Z_sa, dv_a), taken together, A is an n x n matrix of (s + 1) x (s + 1) blocks whose block pattern
is P = pattern(M) + pattern(Hess U) + pattern(d(K^T lam)/dq) (+ the diagonal): block (a, b) is
delta_ik M_ab + h^2 (A^ A)_ik Hess U_ab + h (A~ A)_ik d(K^T Lambda)/dq_ab, summed over the stages as
in ``kernels_mech.spark_jacobian``. A is factored by block LU in a minimum-degree order of the
graph of P (the fill it creates is computed here, once per system and stage count), then the
Schur complement S = -C A^-1 B (s m x s m, dense, partial pivoting) gives the multipliers. The
cost per factorisation is ~ 2 (s + 1)^3 per block update instead of ((s + 1) n + s m)^3 / 3 for
the dense LU, and ~ nnz(L + U) (s + 1)^2 per solve.

Blocks are not pivoted against each other (each diagonal block is factored with partial
pivoting): the diagonal blocks hold M_aa + O(h), so for the step sizes a simplified Newton
converges at, the block pivots are those of M; a pivot below PIVOT_RTOL of its block makes the
factorisation report a singular matrix, and ``fast`` then runs the dense path.

Why not scipy.sparse.linalg.splu: it cannot be called from the compiled step loop (numba), and
the pattern is fixed for a whole run, so the symbolic work is done once, here, and only the
numeric factorisation runs per step.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: budget of set operations for the symbolic elimination (Python): a pattern whose elimination
#: needs more (a dense or nearly dense Hessian at large n) gets no sparse structure (dense path)
MAX_SYMBOLIC_WORK = 4_000_000


@dataclass(frozen=True)
class NewtonStructure:
    """Arrays (int64, C-contiguous) the sparse kernel takes; positions are places in the
    elimination order, ``perm[a]`` the position of degree of freedom a.

    pattern_ptr, pattern_col, pattern_slot: P in CSR over the original indices, and the block slot
    of each entry; row_ptr, col_pos: the filled pattern F = L + U in CSR over positions (columns
    ascending); diag_slot: the slot of each diagonal block; fill_ratio = nnz(F) / nnz(P)."""

    perm: np.ndarray
    pattern_ptr: np.ndarray
    pattern_col: np.ndarray
    pattern_slot: np.ndarray
    row_ptr: np.ndarray
    col_pos: np.ndarray
    diag_slot: np.ndarray
    n_blocks: int
    fill_ratio: float
    block_updates: int

    def arrays(self):
        return (self.perm, self.pattern_ptr, self.pattern_col, self.pattern_slot, self.row_ptr, self.col_pos,
                self.diag_slot)

    def factor_flops(self, s: int, m: int) -> float:
        """Multiply-adds of one numeric factorisation: the block updates of A ((s + 1)^3 each,
        with the scaling of L), the s m solves for A^-1 B and the dense LU of S."""
        b = s + 1
        solve = 2 * self.n_blocks * b * b
        return float((self.block_updates + self.n_blocks) * b ** 3 + s * m * solve + (s * m) ** 3 / 3)


def pattern_pairs(n: int, pairs, M: np.ndarray):
    """The symmetric block pattern P: the given (i, j), the nonzeros of M and the diagonal."""
    adj = [set() for _ in range(n)]
    for i, j in pairs:
        i, j = int(i), int(j)
        if i != j:
            adj[i].add(j)
            adj[j].add(i)
    rows, cols = np.nonzero(M)
    for i, j in zip(rows.tolist(), cols.tolist()):
        if i != j:
            adj[i].add(j)
            adj[j].add(i)
    return adj


def minimum_degree_fill(adj, budget=MAX_SYMBOLIC_WORK):
    """Elimination order by minimum degree (ties: lowest index) and, for each node, its
    neighbours at elimination (the later nodes its row of U couples to). Returns (order,
    neighbours) or None when the elimination needs more than ``budget`` set operations (the
    cliques it forms: sum of deg^2)."""
    import heapq
    n = len(adj)
    g = [set(a) for a in adj]
    alive = [True] * n
    # a heap of (degree, node) with stale entries skipped: the choice costs log n, so the budget
    # bounds the fill work and not n itself (a scan of the remaining nodes per elimination was
    # n^2 / 2 and used the whole budget by itself from n ~ 2800 on)
    def priority(x):
        return len(g[x])            # the degree in the elimination graph
    heap = [(priority(x), x) for x in range(n)]
    heapq.heapify(heap)
    order, upper = [], []
    work = 0
    while heap:
        d, k = heapq.heappop(heap)
        if not alive[k] or d != priority(k):
            continue
        nb = g[k]
        order.append(k)
        upper.append(frozenset(nb))
        work += len(nb) ** 2
        if work > budget:
            return None
        for u in nb:
            gu = g[u]
            gu.discard(k)
            gu |= nb
            gu.discard(u)
            heapq.heappush(heap, (priority(u), u))
        alive[k] = False
        g[k] = set()
    return order, upper


def newton_structure(n: int, pairs, M: np.ndarray, budget=MAX_SYMBOLIC_WORK):
    """The ``NewtonStructure`` of a mechanical system with Hessian/K^T lam pattern ``pairs`` and mass
    matrix M; None when the symbolic elimination exceeds the budget."""
    adj = pattern_pairs(n, pairs, np.asarray(M))
    res = minimum_degree_fill(adj, budget)
    if res is None:
        return None
    order, upper = res
    perm = np.empty(n, dtype=np.int64)
    perm[np.array(order, dtype=np.int64)] = np.arange(n, dtype=np.int64)
    # filled pattern over positions: row r holds its lower part (from the rows that eliminated
    # before it and coupled to it) and its upper part (its neighbours at elimination)
    rows = [set() for _ in range(n)]
    for r, k in enumerate(order):
        rows[r].add(r)
        for u in upper[r]:
            c = int(perm[u])
            rows[r].add(c)
            rows[c].add(r)
    row_ptr = np.zeros(n + 1, dtype=np.int64)
    cols = []
    for r in range(n):
        cr = sorted(rows[r])
        cols.extend(cr)
        row_ptr[r + 1] = row_ptr[r] + len(cr)
    col_pos = np.array(cols, dtype=np.int64)
    diag_slot = np.empty(n, dtype=np.int64)
    for r in range(n):
        seg = col_pos[row_ptr[r]:row_ptr[r + 1]]
        diag_slot[r] = row_ptr[r] + int(np.searchsorted(seg, r))
    # P over the original indices (with the diagonal), each entry's slot in F
    pptr = np.zeros(n + 1, dtype=np.int64)
    pcol, pslot = [], []
    for a in range(n):
        ca = sorted(adj[a] | {a})
        ra = int(perm[a])
        seg = col_pos[row_ptr[ra]:row_ptr[ra + 1]]
        for b in ca:
            pcol.append(b)
            pslot.append(int(row_ptr[ra] + np.searchsorted(seg, perm[b])))
        pptr[a + 1] = pptr[a] + len(ca)
    nnz_p = int(pptr[-1])
    n_upper = row_ptr[1:] - diag_slot - 1
    updates = sum(int(n_upper[c]) for r in range(n) for c in col_pos[row_ptr[r]:diag_slot[r]].tolist())
    return NewtonStructure(perm, pptr, np.array(pcol, dtype=np.int64), np.array(pslot, dtype=np.int64),
                           row_ptr, col_pos, diag_slot, int(row_ptr[-1]), row_ptr[-1] / max(nnz_p, 1), updates)


def dense_flops(s: int, n: int, m: int) -> float:
    """Multiply-adds of the dense LU of the Newton matrix, ((s + 1) n + s m)^3 / 3."""
    return ((s + 1) * n + s * m) ** 3 / 3.0
