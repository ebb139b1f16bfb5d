"""Stand-ins shared by the rule tests of the facade, errors, conditions, ensembles and the ledger:
a fake system, fake hypothesis draws for the strategies of ``verification.strategies``, a
client-less executor, a recorder of checkpoint fingerprints, and two small helpers."""
from __future__ import annotations

import re

import numpy as np
import pytest
import sympy
from hypothesis import HealthCheck, Phase, given, settings

from ldaspark.core.errors import InconsistentInitialDataError, SingularSaddleError
from ldaspark.core.system import LagrangianSystem
from verification import strategies as ST

_PERM = [True]


def _one_line(exc_info):
    msg = str(exc_info.value)
    assert msg and "\n" not in msg
    return msg


@pytest.fixture
def no_client(monkeypatch):
    """distributed.Client replaced by a recorder: a malformed address must be refused before any
    Client exists (a Client waits for its connect timeout, then complains again in __del__)."""
    distributed = pytest.importorskip("distributed")
    made = []
    monkeypatch.setattr(distributed, "Client", lambda *a, **k: made.append(a) or pytest.fail("Client created"))
    return made


def collect(strategy, n):
    """n examples of ``strategy`` (derandomized by the ci profile), no shrinking."""
    out = []

    @settings(max_examples=n, database=None, phases=[Phase.generate],
              suppress_health_check=list(HealthCheck))
    @given(strategy)
    def run(x):
        out.append(x)
    run()
    return out


class FakeSystem:
    """Stands for LagrangianSystem inside ``general_systems``: records L and k; the base point's
    behaviour is set per test through ``FakeSystem.mode``."""
    mode = {}

    def __init__(self, L, k, q, v, t=None, name="system"):
        self.L, self.k, self.q, self.v, self.t, self.name = L, list(k), list(q), list(v), t, name
        self.n, self.m = len(self.q), len(self.k)

    def project_velocity(self, bk, t, q, v):
        if self.mode.get("raise"):
            raise InconsistentInitialDataError("fake: no projection")
        if "v" in self.mode:
            return bk.array(self.mode["v"][:self.n] + [0] * max(0, self.n - len(self.mode["v"])))
        return bk.array(v)

    def check_saddle(self, bk, t, q, v, rcond=None):
        rc = self.mode.get("rc", 1.0)          # the reciprocal condition of this fake's matrix (4)
        if rc <= rcond:
            raise SingularSaddleError("fake: singular")
        return rc


@pytest.fixture
def fake_system(monkeypatch):
    monkeypatch.setattr(ST, "LagrangianSystem", FakeSystem)
    monkeypatch.setattr(FakeSystem, "mode", {})
    return FakeSystem


class _St:
    """Stands for ``hypothesis.strategies`` inside the strategies' definitions, driven by ``_draw``:
    each strategy is a tuple that the fake draw resolves by a policy (module attribute)."""
    integers = staticmethod(lambda lo, hi: ("i", lo, hi))
    fractions = staticmethod(lambda min_value, max_value, max_denominator: ("f", min_value, max_value))
    permutations = staticmethod(lambda x: ("p", list(x), list(x)))
    sampled_from = staticmethod(lambda x: ("p", list(x), list(x)))


def _draw(policy):
    """low: every draw at its lower end (a list: its first element, a permutation: the identity);
    high: the upper end (last element, reversed); zero: 0 where the range holds it, else low."""
    def draw(s):
        kind, a, b = s
        if kind == "p":
            return (a if policy != "high" else a[::-1]) if _PERM[0] else (a[0] if policy != "high" else a[-1])
        if policy == "zero" and a <= 0 <= b:
            return type(a)(0)
        return b if policy == "high" else a
    return draw


def _run(monkeypatch, strategy, policy, perm=True):
    """The composite's definition run once with the fake draws (``perm``: "p" strategies are
    permutations, else sampled_from)."""
    w = strategy.wrapped_strategy
    monkeypatch.setattr(ST, "st", _St)
    _PERM[0] = perm
    return w.definition(_draw(policy), *w.args, **w.kwargs)


def _documented_defaults(doc):
    """{parameter: text} for numpydoc parameters whose description says '(default X' (X up to the
    first ';' or ')' that closes it)."""
    import re
    out, name = {}, None
    for line in (doc or "").splitlines():
        m = re.match(r"^(\w+)(?:, (\w+))* : ", line)
        if m and not line.startswith(" "):
            name = [n.strip() for n in line.split(" : ")[0].split(",")]
            continue
        if name and line.startswith(" "):
            d = re.search(r"\(default ([^;]*?)(?:;|\)$|\)\.|\)\s*$)", line.strip())
            if d:
                for n in name:
                    out[n] = d.group(1).strip()
        elif not line.strip():
            continue
        else:
            name = None
    return out


def _binding(monkeypatch, call):
    from ldaspark.lab import checkpoint as lab_checkpoint
    seen = []

    def fake(work, checkpoint, **kw):
        seen.append(checkpoint.fingerprint)
        return {u.name: [] for u in work}
    monkeypatch.setattr(lab_checkpoint, "run_resumable", fake)
    call(lab_checkpoint.Checkpoint("unused.partial.jsonl", "caller-fp"))
    return seen[-1]


def max_diff(fast, sol):
    return max(float(np.max(np.abs(fast.q - np.asarray(sol.q, float)))),
               float(np.max(np.abs(fast.v - np.asarray(sol.v, float)))),
               float(np.max(np.abs(fast.energy - np.asarray(sol.energy, float)))),
               float(np.max(np.abs(fast.constraint - np.asarray(sol.constraint, float)))))


def two_constraints():
    """n = 4, m = 2, k = (v3 + q2 v4 - cos(q1) v1, v4 + (1 + q3) v3 - q1 v2): the dependent block
    K_dep = [[1, q2], [1 + q3, 1]] is neither diagonal nor symmetric and k_q != 0."""
    q, v = sympy.symbols("q1:5"), sympy.symbols("v1:5")
    L = sum(x ** 2 for x in v) / 2 - (q[0] ** 2 + 2 * q[1] ** 2 + q[2] ** 2 / 2 + q[3] ** 2 / 3) / 2
    k = [v[2] + q[1] * v[3] - sympy.cos(q[0]) * v[0], v[3] + (1 + q[2]) * v[2] - q[0] * v[1]]
    return LagrangianSystem(L, k, q, v, name="two-constraints"), q, v, k
