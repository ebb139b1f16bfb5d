"""Command line: ``ldaspark integrate | methods | report | verify | audit`` (also ``python -m ldaspark``).

User errors (LdasparkError) print one line to stderr and exit 2, without a traceback.
Subcommands other than integrate/methods live in their own modules, each exposing
``add_arguments(parser)`` and ``run(args) -> int``; a module is imported only when its command
runs (or its own ``--help`` is asked for), so ``ldaspark --help`` imports nothing heavy.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from .core.errors import LdasparkError

PLUGIN_COMMANDS = {
    "report": ("reports.driver", "write the reports (main job; no arguments = everything)"),
    "verify": ("reports.claims", "run the theorem checks and write the claims ledger"),
    "audit": ("theory.audit", "audit a tableau against Theorem 1's hypotheses and the numerics"),
    "mutants": ("reports.mutation", "plant catalogued faults one at a time and check the suite kills each"),
}


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse's own usage errors: one line, exit 2
        self.exit(2, f"ldaspark: error: {message}\n")


def _add_integrate(sub):
    p = sub.add_parser("integrate", help="integrate a scene with a SPARK method and write JSON")
    p.add_argument("scene", help="particle, skate, robot, mp-particles (also pendulum, rolling-disk)")
    p.add_argument("method", help="gauss-S, lobatto-iiia-iiib-S, lobatto-iiia-iiib-iiid-S, euler-i, "
                                  "euler-ii, or custom with --tableau FILE")
    p.add_argument("--h", required=True, help="step size (a decimal string keeps full precision with --dps)")
    p.add_argument("--t-end", required=True, help="final time")
    p.add_argument("--dps", type=int, default=None, help="mpmath digits (default: float64)")
    p.add_argument("--ic", type=int, default=None, help="initial condition j (mp-particles)")
    p.add_argument("--tableau", default=None, help="tableau JSON file for METHOD custom")
    p.add_argument("--newton", choices=("full", "simplified"), default="full")
    p.add_argument("--project", action="store_true", help="project v0 onto k = 0 instead of failing")
    p.add_argument("--out", required=True, help="output JSON file (written atomically)")
    p.set_defaults(func=_run_integrate)


def _run_integrate(args) -> int:
    from .core.io import atomic_write_json
    from .core.scenes import get_scene
    from .core.spark import integrate, n_steps_for
    from .core.tableau import load_tableau
    from .core.families import get_method
    from .core.errors import InputError

    if args.method == "custom":
        if not args.tableau:
            raise InputError("METHOD custom needs --tableau FILE")
        tab = load_tableau(args.tableau)
    else:
        if args.tableau:
            raise InputError("--tableau is only used with METHOD custom")
        tab = get_method(args.method)
    scene = get_scene(args.scene, args.ic)
    try:
        h = float(args.h)
        t_end = float(args.t_end)
    except ValueError:
        raise InputError(f"--h and --t-end must be numbers, got {args.h!r}, {args.t_end!r}") from None
    t0, q0, v0 = scene.initial(args.dps)
    N = n_steps_for(float(t0), t_end, h)
    sol = integrate(scene.system, tab, t0, q0, v0, args.h if args.dps else h, n_steps=N, dps=args.dps,
                    project=args.project, newton=args.newton)
    fmt = (lambda x: _mp_str(x, args.dps)) if args.dps else float
    out = {
        "scene": scene.name, "method": tab.name, "h": args.h if args.dps else h, "dps": args.dps,
        "t": [fmt(x) for x in sol.t],
        "q": [[fmt(x) for x in row] for row in sol.q],
        "v": [[fmt(x) for x in row] for row in sol.v],
        "energy": [fmt(x) for x in sol.energy],
        "constraint": [[fmt(x) for x in row] for row in sol.constraint],
        "psi": [[[fmt(x) for x in r] for r in stage] for stage in sol.psi],
        "stats": sol.stats,
    }
    atomic_write_json(args.out, out)
    print(f"{scene.name} {tab.name}: {N} steps, max |k| = {max(abs(float(x)) for x in sol.constraint.reshape(-1)):.2e}, "
          f"mean Newton iterations {sol.stats['mean_iterations']:.2f} -> {args.out}")
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
    from .theory.conditions import method_table
    rows = method_table(args.max_s)
    print(f"{'method':28s} {'s':>2s} {'order':>5s}  (22)  (23)")
    for r in rows:
        print(f"{r['method']:28s} {r['s']:2d} {r['order']:5d}  {'yes' if r['22'] else 'no':4s}  "
              f"{'yes' if r['23'] else 'no'}")
    if args.json:
        from .core.io import atomic_write_json
        atomic_write_json(args.json, rows)
    return 0


def build_parser(command: str | None = "*") -> argparse.ArgumentParser:
    """The parser; plugin modules are imported only for ``command`` ("*" = all of them)."""
    from . import __version__
    parser = _Parser(prog="ldaspark", description="Lagrange-d'Alembert SPARK integrators (Jay)")
    parser.add_argument("--version", action="version", version=f"ldaspark {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    _add_integrate(sub)
    _add_methods(sub)
    for name, (mod, helptext) in PLUGIN_COMMANDS.items():
        p = sub.add_parser(name, help=helptext)
        if command not in ("*", name):
            continue
        module = importlib.import_module(f"ldaspark.{mod}")
        module.add_arguments(p)
        p.set_defaults(func=module.run)
    return parser


def _command_of(argv) -> str | None:
    """The subcommand named in argv (the first word that is not an option), if any."""
    for a in argv:
        if not a.startswith("-"):
            return a
    return None


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        parser = build_parser(_command_of(argv))
    except KeyboardInterrupt:
        print("ldaspark: interrupted", file=sys.stderr)
        return 130
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except LdasparkError as exc:
        print(f"ldaspark: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("ldaspark: interrupted (no partial output was written)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
