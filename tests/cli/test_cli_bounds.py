"""Bounds and hostile values at the command line: every attack is one line ``ldaspark: error:``
and exit 2 (never a traceback, a MemoryError, an OverflowError or a full ledger run); Ctrl-C
stops a long compiled run; the interrupt message says whether the output was written."""
import os
import signal
import subprocess
import sys
import time

import pytest

import ldaspark

from run_helpers import assert_ok_or_one_line, run_cli


def one_line(argv, match, seconds=60):
    rc, err = run_cli(argv, seconds)
    assert_ok_or_one_line(rc, err, argv)
    assert rc == 2 and match in err, (argv, rc, err)


INTEGRATE = ["integrate", "skate", "gauss-2", "--h", "0.1", "--t-end", "0.2"]


@pytest.mark.parametrize("extra, match", [
    (["--max-stages", "1000000"], "max_stages must be an integer between 1 and 100"),      # was MemoryError
    (["--every", str(10 ** 40)], "save_every must be an integer between 1 and 1e+09"),       # was exit 1
    (["--dps", "100000"], "dps must be between 16 and 2000"),                               # ran > 40 s
    (["--dps", "-5"], "dps must be between"),
])
def test_integrate_option_bounds(tmp_path, extra, match):
    one_line(INTEGRATE + ["--out", str(tmp_path / "o.json")] + extra, match)
    assert not (tmp_path / "o.json").exists()


def test_method_name_of_5000_digits_is_one_line(tmp_path):
    # was: ValueError: Exceeds the limit (4300 digits) for integer string conversion, after a notice
    one_line(["integrate", "skate", "gauss-irk-" + "9" * 5000, "--h", "0.1", "--t-end", "0.2",
              "--out", str(tmp_path / "o.json")], "unknown method")
    one_line(["integrate", "skate", "gauss-" + "9" * 5000, "--h", "0.1", "--t-end", "0.2",
              "--out", str(tmp_path / "o.json")], "unknown method")


def test_comparator_stage_limit_message_and_max_stages(tmp_path):
    """gauss-irk-21 said "raise it with --max-stages" although --max-stages was ignored for the
    comparators, in two lines (a notice, then the error). Now the stage check comes first (one
    line) and --max-stages applies to gauss-irk-S as to the SPARK names."""
    out = str(tmp_path / "o.json")
    one_line(["integrate", "skate", "gauss-irk-21", "--h", "0.1", "--t-end", "0.1", "--out", out], "raise it")
    rc, err = run_cli(["integrate", "skate", "gauss-irk-21", "--max-stages", "21", "--h", "0.1", "--t-end", "0.1",
                       "--out", out], 120)
    assert rc == 0 and "Traceback" not in err, err
    assert ldaspark.load_result(out).method == "gauss-irk-21"


def test_audit_max_stages_is_bounded():
    one_line(["audit", "--method", "gauss-2", "--max-stages", str(10 ** 8)], "max_stages must be an integer")


@pytest.mark.parametrize("jobs", ["0", "-3"])
def test_verify_jobs_must_be_positive(tmp_path, jobs):
    # was: the full ledger ran with --jobs 0 / --jobs -3
    one_line(["verify", "--quick", "--jobs", jobs, "--outdir", str(tmp_path)], "--jobs must be an integer")
    assert os.listdir(tmp_path) == []


def test_broken_pipe_is_one_line():
    """``ldaspark methods | head -1``: the reader went away. A pipe whose read end is closed
    before the first write makes the failure deterministic (a small output would otherwise fit
    in the pipe's buffer)."""
    r, w = os.pipe()
    os.close(r)
    p = subprocess.run([sys.executable, "-m", "ldaspark", "methods"], stdout=w, stderr=subprocess.PIPE,
                       text=True, env=dict(os.environ, PYTHONPATH=os.getcwd()), timeout=120)
    os.close(w)
    assert p.returncode == 2 and p.stderr == "ldaspark: error: output closed by the reader (broken pipe)\n", p.stderr
    rc, err = run_cli(["methods"])
    assert rc == 0 and err == ""                        # control: a reader that stays


def test_interrupt_message_says_whether_the_output_was_written(tmp_path, monkeypatch):
    """A SIGINT that lands after the output was written said "no partial output was written"
    though the complete new result was there. Simulated deterministically: KeyboardInterrupt
    raised right after the atomic write inside save_result (then: the file is complete and the
    message says so), and right before it writes (the negative control: nothing was written;
    an old file at the path stays as it was)."""
    from ldaspark.core import resultio
    real = resultio.save_result
    out = tmp_path / "o.json"

    def after(res, path):
        real(res, path)
        raise KeyboardInterrupt

    def before(res, path):
        raise KeyboardInterrupt
    monkeypatch.setattr(resultio, "save_result", after)
    rc, err = run_cli(INTEGRATE + ["--out", str(out)])
    assert rc == 130 and err == f"ldaspark: interrupted (after the complete result was written to {out})\n", err
    assert ldaspark.load_result(out).status == 0
    out.write_text("old")
    monkeypatch.setattr(resultio, "save_result", before)
    rc, err = run_cli(INTEGRATE + ["--out", str(out)])
    assert rc == 130 and err == "ldaspark: interrupted (no partial output was written)\n", err
    assert out.read_text() == "old"


_LONG_COMPILED = """
import sys
import ldaspark
from ldaspark.core import chunks
from ldaspark.cli import main
if len(sys.argv) > 2:
    chunks.COMPILED_CHUNK = int(sys.argv[2])
ldaspark.integrate("skate", "gauss-2", t_span=(0, 0.1), h=0.05, engine="compiled")   # compile / load first
print("ready", flush=True)
sys.exit(main(["integrate", "skate", "gauss-2", "--h", "0.001", "--t-end", "1000000", "--every", "100000000",
               "--engine", "compiled", "--out", sys.argv[1]]))
"""


def _interrupt_long_run(out, chunk=None, wait=60):
    args = [sys.executable, "-c", _LONG_COMPILED, str(out)] + ([str(chunk)] if chunk else [])
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         env=dict(os.environ, PYTHONPATH=os.getcwd()), start_new_session=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert p.stdout.readline().strip() == "ready"
        time.sleep(2.0)                 # inside the 10**9-step run, which cannot end in minutes
        os.killpg(p.pid, signal.SIGINT)
        try:
            _, err = p.communicate(timeout=wait)
        except subprocess.TimeoutExpired:
            return None, "still running"
    finally:
        if p.poll() is None:
            os.killpg(p.pid, signal.SIGKILL)
            p.wait()
    return p.returncode, err


def test_ctrl_c_stops_a_long_compiled_run(tmp_path):
    """Before: still running 30 s after SIGINT (a kernel holds the interpreter, the signal waits
    for it to return, and a 10**9-step run never returns). Now the run is a sequence of kernel
    calls of COMPILED_CHUNK steps: exit 130 with one line. The 60 s bound catches a run that
    does not stop (a chunk is 0.1-3 s), not the machine's speed."""
    rc, err = _interrupt_long_run(tmp_path / "o.json")
    assert rc == 130 and err == "ldaspark: interrupted (no partial output was written)\n", (rc, err)
    assert not (tmp_path / "o.json").exists()


@pytest.mark.exhaustive
def test_ctrl_c_negative_control_without_chunks(tmp_path):
    # one kernel call for the whole run: SIGINT waits for the kernel, which does not end in 20 s
    rc, err = _interrupt_long_run(tmp_path / "o.json", chunk=10 ** 9, wait=20)
    assert rc is None and err == "still running"


class _PoolAsked(Exception):
    pass


def test_no_more_pool_workers_than_work_units(monkeypatch, tmp_path):
    """CPython's fork pools start max_workers processes at once: ``report convergence --scenes
    particle skate --workers 24`` forked 24 processes for 2 scenes (counted with ps), and
    ``run_units`` (``verify``, ``mutants``, ``run_many``'s ledger) a pool of --jobs whatever the
    number of units. Now min(workers, units). Control: fewer workers than units stay as asked."""
    import contextlib
    from ldaspark import executors
    from ldaspark.cli import main
    from ldaspark.core import lifecycle
    asked = []

    def pool(max_workers=None, **kw):
        asked.append(max_workers)
        raise _PoolAsked
    monkeypatch.setattr(lifecycle, "make_process_pool", pool)
    monkeypatch.setattr(executors, "make_process_pool", pool)
    for workers in ("24", "1"):     # 1: the scenes run in this process, no pool (control)
        with pytest.raises(_PoolAsked) if workers != "1" else contextlib.nullcontext():
            main(["report", "convergence", "--scenes", "particle", "skate", "--methods", "gauss-1", "--t-end",
                  "0.25", "--workers", workers, "--json", str(tmp_path / "c.json")])
    units = [executors.Unit(f"u{i}", abs, (-i,)) for i in range(3)]
    for jobs in (64, 2):
        with pytest.raises(_PoolAsked):
            executors.run_units(units, jobs=jobs)
    assert asked == [2, 3, 2], asked
