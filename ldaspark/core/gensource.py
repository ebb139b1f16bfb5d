"""Generated source holds no user text: the one gate in front of every piece of Python source the
library builds from a model's expressions and then compiles (sympy's lambdify for the generic
float64 / mpmath engines and the comparators, the compiled engine's code generator, the model
modules read back from the cache).

Three rules, each enforced here:

* **the expressions are made of known nodes only** (``check_expressions``): numbers, symbols,
  sums, products, powers, the sympy functions of ``SUPPORTED_FUNCTIONS`` (the classes themselves,
  not a user class of the same name), Piecewise and its conditions, Min and Max. An undefined
  function (``sympy.Function("f")(x)``) is refused by name, as is any other node: its printed form
  would be its (user-chosen) name, or text of its own print method. The expressions' depth is
  bounded (``MAX_DEPTH``): the printers, cse and sympy's own algorithms recurse on it;
* **no user name is printed** (``lambdify``): every symbol is printed as an identifier the
  library generates (``_s0``, ``_s1``, ... by argument position; cse's ``x0``, ``x1``, ...), by
  the printer, without rebuilding the expressions (a rebuilt sum is re-sorted by the new names,
  which would change the order of the floating-point additions and so the results' last bits).
  A parameter named ``pi``, ``E``, ``sin`` or ``__import__('os')`` is ``_s7`` in the source;
* **the source is checked before it is compiled** (``check_source``): every identifier in it is
  a keyword, a generated name or a name of the numeric module's namespace (never one beginning
  with ``__``), and it holds no string literal. A violation is a library bug and raises
  ``GeneratedSourceError``; nothing has been executed.

Tests: tests/test_generated_names.py.
"""
from __future__ import annotations

import ast
import io
import keyword
import re
import sys
import threading
import tokenize

import sympy

from .errors import LdasparkError, SystemDefinitionError


class UndefinedFunctionError(SystemDefinitionError):
    """An expression of the model contains an undefined function (``sympy.Function("f")(x)``):
    it has no value, and its name would be printed into generated code."""


class ExpressionTooLargeError(SystemDefinitionError):
    """An expression of the model is nested deeper than ``MAX_DEPTH`` (the printers, cse and
    the compiler recurse on the nesting)."""


class GeneratedSourceError(LdasparkError):
    """Generated source holds an identifier or literal the library did not generate (a bug
    guard: nothing of it was executed)."""


#: the sympy functions every engine translates: numpy / math at float64 and mpmath at dps (the
#: lambdify modules of ``Backend``), and their derivatives (DiracDelta, from sign and Heaviside,
#: is zero off its support). The compiled engine translates a subset and refuses the others with
#: NotCompilableError (engine "auto" then runs the generic engine).
SUPPORTED_FUNCTIONS = frozenset((
    "sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos", "atan", "acot", "asec", "acsc", "atan2",
    "sinh", "cosh", "tanh", "coth", "sech", "csch", "asinh", "acosh", "atanh",
    "exp", "log", "erf", "erfc", "sinc", "Abs", "sign", "re", "im", "Heaviside", "Piecewise", "Min", "Max"))
_FUNCTION_CLASSES = {getattr(sympy, f): f for f in SUPPORTED_FUNCTIONS}

#: the deepest expression accepted (the library's models are at most 16 deep, the Whipple
#: bicycle's derivatives included); sympy's printers use 3-5 Python frames per level
MAX_DEPTH = 120

#: the most nodes an expression may have written out as a tree (shared subexpressions counted
#: at every use: what sympy's free_symbols, derivatives and printers walk). The library's largest,
#: the Whipple bicycle's derivatives, have 12282; e = sin(e) + cos(e) twenty times over (2e6) took
#: LagrangianSystem 65 s and the first step minutes
MAX_TREE_NODES = 500_000

#: node types that print as numbers, operators or the printer's own names (never user text)
_STRUCTURAL = (sympy.Add, sympy.Mul, sympy.Pow, sympy.Number, sympy.NumberSymbol,
               sympy.functions.elementary.piecewise.ExprCondPair,
               sympy.core.relational.Relational, sympy.logic.boolalg.BooleanAtom, sympy.And, sympy.Or,
               sympy.Not, sympy.Tuple)
_SPECIAL = (sympy.I, sympy.zoo)

_DERIVED_ONLY = {sympy.DiracDelta: "DiracDelta"}


def _node_problem(node, derived: bool):
    """None for a node the engines print from its type alone, else a short description."""
    from sympy.core.function import AppliedUndef
    t = type(node)
    if isinstance(node, AppliedUndef):
        return "undefined"
    if t in _FUNCTION_CLASSES or (derived and t in _DERIVED_ONLY):
        return None
    if isinstance(node, (sympy.Derivative, sympy.Integral, sympy.Subs, sympy.Sum, sympy.Product, sympy.Function)):
        return t.__name__
    if not (t.__module__ or "").startswith("sympy."):
        # a subclass defined outside sympy (of Symbol, NumberSymbol, Add, ...) may print itself
        # (_pythoncode, _numpycode, _sympystr): its own text would go into the generated source
        return f"{t.__name__} (defined outside sympy)"
    if isinstance(node, sympy.Symbol):
        return None
    if not isinstance(node, _STRUCTURAL):
        if node in _SPECIAL:
            return None
        return t.__name__
    return None


_DYNAMIC = ("; functions of t and their derivatives (dynamicsymbols) are not coordinates here: use plain "
            "symbols q, v, or LagrangianSystem.from_mechanics(...) for sympy.physics.mechanics models")


def tree_nodes(e, cap: int) -> int:
    """The number of nodes of ``e`` written out as a tree, counted on its graph (each distinct node
    once, iteratively) and capped just above ``cap``: linear in the distinct nodes, where a walk of
    the tree is exponential in the nesting of shared parts."""
    size: dict = {}
    todo = [(e, False)]
    while todo:
        node, ready = todo.pop()
        if node in size:
            continue
        args = node.args
        if not args:
            size[node] = 1
        elif ready:
            size[node] = min(cap + 1, 1 + sum(size[a] for a in args))
        else:
            todo.append((node, True))
            todo.extend((a, False) for a in args if a not in size)
    return size[e]


def check_expressions(named_exprs, derived: bool = False, max_depth: int = MAX_DEPTH) -> None:
    """SystemDefinitionError (one line) for the first expression of ``named_exprs`` ([(where,
    expr)]) that holds a node the engines do not translate: an undefined function
    (``UndefinedFunctionError``, named), a function or node outside ``SUPPORTED_FUNCTIONS`` and
    the structural nodes, or a nesting deeper than ``max_depth`` (``ExpressionTooLargeError``).
    One iterative walk per expression graph (no recursion: the depth is what is bounded)."""
    for where, e in named_exprs:
        if not isinstance(e, sympy.Basic):
            continue
        if tree_nodes(e, MAX_TREE_NODES) > MAX_TREE_NODES:
            raise ExpressionTooLargeError(
                f"{where} has more than {MAX_TREE_NODES} nodes written out (shared subexpressions count at "
                "every use; the limit of ldaspark.core.gensource.MAX_TREE_NODES): name its parts as "
                "coordinates or parameters, or give it in a smaller form")
        depth: dict = {}
        todo = [(e, 1)]
        while todo:
            node, d = todo.pop()
            if depth.get(node, 0) >= d:
                continue
            depth[node] = d
            if d > max_depth:
                raise ExpressionTooLargeError(
                    f"{where} is nested more than {max_depth} levels deep (the limit of "
                    "ldaspark.core.gensource.MAX_DEPTH); give it in a flatter form (expand it, or name its parts "
                    "as coordinates)")
            bad = _node_problem(node, derived)
            if bad == "undefined":
                raise UndefinedFunctionError(
                    f"{where} contains the undefined function {_shown(type(node).__name__)}: it has no value to "
                    f"compute; substitute an expression for it{_DYNAMIC}")
            if bad is not None and type(node).__module__.startswith("sympy.physics.units"):
                units = sorted({_shown(str(u)) for u in e.atoms(type(node))})[:6]
                raise SystemDefinitionError(
                    f"{where} contains physical units ({', '.join(units)}); the integrator works on numbers: "
                    "substitute the quantities by their values in one consistent unit system")
            if bad is not None:
                what = (f"the derivatives of L and k ({where}) contain {_shown(bad)}" if derived
                        else f"{where} contains the function {_shown(bad)}")
                hint = _DYNAMIC if bad == "Derivative" and not derived else ""
                raise SystemDefinitionError(f"{what}, which the engines do not translate; supported: "
                                            f"{', '.join(sorted(SUPPORTED_FUNCTIONS))} (and powers, sqrt){hint}")
            if node.args:
                todo.extend((a, d + 1) for a in node.args)


def _shown(name: str) -> str:
    """A user-chosen name for a one-line message: printable, quoted when it is not a plain
    identifier, at most 60 characters."""
    s = str(name)
    if s.isidentifier() and s.isascii() and len(s) <= 60:
        return s
    return repr(s[:60])


# --- the printer: symbols by generated names --------------------------------------------------
_CSE_NAME = re.compile(r"^x[0-9]+$")
_GENERATED_NAME = re.compile(r"^(_s[0-9]+|x[0-9]+|_lambdifygenerated)$")


def _printer(module: str, names: dict, cse_symbols: set, settings: dict):
    """sympy's printer for ``module`` ("math": PythonCodePrinter, "mpmath": MpmathPrinter) with
    ``settings``, printing each symbol of ``names`` by its generated name and cse's symbols by
    theirs; any other symbol raises GeneratedSourceError."""
    from sympy.printing.pycode import MpmathPrinter, PythonCodePrinter
    base = MpmathPrinter if module == "mpmath" else PythonCodePrinter

    class _Named(base):
        def _print_Symbol(self, expr):
            name = names.get(expr)
            if name is not None:
                return name
            if expr in cse_symbols and _CSE_NAME.match(expr.name):
                return expr.name
            raise GeneratedSourceError("generated source: a symbol that is not an argument of the function")

        _print_Dummy = _print_Symbol

        def _print_Function(self, expr):
            from sympy.core.function import AppliedUndef
            if isinstance(expr, AppliedUndef):
                raise UndefinedFunctionError(f"undefined function {_shown(type(expr).__name__)} in an expression")
            return super()._print_Function(expr)
    return _Named(settings)


def lambdify(args, exprs, module: str, namespaces=(), order: str | None = None, cse: bool = True):
    """``sympy.lambdify(args, exprs, modules=[*namespaces, module], cse=cse)`` with no user text in
    its source: the expressions checked (``check_expressions``), each argument printed as
    ``_s<position>``, the source checked (``check_source``) before it is compiled. ``order``:
    the printer's "order" setting ("none": the sums' stored order, as ``LagrangianSystem`` prints).
    A symbol of ``exprs`` that is not in ``args`` is refused. Results are those of sympy.lambdify
    with the same printer settings: the expressions are printed as they are, only the names
    differ. A source beyond CPython's compiler's nesting (a sum of thousands of terms) is compiled
    with its long sums and products rebalanced."""
    from sympy.utilities.lambdify import _EvaluatorPrinter, _get_namespace
    import builtins
    flat = list(_flatten(exprs))
    check_expressions([(f"generated function output {i}", e) for i, e in enumerate(flat)], derived=True)
    names = {}
    for i, a in enumerate(args):
        if not isinstance(a, sympy.Symbol) or a in names:
            raise GeneratedSourceError("generated source: arguments must be distinct symbols")
        names[a] = f"_s{i}"
    free = set().union(*(e.free_symbols for e in flat if isinstance(e, sympy.Basic))) if flat else set()
    if free - set(names):
        raise SystemDefinitionError(f"an expression contains symbols that are not arguments: "
                                    f"{', '.join(sorted(_shown(str(s)) for s in free - set(names))[:3])}")
    if cse:
        from sympy.simplify.cse_main import cse as _cse
        cses, red = _cse(exprs, list=False)
    else:
        cses, red = (), exprs
    namespace: dict = {}
    for m in [*namespaces, module][::-1]:     # the first has priority, as in sympy.lambdify
        namespace.update(_get_namespace(m))
    user_functions = {k: k for m in namespaces if isinstance(m, dict) for k in m}
    settings = {"fully_qualified_modules": False, "inline": True, "allow_unknown_functions": True,
                "user_functions": user_functions}
    if order is not None:
        settings["order"] = order
    printer = _printer(module, names, {s for s, _ in cses}, settings)
    new_args = [sympy.Symbol(names[a]) for a in args]
    try:
        src = _EvaluatorPrinter(printer, False).doprint("_lambdifygenerated", new_args, red, cses=cses)
    except RecursionError:
        raise ExpressionTooLargeError("an expression is too deep to print; give it in a flatter form") from None
    check_source(src, namespace)
    _one_function(src)
    namespace.update({"builtins": builtins, "range": range})
    code = _compile(src)
    local: dict = {}
    exec(code, namespace, local)     # noqa: S102 - checked generated source: defines the function only
    return local["_lambdifygenerated"]


def _flatten(x):
    if isinstance(x, sympy.MatrixBase):
        yield from x
    elif isinstance(x, (list, tuple)):
        for y in x:
            yield from _flatten(y)
    else:
        # strict: text is never parsed here (sympify of a str evaluates it); numbers and sympy
        # objects as before
        try:
            yield sympy.sympify(x, strict=True)
        except sympy.SympifyError:
            raise SystemDefinitionError(f"an expression to compile is {type(x).__name__}, not a sympy "
                                        "expression (text is parsed by LagrangianSystem, never here)") from None


def _one_function(src: str) -> None:
    """GeneratedSourceError unless ``src`` is one function definition, ``_lambdifygenerated``, with
    no definition, import or global statement inside: executing it defines that function and does
    nothing else (the names are checked by ``check_source``, the statements here)."""
    with SOURCE_LOCK:
        try:
            tree = ast.parse(src)
        except (SyntaxError, ValueError):
            raise GeneratedSourceError("generated source does not parse") from None
        except (RecursionError, MemoryError):
            return          # too deep for the checker's parser: _compile rebalances or refuses it
    body = tree.body
    if len(body) != 1 or not isinstance(body[0], ast.FunctionDef) or body[0].name != "_lambdifygenerated":
        raise GeneratedSourceError("generated source is not one function definition")
    bad = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Lambda, ast.Import, ast.ImportFrom,
           ast.Global, ast.Nonlocal, ast.Delete, ast.With, ast.Try, ast.Raise)
    for node in ast.walk(body[0]):
        if node is not body[0] and isinstance(node, bad):
            raise GeneratedSourceError(f"generated source holds a {type(node).__name__} statement")
        # the printers read builtins.<name> (nan as builtins.float('nan')); nothing is assigned to
        # an attribute or a subscript
        if isinstance(node, ast.Attribute) and not (isinstance(node.value, ast.Name) and node.value.id == "builtins"
                                                    and isinstance(node.ctx, ast.Load)):
            raise GeneratedSourceError("generated source holds an attribute other than a builtin read")
        if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            if not all(isinstance(x, ast.Name) for x in targets):
                raise GeneratedSourceError("generated source assigns to something other than a name")


def check_source(src: str, namespace=(), pattern=_GENERATED_NAME, strings=None) -> None:
    """GeneratedSourceError unless every identifier of ``src`` is a Python keyword, matches
    ``pattern`` (the generated names) or is a name of ``namespace`` (the numeric module's
    functions) not beginning with ``__``, and ``src`` has no string literal (a docstring at a
    ``_STRINGS`` ("nan", "inf") and those ``strings`` (a regex) matches excepted)."""
    if not src.isascii():
        # every name and number the library prints is ASCII; the compiler folds other identifier
        # characters (NFKC: U+FE33 is "_") into names the token check never saw
        raise GeneratedSourceError("generated source holds a character outside ASCII")
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(src).readline))
    except (tokenize.TokenError, SyntaxError, IndentationError) as exc:
        raise GeneratedSourceError(f"generated source does not tokenize ({type(exc).__name__})") from None
    for tok in tokens:
        if tok.type == tokenize.NAME:
            s = tok.string
            if keyword.iskeyword(s) or pattern.match(s) or s in _BUILTINS \
                    or (s in namespace and not s.startswith("__")):
                continue
            raise GeneratedSourceError(f"generated source holds the identifier {_shown(s)}, which the library "
                                       "did not generate")
        if tok.type == tokenize.STRING and tok.string not in _STRINGS \
                and not (strings is not None and strings.match(tok.string)):
            raise GeneratedSourceError("generated source holds a string literal")


#: the builtins the printers use (Abs: abs, Max: max, nan: float('nan'), lambdify's range) and the
#: only string literals they print
_BUILTINS = frozenset(("abs", "min", "max", "float", "int", "complex", "bool", "pow", "range", "builtins"))
_STRINGS = frozenset(("'nan'", "'inf'", "'-inf'", "'+inf'"))


#: one parse or compile of generated source at a time in this process. CPython 3.11 counts the AST
#: constructor's recursion in state the threads share, so two threads parsing at once can raise
#: "SystemError: AST constructor recursion depth mismatch" (python/cpython#106905; seen with models
#: compiled for an ensemble on a ThreadPoolExecutor), and the recursion limit raised below for deep
#: trees is process-wide. Reentrant: a parse may run inside a caller that holds it.
SOURCE_LOCK = threading.RLock()


def _compile(src: str):
    with SOURCE_LOCK:
        return _compile_locked(src)


def _compile_locked(src: str):
    try:
        return compile(src, "<ldaspark generated>", "exec")
    except (RecursionError, MemoryError):
        pass
    limit = sys.getrecursionlimit()
    try:
        sys.setrecursionlimit(max(limit, 20000))
        tree = ast.fix_missing_locations(BalancedSums().visit(ast.parse(src)))
        return compile(tree, "<ldaspark generated>", "exec")
    except (RecursionError, MemoryError, SyntaxError) as exc:
        raise ExpressionTooLargeError(f"the generated function does not compile ({type(exc).__name__}): an "
                                      "expression is too large; give it in a smaller form") from None
    finally:
        sys.setrecursionlimit(limit)


class BalancedSums(ast.NodeTransformer):
    """Chains ``a + b - c + ...`` and ``a * b * ...`` of a generated source as balanced trees: a
    sum of n terms is n - 1 nested BinOp nodes, and CPython's compiler refuses nesting beyond a
    few thousand ("maximum recursion depth exceeded while traversing 'expr' node": a model with
    n = 1001 coordinates). Used where a source is compiled as Python (here, when the printed form
    was refused; ``compiled.native.python_module`` always); the sums then differ from the native
    code's order in the last bits, far below every tolerance they are checked at."""

    @staticmethod
    def _chain(node, ops):
        terms, stack = [], [(node, False)]
        while stack:
            x, neg = stack.pop()
            if isinstance(x, ast.BinOp) and type(x.op) in ops:
                stack.append((x.right, neg != isinstance(x.op, ast.Sub)))
                stack.append((x.left, neg))
            else:
                terms.append((x, neg))
        return terms

    @staticmethod
    def _tree(items, op):
        while len(items) > 1:
            items = [ast.BinOp(left=items[i], op=op(), right=items[i + 1]) if i + 1 < len(items) else items[i]
                     for i in range(0, len(items), 2)]
        return items[0]

    def visit_BinOp(self, node):
        if type(node.op) in (ast.Add, ast.Sub):
            terms = self._chain(node, (ast.Add, ast.Sub))
            if len(terms) > 8:
                items = [self.visit(x) for x, _ in terms]
                items = [ast.UnaryOp(op=ast.USub(), operand=x) if neg else x for x, (_, neg) in zip(items, terms)]
                return self._tree(items, ast.Add)
        elif isinstance(node.op, ast.Mult):
            terms = self._chain(node, (ast.Mult,))
            if len(terms) > 8:
                return self._tree([self.visit(x) for x, _ in terms], ast.Mult)
        return self.generic_visit(node)
