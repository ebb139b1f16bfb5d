"""A long run of a block engine (the compiled kernels) as a sequence of kernel calls.

The driver (``ldaspark.solve``) and the ensemble's kernel tasks (``ldaspark.ensemble``) cut a run
into the same blocks, so a member of an ensemble is its single ``integrate`` run bit for bit; the
function lives here, below both layers, so that neither imports the other. ``COMPILED_CHUNK`` is
read at call time: lowering it (tests do, with ``monkeypatch.setattr(chunks, "COMPILED_CHUNK", k)``)
cuts every path's runs alike."""
from __future__ import annotations

import re

import numpy as np

from .errors import LdasparkError
from .result import MSG_DONE, Result, add_counters, attach_counters, failure_counters


#: steps of one block of a chunked engine (the compiled kernels): a long run is a sequence of
#: blocks (each starting from the previous end state), and Python handles a Ctrl-C between two of
#: them (a kernel holds the interpreter). 2**18 steps take 0.1-3 s (0.4-10 us a step), so an
#: interrupt ends the run within a few seconds; runs up to this length are one call, bit for bit
#: as before.
COMPILED_CHUNK = 2 ** 18
#: the counters that add up over the blocks of a chunked run
BLOCK_SUMS = ("steps", "nfev", "njev", "nlu", "newton_iterations", "full_newton_steps", "quasi_iterations",
               "quasi_steps", "quasi_fallbacks", "multiplier_lu", "quasi_skipped", "generic_steps", "rescued_steps",
               "curvature_refreshes", "curvature_steps", "rate_first_steps")


def run_in_blocks(engine, prep, start, n, every, boundaries=None) -> Result:
    """``engine.run`` of n steps from ``start`` = (t0, q0, v0) keeping every ``every``-th sample, in
    blocks of at most COMPILED_CHUNK steps (a ``chunked`` engine) whose ends fall on the saved points
    of a run keeping every ``boundaries``-th step (default ``every``: the guard's rerun of the first
    steps with every step kept gets the blocks of the run it judges, so the predictor restarts at
    the same steps and it sees the same trajectory), so the saved samples are those of one call:
    their times t0 + i h computed as one call computes them; a failure names the step of the whole
    run, in its message too. Between blocks the predictor restarts (the numbers agree with one call
    to the Newton tolerance). Stats: the counters summed over the blocks (``BLOCK_SUMS``),
    max_iterations their maximum, kernel_specialised whether any block ran the specialised kernel."""
    chunk = COMPILED_CHUNK
    if not engine.chunked or n <= chunk:
        return engine.run(prep, start, n, every)
    b = every if boundaries is None else int(boundaries)
    (t0, q0, v0), hf = start, float(prep.prob.h)
    t0f = float(t0)
    parts, stats, done = [], None, 0
    q, v = q0, v0
    while done < n:
        L = min(n - done, (chunk // b) * b) if b <= chunk else min(n - done, chunk, (done // b + 1) * b - done)
        e = every if every <= chunk else L
        try:
            fs = engine.run(prep, (t0f + done * hf, q, v), L, e)
        except LdasparkError as exc:
            if parts and failure_counters(exc) is not None:    # the blocks before count too
                attach_counters(exc, add_counters(stats, failure_counters(exc)))
            if isinstance(getattr(exc, "step", None), int):
                old = exc.step
                exc.step += done
                exc.time = t0f + exc.step * hf
                if done and exc.args and isinstance(exc.args[0], str):
                    # the kernel's message counts the block's steps: the run's step number in it too
                    exc.args = (re.sub(rf"\bstep {old}\b", f"step {exc.step}", exc.args[0]),) + exc.args[1:]
            raise
        if not parts and fs.engine != engine.label:    # the block ran on a fallback, which does not chunk
            return engine.run(prep, start, n, every)
        rows = [0] if not parts else []            # the start of a chunk ends the previous one
        if every <= chunk:
            rows += list(range(1, len(fs.t)))        # its samples fall on multiples of every
        elif (done + L) % every == 0 or done + L == n:
            rows.append(len(fs.t) - 1)               # the chunk's end is a saved point
        # the psi rows of the steps that start at this chunk's saved samples: all of them when
        # the samples fall inside the chunk, else its one step row if the chunk starts at a sample
        psi = None if fs.psi is None else (fs.psi if every <= chunk else fs.psi[:1] if done % every == 0
                                           else fs.psi[:0])
        # the times as one call computes them, t0 + i h (the block's t0 + j h is an ulp off)
        steps_at = np.minimum(np.arange(len(fs.t)) * e, L)
        t_block = t0f + (done + steps_at) * hf
        parts.append((t_block[rows],) + tuple(np.asarray(a)[rows] for a in (fs.q, fs.v, fs.energy, fs.constraint))
                     + (psi,))
        if stats is None:
            stats = dict(fs.stats)
        else:
            for key in BLOCK_SUMS:
                if key in fs.stats:
                    stats[key] = stats.get(key, 0) + fs.stats[key]
            if "max_iterations" in fs.stats:
                stats["max_iterations"] = max(stats.get("max_iterations", 0), fs.stats["max_iterations"])
            if "kernel_specialised" in fs.stats:
                stats["kernel_specialised"] = bool(stats.get("kernel_specialised")) or bool(fs.stats["kernel_specialised"])
        q, v = fs.q[-1], fs.v[-1]
        done += L
    stats["mean_iterations"] = stats.get("newton_iterations", 0) / max(stats.get("steps", 1), 1)
    psi = None if any(p[5] is None for p in parts) else np.concatenate([p[5] for p in parts])
    return Result(*(np.concatenate([p[i] for p in parts]) for i in range(5)), psi, 0, MSG_DONE,
                  *(stats.get(c, 0) for c in ("nfev", "njev", "nlu", "newton_iterations")), engine=engine.label,
                  stats=stats)
