"""Helpers of the input-checking tests: a time bound that turns a hang into a test failure, and
the check that a CLI run ended with rc 0, or rc 2 and exactly one line on stderr."""
import contextlib
import signal
import threading


class Hang(AssertionError):
    pass


@contextlib.contextmanager
def time_bound(seconds):
    """Fail (Hang) instead of hanging when the body runs longer than ``seconds`` (main thread,
    SIGALRM; elsewhere no bound). The bound is generous: it catches hangs, it does not time."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def alarm(signum, frame):
        raise Hang(f"still running after {seconds} s")
    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def run_cli(argv, seconds=60):
    """ldaspark.cli.main(argv) in-process: (rc, stderr), with the time bound."""
    from io import StringIO
    from contextlib import redirect_stderr, redirect_stdout
    from ldaspark.cli import main
    err, out = StringIO(), StringIO()
    with time_bound(seconds), redirect_stderr(err), redirect_stdout(out):
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = exc.code
    return rc, err.getvalue()


def assert_ok_or_one_line(rc, err, argv=None):
    assert rc in (0, 2), (argv, rc, err)
    assert "Traceback" not in err, (argv, err)
    if rc == 2:
        assert err.count("\n") == 1 and err.startswith("ldaspark: error:"), (argv, err)


def two_line_error(cls, first, second, **kw):
    """An error of ``cls`` whose message prints as two lines. LdasparkError escapes a line break
    in the text it is given (``core.errors.one_line``); text from deeper down (a third-party
    exception's message carried over, a subclass's own ``__str__``) may still hold one, and the
    code that keeps only the first line is tested with this."""
    exc = cls(first, **kw)
    exc.args = (f"{first}\n{second}",)
    return exc


def main_rc_err(capsys, argv):
    """(exit code, stderr) of ``ldaspark.cli.main(argv)`` in this process (SystemExit's code as argparse
    exits), for tests that monkeypatch the computation behind a command."""
    from ldaspark.cli import main
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    return rc, capsys.readouterr().err
