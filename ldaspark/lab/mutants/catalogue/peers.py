"""Mutants of the peer harness and of the equal-error comparison: the interpolation
in log-log, the lower envelope, the best peer, the speed-up, IDA's index-1 residual, the README
check of timings and residual classes."""
from ..mutant import _m

TP = "tests/lab/reports/test_peers.py"
# test_readme.py's checks of the committed reports fail in the mutants' scratch copy (it has no
# reports/): the README-check mutants are hinted at the synthetic tests, which need none
TR = "tests/lab/reports/test_readme_kinds.py"

MUTANTS = (
    _m("peers-interp-lin-lin", "lab/reports/envelope.py",
       "return float(10 ** np.interp(np.log10(target), np.log10(errs[keep]), np.log10(cpus[keep])))",
       "return float(np.interp(target, errs[keep], cpus[keep]))",
       "equal-error CPU time interpolated in lin-lin instead of log-log", "peers", TP),
    _m("peers-no-envelope", "lab/reports/envelope.py",
       "keep = cpus <= np.minimum.accumulate(cpus)", "keep = cpus == cpus",
       "equal-error cost from every run, not the lower envelope (a dominated run counts)", "peers", TP),
    _m("peers-best-is-worst", "lab/reports/peers.py",
       "p = min(costs, key=costs.get)", "p = max(costs, key=costs.get)",
       "the best peer at a target taken as the most expensive one", "peers", TP),
    _m("peers-speedup-inverted", "lab/reports/peers.py",
       "ratio = (pc / sc) if (sc and pc) else None", "ratio = (sc / pc) if (sc and pc) else None",
       "speed-up cpu(SPARK) / cpu(peer) instead of cpu(peer) / cpu(SPARK)", "peers", TP),
    _m("peers-study-best-is-worst", "lab/reports/peers.py",
       "m = min(costs, key=lambda k: costs[k][0])", "m = max(costs, key=lambda k: costs[k][0])",
       "the study's best SPARK method and best peer taken as the most expensive", "peers", TP),
    _m("peers-bound-direction", "lab/reports/peers.py",
       '"speedup_at_least": ratio if (ratio is not None and sb and not pb) else None',
       '"speedup_at_least": ratio if (ratio is not None and pb and not sb) else None',
       "a speed-up bounded by the peer's cost reported as a lower bound", "peers", TP),
    _m("peers-main-best-peer-worst", "lab/reports/work_precision.py",
       "if best_scipy is not None and (pc is None or best_scipy < pc):",
       "if best_scipy is not None and (pc is None or best_scipy > pc):",
       "work-precision's best peer: solve_ivp taken when it is dearer than the compiled peers", "peers", TP),
    _m("peers-ida-psi-sign", "compiled/ode.py",
       "x[n:] = y[2 * n:]", "x[n:] = -y[2 * n:]",
       "IDA's index-1 residual with K^T psi of the wrong sign", "peers", TP),
    _m("peers-readme-residual-any-class", "lab/reports/summary.py",
       "return abs(math.log10(abs(x) / abs(y))) <= 1.0", "return True",
       "README residuals accepted whatever their order of magnitude", "peers", TR),
    _m("peers-readme-timing-unchecked", "lab/reports/summary.py",
       "        if shown != snap[\"values\"][key]:\n",
       "        if False:\n",
       "README timings not compared with the committed snapshot", "peers", TR),
)
