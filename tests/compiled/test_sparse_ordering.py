"""The minimum-degree ordering of the sparse Newton factorisation (``compiled.sparse.
minimum_degree_fill``, a heap with stale entries skipped) against a recomputation by scanning:
at each elimination the alive node of least current degree (ties: lowest index), its
neighbours recorded, then made a clique. A stale heap entry taken for a live one (a node chosen
at an old, lower degree) changes the order or the fill on random patterns."""
from __future__ import annotations

from hypothesis import given, settings, strategies as st

from ldaspark.compiled.sparse import minimum_degree_fill


def scan_minimum_degree(adj):
    g = [set(a) for a in adj]
    alive = set(range(len(adj)))
    order, upper = [], []
    while alive:
        k = min(alive, key=lambda x: (len(g[x]), x))
        nb = set(g[k])
        order.append(k)
        upper.append(frozenset(nb))
        for u in nb:
            g[u].discard(k)
            g[u] |= nb - {u}
        alive.discard(k)
        g[k] = set()
    return order, upper


@st.composite
def patterns(draw):
    n = draw(st.integers(1, 24))
    p = draw(st.sampled_from([0.1, 0.2, 0.35]))
    adj = [set() for _ in range(n)]
    for i in range(n):
        for j in range(i + 1, n):
            if draw(st.floats(0, 1)) < p:
                adj[i].add(j)
                adj[j].add(i)
    return adj


@settings(max_examples=60, deadline=None)
@given(patterns())
def test_minimum_degree_equals_the_scanning_recomputation(adj):
    got = minimum_degree_fill(adj, budget=10 ** 9)
    assert got is not None
    order, upper = got
    ref_order, ref_upper = scan_minimum_degree(adj)
    assert list(order) == ref_order
    assert [frozenset(u) for u in upper] == ref_upper
    # every neighbour at elimination is eliminated later (the rows of U couple forward only)
    pos = {k: i for i, k in enumerate(order)}
    assert all(pos[u] > pos[k] for k, nb in zip(order, upper) for u in nb)


def test_a_stale_degree_would_change_the_order():
    """Control: the path 0-1-2-3 plus the edge 1-3; eliminating 0 lowers 1's degree from 3 to 2
    (a fresh heap entry) while node 2 has degree 2 throughout: the order is 0, 1 (tie at 2:
    lowest index)... as the scan says, and differs from the order by initial degrees."""
    adj = [{1}, {0, 2, 3}, {1, 3}, {1, 2}]
    order, _ = minimum_degree_fill(adj, budget=10 ** 6)
    assert list(order) == scan_minimum_degree(adj)[0]
    initial = sorted(range(4), key=lambda x: (len(adj[x]), x))
    assert list(order) != initial
