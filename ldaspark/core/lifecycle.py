"""How a run ends, whatever ends it.

* **Processes die with their parent.** Every worker process the package starts goes through
  ``make_process_pool`` (a ``ProcessPoolExecutor``) or ``run_linked`` (a subprocess): on Linux
  the child asks the kernel for SIGTERM when its parent dies (``PR_SET_PDEATHSIG``); everywhere
  a watcher thread in the child polls its parent pid and ends the child within about a second
  once it changes. A pool left by an exception (Ctrl-C included) terminates its workers instead
  of waiting for them. Pool workers ignore SIGINT, SIGHUP and SIGQUIT (a terminal sends them to
  the whole process group): the parent decides and stops them.
* **One stop policy for the command line** (``stop_on_signals``): every signal whose default
  action terminates the process (``STOP_SIGNALS``, computed from the platform's signal list:
  SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGUSR1, SIGUSR2, SIGALRM, SIGXCPU, SIGVTALRM, SIGPROF, the
  real-time signals, ...; not SIGKILL, which cannot be caught, nor the fault signals SIGSEGV,
  SIGBUS, SIGFPE, SIGILL, SIGTRAP, SIGSYS) raises ``Stopped`` (a ``KeyboardInterrupt``) in the
  main thread, so that every cleanup
  that runs for Ctrl-C runs for each of them (workers stopped, checkpoints closed, temporary
  files removed); the command line prints one line and exits with 128 + the signal number. A
  second stop signal, or a cleanup that takes longer than ``deadline`` seconds, ends the run at
  once: registered workers and subprocesses are killed, live temporary files removed.
  A signal that is ignored when the run starts (``nohup``) stays ignored.
* **Temporary files** (``TempFile``) are named ``.tmp-ldaspark-<host>-<pid>-<random>.<target>``
  beside their target, at most NAME_MAX bytes (a long target name is shortened and hashed),
  created with O_CREAT | O_EXCL | O_NOFOLLOW (never through a planted file or symbolic link).
  One left by a killed writer (its pid no longer alive on this host) is removed at the next
  write to the same target; nothing ever reads one as a result.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import errno
import hashlib
import os
import re
import secrets
import signal
import socket
import sys
import threading
import time
import weakref

#: the signals a terminal sends to the whole process group (and SIGTERM): the first four of the
#: policy, named in messages and documentation
STOP_SIGNAL_NAMES = ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT")
#: default actions that do not terminate the process (POSIX <signal.h>: ignore, stop, continue;
#: SIGINFO, SIGWAITING, SIGLWP, SIGTHR, SIGCANCEL: ignored on the BSDs and Solaris)
_NOT_TERMINATING = frozenset(("SIGCHLD", "SIGCLD", "SIGCONT", "SIGSTOP", "SIGTSTP", "SIGTTIN", "SIGTTOU",
                              "SIGURG", "SIGWINCH", "SIGINFO", "SIGWAITING", "SIGLWP", "SIGTHR", "SIGCANCEL"))
#: terminating, but not caught: SIGKILL cannot be; the synchronous fault signals must not be (the
#: kernel sends them for the faulting instruction itself, and a Python-level handler returns to
#: it: an endless loop instead of a crash); a file left by them is removed by the next write's
#: sweep, its writer being dead
UNCAUGHT_SIGNAL_NAMES = ("SIGKILL", "SIGSEGV", "SIGBUS", "SIGFPE", "SIGILL", "SIGTRAP", "SIGSYS", "SIGEMT")


def _terminating_signals() -> tuple:
    """Every signal of this platform (``signal.valid_signals``, real-time signals included)
    whose default action terminates the process and that can be caught safely, in number
    order; SIGINT, SIGTERM, SIGHUP and SIGQUIT are among them wherever the platform has them."""
    names = {}
    for sig in signal.Signals:              # aliases (SIGIOT, SIGPOLL, SIGCLD) share a number
        names.setdefault(int(sig), set()).add(sig.name)
    for n in ("SIGCLD", "SIGPOLL", "SIGIOT"):
        if hasattr(signal, n):
            names.setdefault(int(getattr(signal, n)), set()).add(n)
    try:
        valid = sorted(int(s) for s in signal.valid_signals())
    except (AttributeError, ValueError, OSError):       # pragma: no cover - Python < 3.8
        valid = sorted(names)
    skip = _NOT_TERMINATING | set(UNCAUGHT_SIGNAL_NAMES)
    out = []
    for num in valid:
        if names.get(num, set()) & skip:
            continue
        # a signal without a name is a real-time one (SIGRTMIN + k): terminating by default
        out.append(signal.Signals(num) if num in names else num)
    return tuple(out)


#: the stop policy's signals: every signal of this platform whose default action terminates the
#: process, computed from the platform's list (``_terminating_signals``), not a list of four
STOP_SIGNALS = _terminating_signals()
# what a pool worker ignores: the terminal's stop signals, which it sends to the whole process
# group; the parent stops the worker (SIGTERM keeps its default action, so that terminating a
# worker ends it at once, whatever it computes)
_WORKER_IGNORES = tuple(getattr(signal, n) for n in ("SIGINT", "SIGHUP", "SIGQUIT") if hasattr(signal, n))
# the signal a child receives when its parent dies; SIGTERM rather than SIGKILL so that a child
# in the middle of an atomic write removes its temporary file (the watcher thread follows up
# with os._exit if it is still alive a second later)
DEATH_SIGNAL = getattr(signal, "SIGTERM", 15)
_PR_SET_PDEATHSIG = 1
_WATCH_PERIOD = 0.2


class Stopped(KeyboardInterrupt):
    """A stop signal arrived (``STOP_SIGNALS``: SIGINT, SIGTERM, SIGHUP, SIGQUIT and every other
    signal whose default action terminates the process); a ``KeyboardInterrupt``, so
    that every cleanup written for Ctrl-C runs for it too."""

    def __init__(self, signum: int = signal.SIGINT):
        self.signum = int(signum)
        super().__init__(signal_name(self.signum))

    @property
    def name(self) -> str:
        return signal_name(self.signum)


def signal_name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def signum_of(exc: BaseException) -> int:
    """The signal behind an interrupt: ``Stopped.signum``; a plain ``KeyboardInterrupt`` is SIGINT."""
    return int(getattr(exc, "signum", signal.SIGINT))


def exit_status(signum: int) -> int:
    """The shell's convention for a run ended by a signal: 128 + its number."""
    return 128 + int(signum)


# --- what this process started and has not finished (for the forced stop) ----------------------
_pools: "weakref.WeakSet" = weakref.WeakSet()
_children: set = set()
_temp_files: set = set()
_registry_lock = threading.RLock()      # reentrant: a forced stop may run inside a holder (signal handler)


def kill_children() -> None:
    """SIGKILL every live worker of the pools made here and every ``run_linked`` subprocess."""
    for pool in list(_pools):
        for p in list((getattr(pool, "_processes", None) or {}).values()):
            with contextlib.suppress(Exception):
                if p.is_alive():
                    p.kill()
    kill_subprocesses()


_no_new_children = threading.Event()


@contextlib.contextmanager
def subprocess_guard():
    """For threads that each drive a ``run_linked`` subprocess: ``stop()`` kills the running
    ones and refuses new ones until the block ends (so that leaving a thread pool does not wait
    for a subprocess that a thread started after the stop)."""
    class _Guard:
        @staticmethod
        def stop():
            with _registry_lock:
                _no_new_children.set()
            kill_subprocesses()
    try:
        yield _Guard()
    finally:
        _no_new_children.clear()


def kill_subprocesses() -> None:
    """SIGKILL every live ``run_linked`` subprocess of this process."""
    with _registry_lock:
        children = list(_children)
    for c in children:
        with contextlib.suppress(Exception):
            if c.poll() is None:
                c.kill()


def remove_temp_files() -> None:
    with _registry_lock:
        names = list(_temp_files)
    for name in names:
        with contextlib.suppress(OSError):
            os.unlink(name)


# --- children that die with their parent --------------------------------------------------------
def set_death_signal(sig: int = DEATH_SIGNAL) -> bool:
    """Linux: ask the kernel to send ``sig`` to this process when the thread that created it
    ends (its parent process, for the callers here). False where that is not available."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError, ImportError):
        return False


def _watch_parent(ppid: int) -> None:
    while True:
        time.sleep(_WATCH_PERIOD)
        if os.getppid() != ppid:            # reparented: the parent is gone
            with contextlib.suppress(OSError):
                os.kill(os.getpid(), DEATH_SIGNAL)      # the path with cleanup first ...
            time.sleep(1.0)
            os._exit(exit_status(DEATH_SIGNAL))         # ... then without


def link_to_parent(parent_pid: int | None, death_signal: bool = True) -> None:
    """In a child: end it when its parent ends (the death signal where the platform has it,
    and a watcher thread on the parent pid). ``parent_pid``: the pid the child must have as
    parent (a parent that died before this call is noticed here); None when the child's
    parent is an intermediary (multiprocessing's forkserver)."""
    if death_signal:
        set_death_signal()
    ppid = os.getppid()
    if parent_pid is not None and ppid != parent_pid:
        os._exit(exit_status(DEATH_SIGNAL))
    if os.name == "posix":
        threading.Thread(target=_watch_parent, args=(ppid,), name="ldaspark-parent-watch", daemon=True).start()


def worker_initializer(parent_pid=None, death_signal=True, initializer=None, initargs=()):
    """Initializer of every pool worker: linked to its parent, the terminal's stop signals
    ignored (the parent stops the worker), SIGTERM at its default action (a Python handler
    inherited through fork would make terminate() a no-op), then the caller's own initializer.
    The stop signals arrive blocked (``LinkedProcessPool._spawn_process``): unblocked once the
    worker's own actions are set, before its watcher thread starts (threads inherit the mask)."""
    for s in _WORKER_IGNORES:
        with contextlib.suppress(OSError, ValueError):
            signal.signal(s, signal.SIG_IGN)
    with contextlib.suppress(OSError, ValueError, AttributeError):
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    with contextlib.suppress(OSError, ValueError, AttributeError):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    link_to_parent(parent_pid, death_signal)
    if initializer is not None:
        initializer(*initargs)


class LinkedProcessPool(cf.ProcessPoolExecutor):
    """A ``ProcessPoolExecutor`` whose workers die with this process (``worker_initializer``);
    leaving its ``with`` block by an exception terminates the workers instead of waiting for
    the queue; ``terminate_workers()`` stops them now."""

    def __init__(self, max_workers=None, mp_context=None, initializer=None, initargs=(), **kwargs):
        if initializer is not None and not callable(initializer):
            raise TypeError("initializer must be a callable")
        self._user_initializer = (initializer, tuple(initargs))
        super().__init__(max_workers, mp_context=mp_context, initializer=worker_initializer,
                         initargs=(None, False, initializer, tuple(initargs)), **kwargs)
        self._initargs = self._link_args()
        _pools.add(self)

    def _link_args(self):
        method = None
        with contextlib.suppress(Exception):
            method = self._mp_context.get_start_method()
        # the workers of "fork" and "spawn" are children of this process; those of
        # "forkserver" are children of the server (which itself ends with this process)
        parent = os.getpid() if method in ("fork", "spawn") else None
        # the death signal follows the creating thread, not the process: a pool started from a
        # thread that may end first relies on the watcher thread only
        main = threading.current_thread() is threading.main_thread()
        init, args = self._user_initializer
        return (parent, main, init, args)

    def _spawn_process(self):       # where CPython starts each worker: this thread spawns it
        self._initargs = self._link_args()
        # a stop signal handled in the middle of the fork would raise Stopped inside an at-fork
        # callback (logging's _releaseLock), where Python only prints "Exception ignored" and
        # goes on: held back until the worker is started and registered, raised after that
        with signals_blocked():
            return super()._spawn_process()

    def terminate_workers(self):
        """Cancel what is queued and end the workers now (SIGTERM, SIGKILL after 2 s)."""
        procs = list((getattr(self, "_processes", None) or {}).values())
        manager = getattr(self, "_executor_manager_thread", None)      # shutdown drops it
        with contextlib.suppress(Exception):
            self.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            with contextlib.suppress(OSError, AttributeError, ValueError):
                p.terminate()
        deadline = time.monotonic() + 2.0
        for p in procs:
            with contextlib.suppress(OSError, AttributeError, ValueError, AssertionError):
                p.join(timeout=max(0.0, deadline - time.monotonic()))
        for p in procs:
            with contextlib.suppress(OSError, AttributeError, ValueError, AssertionError):
                if p.is_alive():
                    p.kill()
                    p.join(timeout=1.0)
        # the executor's manager thread closes its wakeup pipe when it ends; left running, it
        # races CPython 3.11's exit hook (concurrent.futures.process._python_exit), which then
        # writes to the closed pipe: "Exception ignored ... OSError: Bad file descriptor" on
        # stderr after the stop line
        if manager is not None and manager is not threading.current_thread():
            with contextlib.suppress(RuntimeError):
                manager.join(timeout=2.0)

    def __exit__(self, typ, exc, tb):
        if typ is not None:
            self.terminate_workers()
            return False
        return super().__exit__(typ, exc, tb)


def make_process_pool(max_workers=None, mp_context=None, initializer=None, initargs=(), **kwargs):
    """The one way the package makes a process pool (see ``LinkedProcessPool``)."""
    return LinkedProcessPool(max_workers, mp_context=mp_context, initializer=initializer,
                             initargs=initargs, **kwargs)


# a child started by run_linked asks for the death signal before it becomes the program
# (and unblocks the stop signals run_linked held back around its start: exec keeps the mask)
_BOOT = ("import sys\n"
         "if sys.path and sys.path[0] == '':\n"      # -c: the working directory (a planted ctypes.py)
         "    del sys.path[0]\n"
         "import os, signal\n"
         "try:\n"
         "    import ctypes\n"
         "    ctypes.CDLL(None).prctl(1, int(sys.argv[1]), 0, 0, 0)\n"
         "except Exception:\n"
         "    pass\n"
         "if os.getppid() != int(sys.argv[2]):\n"
         "    os._exit(1)\n"
         "if sys.argv[3]:\n"
         "    signal.pthread_sigmask(signal.SIG_UNBLOCK, [int(x) for x in sys.argv[3].split(',')])\n"
         "os.execv(sys.argv[4], sys.argv[4:])\n")


#: the directory this process imported ldaspark from (the parent of the package)
_PACKAGE_ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def python_code(code: str) -> str:
    """``code`` for a child ``python -c`` that imports ldaspark (and numpy, h5py, ...) as this
    process does, never from its working directory: ``-c`` and ``-m`` put that directory first on
    the child's sys.path, so a planted h5py.py, ctypes.py or ldaspark/ in the directory the user
    runs from (a downloaded archive of result files) ran in the child, while the parent (a console
    script) never looks there. The package's own root is put first when the child would not find
    it (the parent imported it from its working directory, or through an editable install's hook)."""
    root = _PACKAGE_ROOT
    return ("import sys\n"
            "if sys.path and sys.path[0] == '':\n"
            "    del sys.path[0]\n"
            f"if {root!r} not in sys.path:\n"
            f"    sys.path.insert(0, {root!r})\n" + code)


def linked_command(cmd: list) -> list:
    """``cmd`` (its first word an absolute path) started so that it dies with this process:
    on Linux through a small Python stub that sets the death signal and then execs it."""
    if not sys.platform.startswith("linux") or not sys.executable:
        return list(cmd)
    held = ",".join(str(int(x)) for x in STOP_SIGNALS) if hasattr(signal, "pthread_sigmask") else ""
    return [sys.executable, "-c", _BOOT, str(int(DEATH_SIGNAL)), str(os.getpid()), held, *map(str, cmd)]


def run_linked(cmd, timeout=None, **kwargs):
    """``subprocess.run(cmd, timeout=...)`` for a child that dies with this process (also on
    SIGKILL of this process, on Linux) and is killed when this process is stopped. Returns the
    ``CompletedProcess``; raises ``subprocess.TimeoutExpired`` as ``subprocess.run`` does."""
    import subprocess
    cmd = list(cmd)
    if kwargs.pop("capture_output", False):
        kwargs["stdout"] = kwargs["stderr"] = subprocess.PIPE
    linked = linked_command(cmd)
    # a stop signal raised between the start and the registration would leave the child running
    # unregistered (not killed by the stop): held back across both where the stub unblocks it in
    # the child (Linux); elsewhere the child would inherit the blocked mask
    hold = signals_blocked() if linked != cmd else contextlib.nullcontext()
    with hold, _registry_lock:  # with stop_subprocesses(): either refused or registered, then killed
        if _no_new_children.is_set():
            raise Stopped(DEATH_SIGNAL)
        proc = subprocess.Popen(linked, **kwargs)
        _children.add(proc)
    try:
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired as exc:
            proc.kill()
            out, err = proc.communicate()
            exc.stdout, exc.stderr = out, err
            raise
        except BaseException:
            proc.kill()
            with contextlib.suppress(Exception):
                proc.wait(timeout=5)
            raise
    finally:
        with _registry_lock:
            _children.discard(proc)
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


# --- one stop policy ----------------------------------------------------------------------------
def _takes_default(sig) -> bool:
    try:
        cur = signal.getsignal(sig)
    except (ValueError, OSError):
        return False
    return cur == signal.SIG_DFL or cur is signal.default_int_handler


@contextlib.contextmanager
def signals_blocked(signals=STOP_SIGNALS):
    """Stop signals held back (delivered on exit) while a few statements must run together."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:
        yield
        return
    old = mask(signal.SIG_BLOCK, signals)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, old)


class stop_on_signals:
    """The command line's stop policy (see the module docstring): within the block each stop
    signal whose action is the default raises ``Stopped`` in the main thread; ``received``
    is the first one's number. ``deadline``: seconds after the first signal before the run is
    ended without its orderly cleanup; ``line(signum)`` is printed to stderr then."""

    def __init__(self, deadline: float = 10.0, line=None):
        self.deadline, self.line = deadline, line
        self.received = None
        self.old = {}
        self._timer = None
        self.pid = os.getpid()
        self._redeliver = False
        self._old_hook = None

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for s in STOP_SIGNALS:
                if _takes_default(s):
                    with contextlib.suppress(ValueError, OSError):
                        self.old[s] = signal.signal(s, self._handler)
            if self.old:
                self._old_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def _unraisable(self, unraisable):
        """``sys.unraisablehook`` while the policy holds. A handler runs at the next bytecode of the
        main thread, which may be inside a weakref callback, a ``__del__`` or a GC callback, where
        Python cannot propagate an exception: it printed "Exception ignored in ... Stopped:
        SIGTERM" and the run went on to exit 0. The stop is raised again at the next opportunity
        (``_thread.interrupt_main`` runs ``_handler`` again, flagged as this re-delivery, not as a
        second signal that forces the end); anything else goes to the previous hook."""
        if isinstance(unraisable.exc_value, Stopped) and os.getpid() == self.pid and self.received is not None:
            self._redeliver = True
            self._schedule_redelivery()
            return
        (self._old_hook or sys.__unraisablehook__)(unraisable)

    def _schedule_redelivery(self):
        """``_thread.interrupt_main`` from a timer thread, so that the handler runs after this hook
        has returned (called from the hook itself it ran inside it, and the hook's own exception
        was reported as "Exception ignored in sys.unraisablehook")."""
        import _thread
        t = threading.Timer(0.01, _thread.interrupt_main, args=(self.received,))
        t.daemon = True
        t.start()
        self._redelivery = t

    def _handler(self, signum, frame):
        if os.getpid() != self.pid:
            return _as_default(signum)    # a forked worker before its initializer reset this
        if self._redeliver:               # a stop that was swallowed (``_unraisable``), raised again
            if _runs_inside(frame, stop_on_signals._unraisable.__code__):
                return self._schedule_redelivery()      # still inside the hook: once it returned
            self._redeliver = False
            raise Stopped(self.received)
        if self.received is None:
            self.received = signum
            self._timer = threading.Timer(self.deadline, self.force, args=(signum,))
            self._timer.daemon = True
            self._timer.start()
            raise Stopped(signum)
        self.force(self.received)          # insisted: end now

    def force(self, signum):
        """End the process now: kill the workers and subprocesses, remove the temporary files,
        one line, exit status 128 + ``signum`` (the checkpoints' lines are already on disk)."""
        kill_children()
        remove_temp_files()
        with contextlib.suppress(Exception):
            msg = self.line(signum) if self.line is not None else f"ldaspark: stopped by {signal_name(signum)}"
            os.write(2, (msg + "\n").encode())
        os._exit(exit_status(signum))

    def __exit__(self, *exc):
        if self._timer is not None:
            self._timer.cancel()
        for s, old in self.old.items():
            with contextlib.suppress(ValueError, OSError, TypeError):
                signal.signal(s, old)
        if self._old_hook is not None and sys.unraisablehook == self._unraisable:
            sys.unraisablehook = self._old_hook
        if getattr(self, "_redelivery", None) is not None:
            self._redelivery.cancel()
        return False


def _runs_inside(frame, code, depth: int = 64) -> bool:
    """Whether ``frame`` or one of its callers (up to ``depth``) runs ``code``."""
    while frame is not None and depth > 0:
        if frame.f_code is code:
            return True
        frame, depth = frame.f_back, depth - 1
    return False


class raise_on_stop_signals:
    """Outside the command line (a library writing a file): while the block runs, every stop
    signal (``STOP_SIGNALS``: SIGTERM, SIGHUP, SIGQUIT, SIGUSR1, SIGALRM, SIGXCPU, ...) raises
    ``Stopped`` (SIGINT raises KeyboardInterrupt as always) so that
    its cleanup runs; on the way out their previous action is restored and the signal sent
    again, so that the process still ends by it as its parent expects. Only in the main thread
    and only for signals at their default action (the command line's or a program's own
    handlers are left alone)."""

    def __enter__(self):
        self.old = {}
        self.pid = os.getpid()
        if threading.current_thread() is threading.main_thread():
            for s in STOP_SIGNALS:
                if s != signal.SIGINT and _takes_default(s):
                    with contextlib.suppress(ValueError, OSError):
                        self.old[s] = signal.signal(s, self._raise)
        return self

    def _raise(self, signum, frame):
        if os.getpid() != self.pid:
            return _as_default(signum)
        raise Stopped(signum)

    def __exit__(self, typ, exc, tb):
        for s, old in self.old.items():
            with contextlib.suppress(ValueError, OSError, TypeError):
                signal.signal(s, old)
        if isinstance(exc, Stopped) and exc.signum in self.old:
            os.kill(os.getpid(), exc.signum)
        return False


def _as_default(signum):
    """In a process that inherited a handler through fork: what the default action would do."""
    with contextlib.suppress(ValueError, OSError):
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)


# --- temporary files ----------------------------------------------------------------------------
_PREFIX = ".tmp-ldaspark-"


def _host_tag() -> str:
    try:
        host = socket.gethostname()
    except OSError:
        host = ""
    return hashlib.sha256(host.encode("utf-8", "surrogateescape")).hexdigest()[:6]


_HOST = _host_tag()


def _name_max(d) -> int:
    try:
        return int(os.pathconf(d, "PC_NAME_MAX"))
    except (OSError, ValueError, AttributeError):
        return 255


def temp_tag(base: str, room: int) -> str:
    """``base`` when it fits in ``room`` bytes, else a prefix of it and a hash of the whole name
    (deterministic: the next write to the same target finds the stale files)."""
    if len(os.fsencode(base)) <= room:
        return base
    digest = "~" + hashlib.sha256(os.fsencode(base)).hexdigest()[:16]
    keep = base
    while keep and len(os.fsencode(keep + digest)) > room:
        keep = keep[:-1]
    return keep + digest


#: the largest process id a temporary file name may carry: pid_t is a signed 32-bit integer on
#: every platform the package runs on (Linux caps pids at 2^22, macOS at 99999)
PID_MAX = 2 ** 31 - 1
# the pid as TempFile writes it: ASCII digits, no sign, no leading zero, at most 10 digits (a
# bare ``\d`` would also take Arabic-Indic and other Unicode digits, which int() converts)
_PID_RE = r"([1-9][0-9]{0,9})"


def _stale_pattern(tag: str):
    return re.compile(re.escape(_PREFIX) + r"([0-9a-f]{6})-" + _PID_RE + r"-[0-9a-z]{8}\." + re.escape(tag) + r"\Z",
                      re.S | re.ASCII)


def parse_temp_pid(text: str) -> int | None:
    """The writer's pid in a temporary file name's pid field, or None when the field is not one
    that ``TempFile`` writes (empty, signed, a leading zero, non-ASCII digits, beyond PID_MAX):
    such a file is not ours, and the sweep leaves it (a planted ``...-99999999999999999999-...``
    once made every later write fail with OverflowError in ``os.kill``)."""
    if not isinstance(text, str) or re.fullmatch(_PID_RE, text, re.ASCII) is None:
        return None
    pid = int(text)
    return pid if 0 < pid <= PID_MAX else None


def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    if not 0 < pid <= PID_MAX:
        return True          # not a pid this platform has: cannot tell, keep the file
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError, OverflowError, ValueError):
        return True          # someone else's process, or cannot tell: keep its file
    return True


class TempFile:
    """A temporary file beside ``target`` (see the module docstring). ``create()`` makes it (and
    first removes the stale ones of the same target); ``remove()`` deletes it if it is still
    there; while it exists it is registered, so that a forced stop removes it."""

    def __init__(self, target):
        self.target = os.fspath(target)
        self.dir = os.path.dirname(os.path.abspath(self.target))
        self.name = None
        self.fd = None

    def _tag(self):
        base = os.path.basename(self.target)
        # fixed part: prefix, host, a pid of up to 10 digits, 8 random characters, three
        # separators (the tag must not depend on the writer's pid: stale files are found by it)
        room = _name_max(self.dir) - len(_PREFIX) - len(_HOST) - 10 - 8 - 3
        return temp_tag(base, max(room, 16))

    def remove_stale(self) -> list:
        """Remove this target's temporary files whose writer (this host, that pid) is dead, and
        this process's own that it no longer holds. Returns the names removed."""
        pat = _stale_pattern(self._tag())
        gone = []
        try:
            entries = os.listdir(self.dir)
        except OSError:
            return gone
        with _registry_lock:
            ours = set(_temp_files)
        for e in entries:
            m = pat.match(e)
            if not m or m.group(1) != _HOST:
                continue
            pid = parse_temp_pid(m.group(2))
            if pid is None:
                continue                    # not a name this writer makes: not ours, left
            full = os.path.join(self.dir, e)
            if pid == os.getpid() and full in ours:
                continue
            if pid != os.getpid() and _pid_alive(pid):
                continue
            with contextlib.suppress(OSError):
                os.unlink(full)             # a symbolic link is removed itself, never followed
                gone.append(e)
        return gone

    def create(self, mode: int = 0o600) -> int:
        """Create the file (O_CREAT | O_EXCL | O_NOFOLLOW); returns its descriptor."""
        self.remove_stale()
        tag = self._tag()
        flags = (os.O_RDWR | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
                 | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0))
        for _ in range(100):
            rand = "".join(secrets.choice("abcdefghijklmnopqrstuvwxyz0123456789") for _ in range(8))
            name = os.path.join(self.dir, f"{_PREFIX}{_HOST}-{os.getpid()}-{rand}.{tag}")
            with signals_blocked():        # the name is known before any handler can run
                try:
                    fd = os.open(name, flags, mode)
                except FileExistsError:
                    continue
                self.name, self.fd = name, fd
                with _registry_lock:
                    _temp_files.add(name)
            return fd
        raise FileExistsError(errno.EEXIST, "no free temporary file name", self.dir)

    def fdopen(self, mode="wb"):
        """The file object over the descriptor (which it then owns)."""
        with signals_blocked():
            f = os.fdopen(self.fd, mode)
            self.fd = None
        return f

    def remove(self) -> None:
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.close(self.fd)
            self.fd = None
        if self.name is not None:
            with contextlib.suppress(OSError):
                os.unlink(self.name)
            self.forget()

    def forget(self) -> None:
        """The file is no longer this writer's (replaced onto its target, or removed)."""
        if self.name is not None:
            with _registry_lock:
                _temp_files.discard(self.name)


def is_temp_name(name: str) -> bool:
    """A name made by ``TempFile`` (for any target)."""
    m = re.match(re.escape(_PREFIX) + r"[0-9a-f]{6}-" + _PID_RE + r"-[0-9a-z]{8}\.", os.path.basename(name), re.ASCII)
    return m is not None and parse_temp_pid(m.group(1)) is not None
