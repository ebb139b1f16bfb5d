"""A run stopped by the user leaves no worker computing and no temporary file.

The real command line runs in a subprocess; a signal (SIGINT, SIGTERM, SIGHUP, SIGQUIT or
SIGKILL) is sent at a chosen moment (while a pool of workers computes, while a result file is
being written, while a run resumes from its checkpoint), and then: no process the run started
is alive 2 s after it ended (checked by pid and start time, through /proc), no temporary file
is left after the next run, the checkpoint is resumed from, the exit status is 128 + the signal
number (SIGKILL: killed), with one ``ldaspark:`` line on stderr naming the signal. The default
run sends each signal at least once (SIGTERM to a pool run, SIGKILL and SIGHUP around a resume,
SIGQUIT and SIGKILL mid-write, SIGINT then SIGTERM to a stuck cleanup); ``--exhaustive`` sends
every signal at every moment.
"""
import glob
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import time

import pytest

from ldaspark.core import lifecycle
import ldaspark.core.io as lio

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")

ROOT = pathlib.Path(__file__).resolve().parents[2]
SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT", "SIGKILL")

# the run starts with the stop signals at their default action whatever the test runner's are
# (a shell's background job ignores SIGINT and SIGQUIT, and the CLI keeps an ignored signal ignored)
_RESET = ("import os, signal, sys\n"
          "for n in ('SIGINT', 'SIGTERM', 'SIGHUP', 'SIGQUIT'):\n"
          "    signal.signal(getattr(signal, n), signal.SIG_DFL)\n"
          "os.execv(sys.executable, [sys.executable] + sys.argv[1:])\n")

# the real command line, with the result's write slowed down: half the bytes, then a pause in
# which the temporary file exists (READY is created then), so that the signal lands mid-write
_SLOW_WRITE = """
import os, sys, time
import ldaspark.core.io as lio
def slow(f, data):
    f.write(data[:len(data) // 2]); f.flush()
    ready = os.environ["LDASPARK_TEST_READY"]
    if os.environ.get("LDASPARK_TEST_HANG"):
        while True:                     # a cleanup that never ends: only the forced stop ends it
            try:
                # ready is signalled inside the try: a SIGINT sent on seeing it, landing before the
                # sleep, was not swallowed (the run stopped in order: 1 failure in a loaded suite)
                open(ready, "w").close()
                time.sleep(60)
            except BaseException:
                pass
    open(ready, "w").close()
    for _ in range(6000):               # short sleeps: a signal landing just before a long one waits it out
        time.sleep(0.01)
    f.write(data[len(data) // 2:])
lio._write_all = slow
from ldaspark.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _env(**extra):
    return dict(os.environ, PYTHONPATH=str(ROOT), PYTHONDONTWRITEBYTECODE="1", **extra)


class Run:
    """One command-line process, its output in files (no pipe to fill), its descendants."""

    def __init__(self, argv, cwd, code=None, env=None):
        self.out, self.err = cwd / f".out-{time.monotonic_ns()}", cwd / f".err-{time.monotonic_ns()}"
        self.out.parent.mkdir(parents=True, exist_ok=True)
        cmd = ([sys.executable, "-c", _RESET] + (["-c", code] if code else ["-m", "ldaspark"]) + list(argv))
        with open(self.out, "w") as o, open(self.err, "w") as e:
            self.p = subprocess.Popen(cmd, cwd=cwd, stdout=o, stderr=e, env=env or _env())
        self.seen = {}

    def stderr(self):
        return self.err.read_text(errors="replace")

    def collect(self):
        """Record the descendants alive now (pid -> start time)."""
        for pid in _descendants(self.p.pid):
            st = _start_time(pid)
            if st is not None:
                self.seen.setdefault(pid, st)
        return self.seen

    def wait_for(self, cond, what, timeout=120):
        deadline = time.monotonic() + timeout
        while not cond():
            self.collect()
            assert self.p.poll() is None, f"the run ended before {what}: {self.p.returncode}\n{self.stderr()[-2000:]}"
            assert time.monotonic() < deadline, f"no {what} within {timeout} s\n{self.stderr()[-2000:]}"
            time.sleep(0.02)
        self.collect()

    def stop(self, signame):
        self.collect()
        self.p.send_signal(getattr(signal, signame))
        try:
            return self.p.wait(timeout=60)
        finally:
            if self.p.poll() is None:
                self.p.kill()

    def survivors(self, within=2.0):
        """Descendants seen during the run and still alive ``within`` s after it ended."""
        deadline = time.monotonic() + within
        while True:
            alive = [pid for pid, st in self.seen.items() if _start_time(pid) == st]
            if not alive or time.monotonic() > deadline:
                return alive
            time.sleep(0.05)

    def kill_survivors(self):
        for pid, st in self.seen.items():
            if _start_time(pid) == st:
                os.kill(pid, signal.SIGKILL)


def _descendants(pid):
    out, todo = [], [pid]
    while todo:
        for path in glob.glob(f"/proc/{todo.pop()}/task/*/children"):
            try:
                kids = [int(k) for k in open(path).read().split()]
            except (OSError, ValueError):
                continue
            for k in kids:
                if k not in out:
                    out.append(k)
                    todo.append(k)
    return out


def _start_time(pid):
    """The start time of a live (not zombie) process, else None (a pid reused later differs)."""
    try:
        fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    return None if fields[0] in ("Z", "X") else fields[19]


def _temp_files(*dirs):
    return [f for d in dirs if os.path.isdir(d) for f in os.listdir(d)
            if f.startswith(".tmp-") or f.endswith(".tmp")]


def _expect_stopped(run, rc, signame):
    """Exit status, one line naming the signal, no traceback, no process left."""
    err = run.stderr()
    try:
        if signame == "SIGKILL":
            assert rc == -signal.SIGKILL
        else:
            assert rc == 128 + getattr(signal, signame), (rc, err[-2000:])
            lines = [ln for ln in err.splitlines() if ln.startswith("ldaspark:")]
            assert len(lines) == 1 and err.rstrip("\n").splitlines()[-1] == lines[0], err[-2000:]
            word = "interrupted" if signame == "SIGINT" else f"stopped by {signame}"
            assert lines[0].startswith(f"ldaspark: {word}"), lines
        assert "Traceback" not in err, err[-3000:]
        assert run.seen, "no child process was seen: the moment was not during a pool run"
        assert run.survivors() == [], "processes of the run still alive 2 s after it ended"
    finally:
        run.kill_survivors()


def _progress_lines(run):
    return len(re.findall(r"^\s+\[\d+/\d+\]", run.stderr(), re.M))


VERIFY = ["verify", "--quick", "--jobs", "2", "--outdir", "out"]


def _pool_started(run, n=2):
    return lambda: len(run.collect()) >= n


# --- during a pool run ------------------------------------------------------------------------
def _matrix(cases, default):
    return [pytest.param(*(c if isinstance(c, tuple) else (c,)), marks=() if c in default else pytest.mark.exhaustive)
            for c in cases]


@pytest.mark.parametrize("command, signame", _matrix(
    [(c, s) for c in ("verify", "convergence") for s in SIGNALS],
    {("convergence", "SIGTERM")}))
def test_signal_during_a_pool_run(tmp_path, command, signame):
    argv = VERIFY if command == "verify" else [
        "report", "convergence", "--json", "out/c.json", "--scenes", "skate", "particle",
        "--methods", "gauss-1", "gauss-2", "--workers", "2"]
    run = Run(argv, tmp_path)
    run.wait_for(_pool_started(run), "two worker processes")
    time.sleep(0.3)                                    # the workers are computing
    rc = run.stop(signame)
    _expect_stopped(run, rc, signame)
    assert _temp_files(tmp_path, tmp_path / "out") == []
    if command == "convergence":
        assert not (tmp_path / "out" / "c.json").exists()


# --- during a resume: the checkpoint survives each signal and the next run resumes from it --------
@pytest.mark.parametrize("first, second", _matrix(
    [(a, b) for a in SIGNALS for b in SIGNALS], {("SIGKILL", "SIGHUP")}))
def test_checkpoint_resumes_after_a_signal_and_a_signal_during_the_resume(tmp_path, first, second):
    run = Run(VERIFY, tmp_path)
    run.wait_for(lambda: _progress_lines(run) >= 1, "a finished unit")
    _expect_stopped(run, run.stop(first), first)
    again = Run(VERIFY, tmp_path)
    again.wait_for(lambda: "resuming:" in again.stderr(), "the resume")
    n = int(re.search(r"resuming: (\d+) of", again.stderr()).group(1))
    assert n >= 1
    again.wait_for(_pool_started(again), "two worker processes")
    _expect_stopped(again, again.stop(second), second)
    # nothing left half-written; a third run resumes at least as much as the second
    assert _temp_files(tmp_path / "out") == []
    third = Run(VERIFY, tmp_path)
    third.wait_for(lambda: "resuming:" in third.stderr(), "the second resume")
    assert int(re.search(r"resuming: (\d+) of", third.stderr()).group(1)) >= n
    try:
        assert third.stop("SIGKILL") == -signal.SIGKILL
        assert third.survivors() == []
    finally:
        third.kill_survivors()


# --- during the write of --out ----------------------------------------------------------------
INTEGRATE = ["integrate", "particle", "gauss-2", "--h", "0.1", "--t-end", "5", "--engine", "generic",
             "--out", "out/result.json"]


def _slow_integrate(tmp_path, hang=False):
    ready = tmp_path / "ready"
    env = _env(LDASPARK_TEST_READY=str(ready), **({"LDASPARK_TEST_HANG": "1"} if hang else {}))
    (tmp_path / "out").mkdir(exist_ok=True)
    (tmp_path / "out" / "result.json").write_text("old")
    run = Run(INTEGRATE, tmp_path, code=_SLOW_WRITE, env=env)
    run.wait_for(ready.exists, "the temporary file")
    assert _temp_files(tmp_path / "out") != []         # the detector sees it while it exists
    return run


@pytest.mark.parametrize("signame", _matrix(list(SIGNALS), {"SIGQUIT", "SIGKILL"}))
def test_signal_during_the_write_of_out(tmp_path, signame):
    run = _slow_integrate(tmp_path)
    rc = run.stop(signame)
    err = run.stderr()
    assert (tmp_path / "out" / "result.json").read_text() == "old"     # the old file is intact
    if signame == "SIGKILL":
        assert rc == -signal.SIGKILL
        left = _temp_files(tmp_path / "out")
        assert len(left) == 1 and lifecycle.is_temp_name(left[0])       # nothing could remove it ...
    else:
        assert rc == 128 + getattr(signal, signame), err
        word = "interrupted" if signame == "SIGINT" else f"stopped by {signame}"
        assert err.splitlines()[-1] == f"ldaspark: {word} (no partial output was written)", err
        assert _temp_files(tmp_path / "out") == []
        return
    # ... and the next run to the same target removes it, and writes a complete result
    nxt = subprocess.run([sys.executable, "-m", "ldaspark", *INTEGRATE], cwd=tmp_path, env=_env(),
                         capture_output=True, text=True, timeout=300)
    assert nxt.returncode == 0, nxt.stderr
    assert _temp_files(tmp_path / "out") == []
    assert json.loads((tmp_path / "out" / "result.json").read_text())["method"]


@pytest.mark.exhaustive
@pytest.mark.parametrize("signame", SIGNALS)
def test_signal_during_the_real_write_of_a_large_out(tmp_path, signame):
    # no seam: a 65 MB JSON result; the signal is sent as soon as its temporary file appears
    argv = ["integrate", "particle", "gauss-2", "--h", "0.001", "--t-end", "300", "--out", "out/big.json"]
    (tmp_path / "out").mkdir()
    run = Run(argv, tmp_path)
    deadline = time.monotonic() + 600
    while not _temp_files(tmp_path / "out"):
        if run.p.poll() is not None or time.monotonic() > deadline:
            run.p.kill()
            pytest.skip("the write ended before the temporary file was seen")
        time.sleep(0.002)
    rc = run.stop(signame)
    out = tmp_path / "out" / "big.json"
    if rc == 0:         # the write was complete when the signal arrived: a complete result
        assert json.loads(out.read_text())["method"]
    elif signame == "SIGKILL":
        assert rc == -signal.SIGKILL and not out.exists()
    else:
        assert rc == 128 + getattr(signal, signame), run.stderr()
        assert _temp_files(tmp_path / "out") == []
    nxt = subprocess.run([sys.executable, "-m", "ldaspark", *argv[:-1], "out/big.json"], cwd=tmp_path,
                         env=_env(), capture_output=True, text=True, timeout=900)
    assert nxt.returncode == 0, nxt.stderr
    assert _temp_files(tmp_path / "out") == []


def test_a_second_signal_forces_the_stop_when_the_cleanup_hangs(tmp_path):
    run = _slow_integrate(tmp_path, hang=True)
    run.p.send_signal(signal.SIGINT)
    with pytest.raises(subprocess.TimeoutExpired):     # the orderly stop is stuck (on purpose)
        run.p.wait(timeout=1.0)
    rc = run.stop("SIGTERM")
    err = run.stderr()
    assert rc == 128 + signal.SIGINT, err              # the status of the first signal
    assert err.splitlines()[-1].startswith("ldaspark: interrupted (forced"), err
    assert _temp_files(tmp_path / "out") == []          # removed by the forced stop too
    assert (tmp_path / "out" / "result.json").read_text() == "old"


# --- the link from worker to parent (with negative controls) -------------------------------------
_POOL = """
import sys, time, concurrent.futures as cf
from ldaspark.core import lifecycle
if sys.argv[1] == "watcher":
    lifecycle.set_death_signal = lambda *a: False      # only the watcher thread links the workers
pool = cf.ProcessPoolExecutor(2) if sys.argv[1] == "plain" else lifecycle.make_process_pool(2)
futs = [pool.submit(time.sleep, 30) for _ in range(2)]
print("ready", flush=True)
time.sleep(60)
"""


@pytest.mark.parametrize("kind", ["pdeathsig", "watcher", "plain"])
def test_workers_die_with_a_killed_parent(tmp_path, kind):
    run = Run([kind], tmp_path, code=_POOL)
    run.wait_for(lambda: run.out.read_text() == "ready\n" and len(run.collect()) >= 2, "the pool")
    rc = run.stop("SIGKILL")
    assert rc == -signal.SIGKILL
    try:
        left = run.survivors()
        if kind == "plain":
            assert len(left) == 2       # negative control: an unlinked pool's workers outlive it
        else:
            assert left == []
    finally:
        run.kill_survivors()


def test_a_pool_left_by_an_exception_terminates_its_workers():
    pool = lifecycle.make_process_pool(2)
    futs = [pool.submit(time.sleep, 30) for _ in range(2)]
    time.sleep(0.2)
    procs = list(pool._processes.values())
    t = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        with pool:
            raise KeyboardInterrupt
    assert time.monotonic() - t < 25                   # not the 30 s of the queue
    assert all(not p.is_alive() for p in procs)
    import concurrent.futures as cf
    assert not cf.wait(futs, timeout=20).not_done      # none of them runs on


def test_a_user_initializer_still_runs(tmp_path):
    mark = tmp_path / "init"
    with lifecycle.make_process_pool(1, initializer=_touch, initargs=(str(mark),)) as pool:
        assert pool.submit(os.path.exists, str(mark)).result(timeout=60)
    with pytest.raises(TypeError):
        lifecycle.make_process_pool(1, initializer=3)


def _touch(path):
    open(path, "w").close()


# --- temporary files ------------------------------------------------------------------------------
def _dead_pid():
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def _plant(d, target_name, pid, host=None):
    tag = lifecycle.TempFile(os.path.join(d, target_name))._tag()
    name = os.path.join(d, f"{lifecycle._PREFIX}{host or lifecycle._HOST}-{pid}-abcd1234.{tag}")
    with open(name, "w") as f:
        f.write("half")
    return name


def test_stale_temporary_files_are_removed_at_the_next_write_and_live_ones_kept(tmp_path):
    target = tmp_path / "r.json"
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        dead = _plant(tmp_path, "r.json", _dead_pid())
        live = _plant(tmp_path, "r.json", sleeper.pid)
        other_host = _plant(tmp_path, "r.json", _dead_pid(), host="0" * 6 if lifecycle._HOST != "0" * 6 else "1" * 6)
        other_target = _plant(tmp_path, "s.json", _dead_pid())
        lio.atomic_write_text(target, "new")
        left = set(os.listdir(tmp_path))
        assert os.path.basename(dead) not in left                      # its writer is dead
        assert {os.path.basename(p) for p in (live, other_host, other_target)} <= left
        assert target.read_text() == "new"
    finally:
        sleeper.kill()
        sleeper.wait()
    # negative control for the detector: the name pattern is what the writer makes
    assert lifecycle.is_temp_name(dead) and not lifecycle.is_temp_name(str(target))


@pytest.mark.parametrize("length", [200, 243, 250, 255])
def test_long_target_names_still_work(tmp_path, length):
    name = "x" * (length - 5) + ".json"
    target = tmp_path / name
    stale = _plant(tmp_path, name, _dead_pid())
    assert len(os.path.basename(stale).encode()) <= 255
    lio.atomic_write_text(target, "new")
    assert target.read_text() == "new" and os.listdir(tmp_path) == [name]


def test_a_planted_symlink_is_never_written_through(tmp_path, monkeypatch):
    victim = tmp_path / "victim"
    victim.write_text("precious")
    target = tmp_path / "r.json"
    tag = lifecycle.TempFile(target)._tag()
    # the first name the writer will try (random characters fixed) is a symlink to the victim
    monkeypatch.setattr(lifecycle.secrets, "choice", lambda seq: "q")
    first = tmp_path / f"{lifecycle._PREFIX}{lifecycle._HOST}-{os.getpid()}-qqqqqqqq.{tag}"
    os.symlink(victim, first)
    choices = iter("q" * 8 + "r" * 8)
    monkeypatch.setattr(lifecycle.secrets, "choice", lambda seq: next(choices))
    lifecycle._temp_files.add(str(first))              # not stale: pretend this process holds it
    try:
        lio.atomic_write_text(target, "new")
    finally:
        lifecycle._temp_files.discard(str(first))
    assert victim.read_text() == "precious" and target.read_text() == "new"
    assert os.path.islink(first)                       # skipped (O_EXCL), not followed


def test_a_planted_stale_symlink_is_removed_not_followed(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("precious")
    tag = lifecycle.TempFile(tmp_path / "r.json")._tag()
    link = tmp_path / f"{lifecycle._PREFIX}{lifecycle._HOST}-{_dead_pid()}-abcd1234.{tag}"
    os.symlink(victim, link)
    lio.atomic_write_text(tmp_path / "r.json", "new")
    assert not os.path.lexists(link) and victim.read_text() == "precious"


def test_temporary_file_is_created_exclusive_and_nofollow(tmp_path, monkeypatch):
    seen = []
    real = os.open

    def spy(path, flags, *a, **k):
        seen.append(flags)
        return real(path, flags, *a, **k)
    monkeypatch.setattr(lifecycle.os, "open", spy)
    lio.atomic_write_text(tmp_path / "r.json", "new")
    assert seen and all(f & os.O_EXCL and f & os.O_NOFOLLOW and f & os.O_CREAT for f in seen)


def test_a_stopped_subprocess_guard_kills_and_refuses_children():
    import threading
    got = {}

    def drive():
        try:
            got["rc"] = lifecycle.run_linked([sys.executable, "-c", "import time; time.sleep(30)"]).returncode
        except BaseException as exc:  # noqa: BLE001
            got["exc"] = exc
    with lifecycle.subprocess_guard() as guard:
        t = threading.Thread(target=drive)
        t.start()
        deadline = time.monotonic() + 60
        while not lifecycle._children and time.monotonic() < deadline:
            time.sleep(0.02)
        guard.stop()
        t.join(timeout=30)
        assert got.get("rc") == -signal.SIGKILL           # the running child was killed
        with pytest.raises(lifecycle.Stopped):             # and no new one starts
            lifecycle.run_linked([sys.executable, "-c", "pass"])
    # negative control: outside the stopped block children start again
    assert lifecycle.run_linked([sys.executable, "-c", "pass"]).returncode == 0


# --- a stop that lands where Python cannot raise it (found by probe t17) --------------------------
def _main_with_a_stop(monkeypatch, body):
    """``ldaspark.cli.main`` with its command replaced by ``body`` (SIGTERM at its default action
    first, as a fresh process has it; restored after)."""
    import ldaspark.cli as cli
    monkeypatch.setattr(cli, "_main", lambda argv: body())
    old = signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        return cli.main([])
    finally:
        signal.signal(signal.SIGTERM, old)


def test_a_stop_raised_inside_a_weakref_callback_still_stops_the_run(monkeypatch, capsys):
    """A handler runs at the next bytecode of the main thread, which can be inside a weakref
    callback (or ``__del__``): there Python prints "Exception ignored in ... Stopped: SIGTERM" and
    drops it. ``report energy --t-end 100`` under SIGTERM exited 0 with that traceback in about one
    run of six, its outputs written. Now the stop is raised again at the next bytecode outside
    it: 143, one line. Control: the same signal in plain code stops the run as before."""
    import weakref

    def in_callback():
        class Obj:
            pass
        obj = Obj()

        def callback(_ref):
            signal.raise_signal(signal.SIGTERM)     # delivered to this thread before it returns
            for _ in range(1000):                   # bytecodes: the handler runs in here
                pass
        ref = weakref.ref(obj, callback)            # noqa: F841 (kept alive until obj dies)
        del obj                                     # the callback runs now
        deadline = time.monotonic() + 3.0           # the run going on: reached only if the stop was lost
        while time.monotonic() < deadline:
            pass
        return 0

    def plain():
        signal.raise_signal(signal.SIGTERM)
        for _ in range(1000):
            pass
        return 0

    assert _main_with_a_stop(monkeypatch, plain) == 143
    assert capsys.readouterr().err.count("\n") == 1
    rc = _main_with_a_stop(monkeypatch, in_callback)
    err = capsys.readouterr().err
    assert rc == 143 and "Exception ignored" not in err and err.count("\n") == 1, (rc, err)
    assert err.startswith("ldaspark: stopped by SIGTERM"), err


def test_a_stop_swallowed_by_the_run_still_sets_the_exit_status(monkeypatch, capsys):
    """Code that catches BaseException swallows the stop where no hook sees it: the run finished,
    exit 0, although it was told to stop. Now 143 and one line saying the run finished. Control: a
    run without a signal exits 0 and prints nothing."""
    def swallowing():
        try:
            signal.raise_signal(signal.SIGTERM)
            for _ in range(1000):
                pass
        except BaseException:                      # noqa: B036 (the point of the test)
            pass
        return 0

    assert _main_with_a_stop(monkeypatch, lambda: 0) == 0 and capsys.readouterr().err == ""
    rc = _main_with_a_stop(monkeypatch, swallowing)
    err = capsys.readouterr().err
    assert rc == 143 and err.count("\n") == 1 and "the run finished" in err, (rc, err)


def test_a_stopped_command_names_the_complete_files_it_wrote(monkeypatch, capsys, tmp_path):
    """``report energy --figure 1 --json F --outdir D`` stopped while it plotted (F written,
    complete) said "no partial output was written", as if nothing had been: the line says what is
    kept (docs/reliability.md, "Signals"). Control: a stop before any write keeps the old words."""
    import ldaspark.cli as cli
    from ldaspark.lab.reports import energy

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt
    argv = ["report", "energy", "--figure", "1", "--t-end", "1", "--outdir", str(tmp_path / "d")]
    monkeypatch.setattr(energy, "plot_energy", ctrl_c)           # after the JSON, during the PNG
    rc = cli.main(argv + ["--json", str(tmp_path / "f1.json")])
    err = capsys.readouterr().err
    assert rc == 130 and err.count("\n") == 1, err
    assert "1 complete file written before it: " + str(tmp_path / "f1.json") in err, err
    assert (tmp_path / "f1.json").is_file()
    monkeypatch.setattr(energy, "figure_data", ctrl_c)           # before any write
    rc = cli.main(argv + ["--json", str(tmp_path / "g1.json")])
    err = capsys.readouterr().err
    assert rc == 130 and err == "ldaspark: interrupted (no partial output was written)\n", err
