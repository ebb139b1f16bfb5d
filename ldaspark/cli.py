"""Command line: ``ldaspark integrate | methods | report | verify | audit`` (also ``python -m ldaspark``).

User errors (LdasparkError) print one line to stderr and exit 2, without a traceback.
Subcommands other than integrate/methods live in their own modules, each exposing
``add_arguments(parser)`` and ``run(args) -> int``; a module is imported only when its command
runs (or its own ``--help`` is asked for), so ``ldaspark --help`` imports nothing heavy.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from .core.errors import LdasparkError

#: entry-point group through which other packages add commands; the paper lab
#: (``ldaspark.lab.commands``) adds report, verify, audit and mutants. The library never imports
#: the lab: the commands are found in the installed metadata (pyproject's entry points).
COMMAND_GROUP = "ldaspark.commands"


def plugin_commands() -> dict:
    """name -> (module, help) of the commands registered under ``COMMAND_GROUP``; each entry point
    names a mapping of that form (loading it imports one light module, not the commands)."""
    from importlib.metadata import entry_points
    out = {}
    for ep in sorted(entry_points(group=COMMAND_GROUP), key=lambda e: e.name):
        out.update(ep.load())
    return out


#: the destinations of the commands' file and directory options (``--out``, ``--json``, ...)
_PATH_OPTIONS = ("out", "json", "outdir", "tableau", "keep_killed", "fill", "file")
#: the outputs among them: a bare "-" there is refused, not written as a file named "-" (several
#: commands print their own text to stdout, so "-" as stdout would mix two outputs in one stream;
#: /dev/stdout names standard output explicitly, ./- a file named "-")
_OUTPUT_OPTIONS = ("out", "json", "outdir")
_DASH_HELP = ("output paths (--out, --json, --outdir): '-' is refused, not read as standard output; "
              "--out/--json /dev/stdout writes to standard output, ./- names a file or directory '-'")


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        # argparse's own usage errors: one line, exit 2. Its message quotes the user's words raw
        # ("unrecognized arguments: ..."): line breaks and terminal controls are written as escapes
        from .core.errors import one_line
        self.exit(2, f"ldaspark: error: {one_line(message)}\n")


def _add_integrate(sub):
    p = sub.add_parser("integrate", help="integrate a scene with a SPARK method and write JSON, npz or h5")
    p.add_argument("scene", help="a built-in scene: the paper's particle, skate, robot, mp-particles, and the others "
                                 "of ldaspark.get_scene (an unknown name lists them all)")
    p.add_argument("method", help="gauss-S, lobatto-iiia-iiib-S, lobatto-iiia-iiib-iiid-S, euler-i, "
                                  "euler-ii, a comparator of sections 7-8 (gauss-irk-S, ...; an unknown "
                                  "name lists them), or custom with --tableau FILE")
    p.add_argument("--h", required=True, help="step size (a decimal string keeps full precision with --dps)")
    p.add_argument("--t-end", required=True, help="final time")
    p.add_argument("--dps", type=int, default=None, help="mpmath digits (default: float64)")
    p.add_argument("--ic", type=int, default=None, help="initial condition j (mp-particles, mp-particles-nh)")
    p.add_argument("--tableau", default=None, help="tableau JSON file for METHOD custom")
    p.add_argument("--max-stages", type=int, default=None, help="allow methods with more than 20 stages")
    # the kinds of ldaspark.Newton (core.rootfinder.KINDS, written out: the CLI does not import
    # numpy before parsing; tests/cli compares the two)
    p.add_argument("--newton", choices=("full", "simplified", "auto", "mixed", "quasi"), default="auto",
                   help="the root finder's kind (ldaspark.Newton; default: auto = simplified Newton, "
                        "full on slow contraction, and on the compiled engine the quasi iteration where "
                        "it applies (SPARK tableaus, mechanical form, n < 32); mixed: float64 matrix "
                        "at --dps; quasi: the compiled engine's multiplier-only iteration, Newton on "
                        "slow contraction)")
    p.add_argument("--project", action="store_true", help="project v0 onto k = 0 instead of failing")
    p.add_argument("--out", required=True, help="output file, format by extension: .npz, .h5 (h5py), else JSON "
                                                "(psi on every engine, not from the semi-implicit kernel of "
                                                "lobatto-iiia-iiib-2; a comparator's are its own); written "
                                                "atomically")
    p.add_argument("--engine", choices=("auto", "compiled", "generic"), default="auto",
                   help="auto (default): compiled kernels when the scene and method qualify, else generic")
    p.add_argument("--every", type=int, default=1, help="save every k-th step (and the last); default 1")
    p.set_defaults(func=_run_integrate)


def _run_integrate(args) -> int:
    from .core.resultio import check_output, save_result
    from .models.scenes import get_scene
    from .core.tableau_file import load_tableau
    from .core.errors import InputError
    from .solve import integrate

    check_output(args.out)                  # a directory or socket at --out: refused now, not after the run
    from .core.io import check_distinct_outputs
    check_distinct_outputs(("--tableau", args.tableau), ("--out", args.out))    # the result replaced the tableau
    if args.method == "custom":
        if not args.tableau:
            raise InputError("METHOD custom needs --tableau FILE")
        method = load_tableau(args.tableau, max_stages=args.max_stages)
    else:
        if args.tableau:
            raise InputError("--tableau is only used with METHOD custom")
        method = args.method                # built-in names and gauss-irk-S get --max-stages below
    scene = get_scene(args.scene, args.ic)
    args.output_before = (args.out, _file_state(args.out))
    try:
        h = float(args.h)
        t_end = float(args.t_end)
    except ValueError:
        raise InputError(f"--h and --t-end must be numbers, got {args.h!r}, {args.t_end!r}") from None
    # with --dps both texts keep their digits (float('2e-420') is 0.0)
    res = integrate(scene, method, h=args.h if args.dps else h, t_end=args.t_end if args.dps else t_end,
                    dps=args.dps, project=args.project,
                    newton=args.newton, engine=args.engine, save_every=args.every, raise_on_failure=True,
                    max_stages=args.max_stages if isinstance(method, str) else None)
    save_result(res, args.out)
    args.output_written = args.out          # a Ctrl-C from here on finds the complete result written
    mean = res.newton_iterations / max(int(res.stats.get("steps", 0)) or 1, 1)
    print(f"{scene.name} {res.method}: {res.stats.get('steps', len(res.t) - 1)} steps ({res.engine}), "
          f"max |k| = {max(abs(float(x)) for x in res.constraint.reshape(-1)):.2e}, "
          f"mean Newton iterations {mean:.2f} -> {args.out}")
    return 0


def _mp_str(x, dps):
    import mpmath
    return mpmath.nstr(x, dps, strip_zeros=False)


def _add_methods(sub):
    p = sub.add_parser("methods", help="list built-in methods: s, claimed order, (22), (23)")
    p.add_argument("--max-s", type=int, default=4)
    p.add_argument("--json", default=None, help="also write the table as JSON")
    p.set_defaults(func=_run_methods)


def _run_methods(args) -> int:
    from .analysis.conditions import method_table
    from .core.errors import InputError
    if not 1 <= args.max_s <= _MAX_S:
        raise InputError(f"--max-s must be between 1 and {_MAX_S} (exact coefficients), got {args.max_s}")
    if args.json:
        from .core.io import check_destination
        check_destination(args.json)    # refused before the table is printed, not after
    rows = method_table(args.max_s)
    print(f"{'method':28s} {'s':>2s} {'order':>5s}  (22)  (23)")
    for r in rows:
        print(f"{r['method']:28s} {r['s']:2d} {r['order']:5d}  {'yes' if r['22'] else 'no':4s}  "
              f"{'yes' if r['23'] else 'no'}")
    if args.json:
        from .core.io import atomic_write_json
        atomic_write_json(args.json, rows)
    return 0


def _count_checker(dest: str):
    """The check of an integer option, with the message of the API's own validator (the CLI and
    ``ldaspark.integrate`` say the same thing about the same value)."""
    from .core import validate as V
    table = {
        "every": lambda x: V.count(x, "save_every"),
        "ic": lambda x: V.count(x, "ic (the initial condition index)", 0, 10 ** 6),
        "jobs": lambda x: V.count(x, "--jobs", 1, _MAX_WORKERS),
        "workers": lambda x: V.count(x, "--workers", 1, _MAX_WORKERS),
        "mutant_timeout": lambda x: V.count(x, "--mutant-timeout (seconds)", 1, 86400),
        # the exact method table's own range (``_run_methods``): 0 said "between 1 and 1e+09", 6 "1 and 5"
        "max_s": lambda x: V.count(x, "--max-s (exact coefficients)", 1, _MAX_S),
    }
    return table.get(dest, lambda x: V.count(x, f"--{dest.replace('_', '-')}", 1, V.MAX_STEPS))


#: the largest s of ``ldaspark methods`` (the table is exact; exact Gauss nodes exist up to s = 5)
_MAX_S = 5
#: most worker processes an option may ask for (more is a typo, and would fork that many)
_MAX_WORKERS = 1024
#: integer options left to their command's own range check (--dps is 16..2000 for integrate and
#: 10..200 for audit; --max-stages is checked with the method it raises the limit of)
_OWN_CHECK = ("dps", "max_stages")


def _count_type(dest: str):
    """argparse type of an integer option: an integer (else argparse's "invalid int value"),
    >= 1 (>= 0 for an index), bounded as the API bounds it."""
    def parse(text):
        val = int(text, 10)                  # ValueError: argparse says "invalid int value"
        try:
            _count_checker(dest)(val)
        except LdasparkError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return val
    parse.__name__ = "int"
    return parse


def _duration_type(text):
    """argparse type of a real option (a time span): finite and positive (nan ran forever)."""
    import math
    val = float(text)                        # ValueError: argparse says "invalid float value"
    if not (math.isfinite(val) and val > 0):
        raise argparse.ArgumentTypeError(f"must be a finite positive number, got {str(text)[:40]!r}")
    return val


_duration_type.__name__ = "float"


def _check_numeric_options(parser) -> None:
    """Give every ``type=int`` / ``type=float`` option of ``parser`` and its subparsers (the
    plugin modules' too) a checking type, so that a zero, negative, NaN or infinite count or time
    is one argparse error (exit 2) before any work, whichever module declared the option."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                _check_numeric_options(sub)
        elif action.type is int and action.choices is None and action.dest not in _OWN_CHECK:
            action.type = _count_type(action.dest)
        elif action.type is float:
            action.type = _duration_type


def dash_message(option: str) -> str:
    """The refusal of a bare "-" as an output path (``_OUTPUT_OPTIONS``)."""
    return (f"{option} -: '-' is not standard output here; give /dev/stdout for that (--out, --json), "
            "or ./- for a file named '-'")


def _note_dash(parser) -> None:
    """One line in the help of every (sub)command that takes an output path: what '-' means."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                _note_dash(sub)
        elif action.dest in _OUTPUT_OPTIONS and action.option_strings and not parser.epilog:
            parser.epilog = _DASH_HELP


def build_parser(command: str | None = "*") -> argparse.ArgumentParser:
    """The parser; plugin modules are imported only for ``command`` ("*" = all of them)."""
    from ._version import __version__
    parser = _Parser(prog="ldaspark", description="Lagrange-d'Alembert SPARK integrators (Jay)")
    parser.add_argument("--version", action="version", version=f"ldaspark {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    _add_integrate(sub)
    _add_methods(sub)
    for name, (mod, helptext) in plugin_commands().items():
        p = sub.add_parser(name, help=helptext)
        if command not in ("*", name):
            continue
        module = importlib.import_module(mod)
        module.add_arguments(p)
        p.set_defaults(func=module.run)
    _check_numeric_options(parser)
    _note_dash(parser)
    return parser


def _command_of(argv) -> str | None:
    """The subcommand named in argv (the first word that is not an option), if any."""
    for a in argv:
        if not a.startswith("-"):
            return a
    return None


def main(argv=None) -> int:
    """Run the command line; returns the exit code (0 ok, 2 user error, 128 + the signal number
    when stopped by SIGINT, SIGTERM, SIGHUP or SIGQUIT: ``ldaspark.core.lifecycle``)."""
    try:
        from .core import lifecycle
    except KeyboardInterrupt:       # Ctrl-C while the signal handling itself loads: one line, 130
        print("ldaspark: interrupted", file=sys.stderr)
        return 130
    with lifecycle.stop_on_signals(line=_forced_line) as stop:
        try:
            rc = _main(argv)
        except KeyboardInterrupt as exc:
            return _stopped(exc, "")
        except ImportError:
            # Ctrl-C inside an extension module's import (numpy, scipy) surfaces as ImportError
            if stop.received is not None:
                return _stopped(lifecycle.Stopped(stop.received), "")
            raise
        if rc == 0 and stop.received is not None:
            # the stop reached no handler of the run (code that swallows BaseException): the run
            # finished, but its caller asked it to stop and reads 128 + the signal, not 0
            return _stopped(lifecycle.Stopped(stop.received), "it arrived where the run could not stop; "
                                                                "the run finished and wrote its outputs")
        return rc


def _stopped(exc, why: str) -> int:
    """The one line of a stopped run and its exit status; the workers and subprocesses it
    started are gone when this returns."""
    from .core import lifecycle
    signum = lifecycle.signum_of(exc)
    lifecycle.kill_children()       # normally none left: the pools have terminated theirs
    print(_stop_line(signum, why), file=sys.stderr)
    return lifecycle.exit_status(signum)


def _stop_line(signum, why: str = "") -> str:
    import signal
    from .core.lifecycle import signal_name
    what = "interrupted" if signum == signal.SIGINT else f"stopped by {signal_name(signum)}"
    return f"ldaspark: {what}{f' ({why})' if why else ''}"


def _forced_line(signum) -> str:
    return _stop_line(signum, "forced: workers killed, temporary files removed; a rerun resumes "
                              "from any checkpoint")


def _main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser(_command_of(argv))
    except KeyboardInterrupt as exc:
        return _stopped(exc, "")
    args = parser.parse_args(argv)
    for dest in _PATH_OPTIONS:      # an empty path is never "not given": refused, never ignored
        val = getattr(args, dest, None)
        if isinstance(val, str) and not val.strip():
            name = "FILE" if dest == "file" else "--" + dest.replace("_", "-")
            print(f"ldaspark: error: {name} is an empty path", file=sys.stderr)
            return 2
    for dest in _OUTPUT_OPTIONS:    # "-" was written as a file named "-": refused before any work
        if getattr(args, dest, None) == "-":
            print(f"ldaspark: error: {dash_message('--' + dest)}", file=sys.stderr)
            return 2
    if not getattr(args, "func", None):
        parser.print_help()
        names = next(a.choices for a in parser._actions if isinstance(a, argparse._SubParsersAction))
        print(f"ldaspark: error: give a command ({', '.join(names)})", file=sys.stderr)
        return 2
    from .core import io as _io
    first_write = len(_io.COMPLETED)    # the files this command completes from here on
    try:
        rc = int(args.func(args) or 0)
        sys.stdout.flush()          # a write error on stdout (``> /dev/full``) surfaces here, as one line
        return rc
    except LdasparkError as exc:
        print(f"ldaspark: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        done = getattr(args, "output_written", None)
        path, before = getattr(args, "output_before", (None, None))
        if done is None and path is not None and _file_state(path) not in (None, before):
            done = path         # replaced atomically after the run: the new file is complete
        kept = ("the finished units are kept in OUTDIR's *.partial.jsonl; a rerun resumes from them"
                if getattr(args, "command", None) in ("verify", "mutants") else None)
        return _stopped(exc, f"after the complete result was written to {done}" if done else
                        kept or _completed_before_stop(_io.COMPLETED[first_write:]))
    except BrokenPipeError:
        # ``ldaspark methods | head -1``: the reader closed the pipe. Further writes to stdout
        # go to /dev/null so that the interpreter's final flush does not raise again.
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        print("ldaspark: error: output closed by the reader (broken pipe)", file=sys.stderr)
        return 2
    except OSError as exc:
        # a write error outside the atomic writers (which say it themselves): stdout on a full
        # disk or /dev/full, an I/O error. One line, exit 2; what stdout still buffers is dropped
        # so that the interpreter's final flush does not print a second error
        _drop_stdout()
        where = f" {exc.filename}" if getattr(exc, "filename", None) else " the output"
        print(f"ldaspark: error: cannot write{where}: {exc.strerror or type(exc).__name__}", file=sys.stderr)
        return 2


def _completed_before_stop(paths) -> str:
    """What a stopped command keeps when it wrote some of its files: each is complete (written
    atomically), none partial. ``report energy --json F --outdir D`` stopped while plotting said
    "no partial output was written" of a complete F."""
    from .core.errors import one_line
    if not paths:
        return "no partial output was written"
    paths = list(dict.fromkeys(paths))
    shown = ", ".join(one_line(p) for p in paths[:3]) + (f" and {len(paths) - 3} more" if len(paths) > 3 else "")
    return (f"{len(paths)} complete file{'s' if len(paths) > 1 else ''} written before it: {shown}; "
            "no partial output was written")


def _drop_stdout() -> None:
    """Point stdout at /dev/null and discard what its buffer holds (it cannot be written)."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        sys.stdout.flush()
    except (OSError, ValueError, AttributeError):
        pass


def _file_state(path):
    """(inode, mtime, size) of a regular file, else None: an atomic replace changes it."""
    import stat
    try:
        st = os.stat(path)
    except (OSError, ValueError, TypeError):
        return None
    return (st.st_ino, st.st_mtime_ns, st.st_size) if stat.S_ISREG(st.st_mode) else None


def _one_line(exc) -> str:
    """The first line of an error message (the CLI's promise: one line)."""
    lines = str(exc).splitlines()
    return lines[0] if lines else type(exc).__name__


if __name__ == "__main__":
    sys.exit(main())
