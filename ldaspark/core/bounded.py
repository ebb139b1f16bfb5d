"""A time bound on one symbolic step (issue 45, class 3): sympy's ``integrate`` and ``simplify``
have no bound of their own (a curl-free load whose potential sympy cannot integrate ran for ever).
``call_bounded`` runs the step in a forked child process and kills it at the bound; the caller then
takes its sound alternative (``mechanics._potential``: the load enters (1b) as its generalized
force, which is exact, instead of through a potential V in L).

Test: tests/test_bounded_symbolic.py.
"""
from __future__ import annotations

import multiprocessing
import pickle

#: seconds one symbolic step may take before it is abandoned
SYMBOLIC_SECONDS = 20.0


class TimedOut:
    """The result of a step that did not finish within its bound (or failed in the child)."""

    def __repr__(self):
        return "TimedOut"


TIMED_OUT = TimedOut()


def _child(conn, fn, args):
    try:
        conn.send_bytes(pickle.dumps(("ok", fn(*args))))
    except BaseException as exc:            # noqa: BLE001 - reported to the parent, which decides
        try:
            conn.send_bytes(pickle.dumps(("error", repr(exc)[:200])))
        except BaseException:               # noqa: BLE001
            pass
    finally:
        conn.close()


def call_bounded(fn, *args, seconds: float | None = None):
    """``fn(*args)`` if it finishes within ``seconds`` (default ``SYMBOLIC_SECONDS``), else
    ``TIMED_OUT`` (also when it raises or its result cannot be sent back). Runs in a forked child
    where the platform forks; elsewhere in this process, unbounded (as before)."""
    limit = SYMBOLIC_SECONDS if seconds is None else float(seconds)
    if "fork" not in multiprocessing.get_all_start_methods():    # pragma: no cover - Windows
        return fn(*args)
    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, fn, args), daemon=True)
    proc.start()
    send.close()
    try:
        if not recv.poll(limit):
            return TIMED_OUT
        try:
            status, value = pickle.loads(recv.recv_bytes())
        except (EOFError, OSError, pickle.UnpicklingError):
            return TIMED_OUT
        return value if status == "ok" else TIMED_OUT
    finally:
        recv.close()
        if proc.is_alive():
            proc.kill()
        proc.join()
