"""Memo of the boundary-value and IVP solves within one unit of the claims ledger
(``ldaspark.lab.claims.ledger``): the checks of one (tableau, scene) unit solve the same base point
several times. Active only inside ``memoized()``; results are returned as first computed."""
from __future__ import annotations

import contextlib

import mpmath
import numpy as np

_MEMO = None        # dict while ``memoized()`` is active (one ledger unit), else None: no caching


@contextlib.contextmanager
def memoized():
    """Within the block, ``base_point`` and ``discrete_lagrangian`` return the stored result for
    inputs they have already seen (the same system and tableau objects, exactly equal numbers at
    the same precision): the ledger's checks solve the same base point several times (the
    well-posedness, Theorem 1 and symmetry records). The results are the very objects a first
    call returned, so nothing changes but the cost; the store is dropped at the end."""
    global _MEMO
    prev = _MEMO
    _MEMO = {} if prev is None else prev
    try:
        yield
    finally:
        _MEMO = prev


def _key(v):
    """Hashable exact image of a number, array or nested sequence (None for None)."""
    if isinstance(v, mpmath.mpf):
        return v._mpf_
    if isinstance(v, np.ndarray):
        return ("array", v.shape) + tuple(_key(x) for x in v.reshape(-1))
    if isinstance(v, (list, tuple)):
        return ("seq",) + tuple(_key(x) for x in v)
    return (type(v).__name__, repr(v))


def cached(kind, system, tableau, dps, args, compute):
    """``compute()``, or inside ``memoized()`` the result stored for the same kind, system and
    tableau objects, precision and exactly equal ``args``."""
    if _MEMO is None:
        return compute()
    k = (kind, id(system), id(tableau), dps, _key(args))
    hit = _MEMO.get(k)
    if hit is None:
        hit = _MEMO[k] = (compute(), system, tableau)    # the objects kept alive: ids stay unique
    return hit[0]
