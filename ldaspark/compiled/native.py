"""Native model functions: the generated model module's functions compiled to machine code by
LLVM directly (llvmlite), without numba's type inference and lowering.

numba spends about 4 ms per generated statement on a model function (typing and lowering in
Python), so a model of ~1200 statements waited ~12 s before its first step although LLVM itself
needs a fraction of a second for that much straight-line code. The model functions are simple
enough to translate without numba: after ``codegen``'s common subexpressions each is a list of
assignments of float expressions (``_x3 = _q0*math.sin(_q1)``, ``out[2, 0] = _x3``) and a return.
This module parses that source (``ast``, a whitelist of nodes: anything else and the model
takes numba's path, so nothing is lost), emits LLVM IR with numba's own data model for the
argument types (an array argument is numba's array struct, by value), compiles it with MCJIT and
hands the kernels each function's address through numba's wrapper address protocol, with
exactly the first-class function signatures of ``modeltypes``: the kernels do not change and are
not compiled again.

Same numbers: each operation is the one numba emits for the same source (IEEE double, no
fast-math, no contraction into FMA; ``x**k`` for an integer constant k by the same
square-and-multiply sequence as numba's constant-exponent power, a float exponent by
``llvm.pow``; ``math.sin`` etc. by the same LLVM intrinsics or the same libm functions).
``tests/compiled/test_native_model.py`` compares native and numba model functions on every scene.

Nothing is stored on disk: the machine code is built from the (trusted, content-keyed) model
source in each process, so there is no new artefact to authenticate.
"""
from __future__ import annotations

import ast
import functools
import math
import os
import threading

from ..core.errors import LdasparkError
from ..core.gensource import SOURCE_LOCK, BalancedSums
import numba.experimental.function_type  # noqa: F401  (registers typeof/unboxing of the protocol)
from numba.core.types.function_type import WrapperAddressProtocol
from numba.core.typing.templates import Signature

from . import modeltypes as mt


class NotNativeError(LdasparkError):
    """The model source uses a construct the native translator does not take (numba then
    compiles the model)."""


#: LDASPARK_NATIVE=0 makes every model take numba's path (the reference the tests compare with)
def enabled() -> bool:
    return os.environ.get("LDASPARK_NATIVE", "1").strip() not in ("0", "false", "no", "off")


# math.<name> -> LLVM intrinsic (what numba's mathimpl lowers the same call to) or libm symbol
_INTRINSIC1 = {"sqrt": "llvm.sqrt", "sin": "llvm.sin", "cos": "llvm.cos", "exp": "llvm.exp", "log": "llvm.log",
               "log10": "llvm.log10", "fabs": "llvm.fabs"}
_LIBM1 = {"tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "asinh", "acosh", "atanh", "log1p", "expm1",
          "log2"}
_LIBM2 = {"atan2"}
_CONSTANTS = {"pi": math.pi, "e": math.e}
#: numba's constant-exponent power expands |k| up to this into multiplications
_MAX_STATIC_POWER = 0x10000
#: functions with more IR instructions than this are compiled at LLVM's -O0 (measured: codegen
#: at -O2 grows faster than linearly with the size of one straight-line function)
_O0_FROM = 20000
#: models with fewer emitted operations per coordinate than this are compiled at -O0 too: their
#: evaluation is a small part of a step (the kernel's linear algebra dominates), and -O2 bought
#: nothing measurable there (mp-particles-nh n = 21, 121: 25 operations per coordinate, steps
#: equally fast, codegen 0.23 s -> 0.06 s at n = 121), while the bicycle's general model (1660
#: per coordinate) ran its steps 1.5x slower at -O0. Same results at every level (no fast-math:
#: LLVM may not reorder floating-point operations), only the machine code's speed differs.
_O2_PER_DOF = 100
#: ... except where a function takes both the sine and the cosine of one argument: -O2 computes the
#: pair by one call of libm's sincos (LLVM's SelectionDAG pairs llvm.sin / llvm.cos of one operand;
#: -O0's fast instruction selection does not), the same bits as the two calls (glibc computes both
#: with the same code). Measured on the skate (33 operations, K and k_q sin / cos q3): 7% of a
#: gauss-6 quasi step (2.24-2.31 -> 2.04-2.14 us), codegen 6 -> 7 ms. Up to this many operations
#: only: -O2's codegen grows faster than the model (a 240-coordinate model with 80 rolling
#: constraints, 10111 operations: 0.16 s at -O0, 0.57 s at -O2, 7% of its first call), and in a
#: model that large the step's linear algebra, not its sines, is what costs (0: the rule off)
_O2_SIN_COS_UP_TO = 4000


def _opt_level(size: int, n_dof, sin_cos: bool = False) -> int:
    """LLVM's optimisation level for a model of ``size`` emitted operations and n coordinates;
    ``sin_cos``: some function takes the sine and the cosine of one value."""
    if size > _O0_FROM:
        return 0
    if sin_cos and size <= _O2_SIN_COS_UP_TO:
        return 2
    if not isinstance(n_dof, int) or n_dof <= 0 or size < _O2_PER_DOF * n_dof:
        return 0
    return 2


def _ctx():
    from numba.core.registry import cpu_target
    return cpu_target.target_context


class _Function:
    """IR of one model function from its ``ast.FunctionDef``."""

    def __init__(self, module, fdef: ast.FunctionDef, sig, n_params=0):
        from llvmlite import ir
        self.ir, self.ctx, self.sig, self.module = ir, _ctx(), sig, module
        self.double = ir.DoubleType()
        self.bool = self.ctx.get_value_type(mt.b1)
        names = [a.arg for a in fdef.args.args]
        if len(names) != len(sig.args) or fdef.args.vararg or fdef.args.kwarg:
            raise NotNativeError(f"{fdef.name}: arguments do not match its signature")
        # a model with parameters: one more argument, a pointer to the n_params values (PARAMS[i])
        extra = [self.double.as_pointer()] if n_params else []
        fnty = ir.FunctionType(self.ctx.get_value_type(sig.return_type),
                               [self.ctx.get_value_type(a) for a in sig.args] + extra)
        self.fn = ir.Function(module, fnty, name=fdef.name + ("__params" if n_params else ""))
        self.builder = ir.IRBuilder(self.fn.append_basic_block("entry"))
        self.scalars, self.arrays = {}, {}
        self.params = (self.fn.args[-1], n_params) if n_params else None
        for name, ty, arg in zip(names, sig.args, self.fn.args):
            if isinstance(ty, type(mt.a1)):
                # numba's array struct by value: its data pointer and shape, by the data model's field
                # positions (numba's make_array proxy would do the same after a registry refresh)
                dm = self.ctx.data_model_manager[ty]
                data = self.builder.extract_value(arg, dm.get_field_position("data"))
                shape = self.builder.extract_value(arg, dm.get_field_position("shape"))
                self.arrays[name] = (ty, data, [self.builder.extract_value(shape, d) for d in range(ty.ndim)])
            elif ty == mt.f8:
                self.scalars[name] = arg
            else:
                raise NotNativeError(f"{fdef.name}: argument type {ty}")
        self.count = 0
        # the IR values (held by the builder's instructions, so their ids stay unique) whose sine /
        # cosine the function takes
        self.trig = {"llvm.sin": set(), "llvm.cos": set()}
        for stmt in fdef.body:
            self.statement(stmt)
        if not self.builder.block.is_terminated:
            raise NotNativeError(f"{fdef.name}: no return")

    # --- statements ---------------------------------------------------------------------------
    def statement(self, node):
        b = self.builder
        if b.block.is_terminated:
            raise NotNativeError("statement after return")
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            return                                   # a docstring
        if isinstance(node, ast.Assign) and len(node.targets) == 1:
            target, value = node.targets[0], self.expr(node.value)
            if isinstance(target, ast.Name) and target.id.startswith("_"):
                self.scalars[target.id] = value
                return
            if isinstance(target, ast.Subscript):
                b.store(self._float(value), self.element(target))
                return
        if isinstance(node, ast.Return):
            rt = self.sig.return_type
            if node.value is None or (isinstance(node.value, ast.Constant) and node.value.value is None):
                if rt != mt.types.void:
                    raise NotNativeError("a bare return in a function with a value")
                b.ret(self.ir.Constant(self.ctx.get_value_type(rt), None))
                return
            if rt == mt.b1:
                if isinstance(node.value, ast.Constant) and isinstance(node.value.value, bool):
                    b.ret(self.ir.Constant(self.bool, int(node.value.value)))
                    return
                raise NotNativeError("a boolean return that is not a constant")
            if rt == mt.f8:
                b.ret(self._float(self.expr(node.value)))
                return
        raise NotNativeError(f"statement {type(node).__name__} at line {getattr(node, 'lineno', '?')}")

    def element(self, node):
        """Pointer to ``array[i]`` / ``array[i, j]`` with constant indices, bounds checked here."""
        from numba.core import cgutils
        idx = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
        if isinstance(node.value, ast.Name) and node.value.id == "PARAMS" and self.params is not None:
            ptr, k = self.params
            if len(idx) != 1 or not (isinstance(idx[0], ast.Constant) and type(idx[0].value) is int
                                     and 0 <= idx[0].value < k):
                raise NotNativeError("a parameter index out of range")
            return self.builder.gep(ptr, [self.ir.Constant(self.ctx.get_value_type(mt.i8), idx[0].value)])
        if not (isinstance(node.value, ast.Name) and node.value.id in self.arrays):
            raise NotNativeError("subscript of something other than an argument array")
        ty, data, shape = self.arrays[node.value.id]
        if len(idx) != ty.ndim or not all(isinstance(i, ast.Constant) and type(i.value) is int and i.value >= 0
                                          for i in idx):
            raise NotNativeError("an index that is not a non-negative integer constant")
        i64 = self.ctx.get_value_type(mt.i8)
        inds = [self.ir.Constant(i64, i.value) for i in idx]
        return cgutils.get_item_pointer2(self.ctx, self.builder, data, shape, None, "C", inds)

    # --- expressions --------------------------------------------------------------------------
    def _const(self, x):
        return self.ir.Constant(self.double, float(x))

    def _float(self, val):
        if val.type != self.double:
            raise NotNativeError("a boolean where a number is expected")
        return val

    def _bool(self, val):
        if val.type != self.ir.IntType(1):
            raise NotNativeError("a number where a condition is expected")
        return val

    def expr(self, node):
        self.count += 1
        b = self.builder
        if isinstance(node, ast.Constant):
            if type(node.value) in (int, float) and math.isfinite(float(node.value)):
                return self._const(node.value)
            raise NotNativeError(f"constant {node.value!r}")
        if isinstance(node, ast.Name):
            if node.id in self.scalars:
                return self.scalars[node.id]
            raise NotNativeError(f"name {node.id}")
        if isinstance(node, ast.Attribute):
            if isinstance(node.value, ast.Name) and node.value.id == "math" and node.attr in _CONSTANTS:
                return self._const(_CONSTANTS[node.attr])
            raise NotNativeError(f"attribute {node.attr}")
        if isinstance(node, ast.Subscript):
            return b.load(self.element(node))
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return b.fneg(self._float(self.expr(node.operand)))
            if isinstance(node.op, ast.UAdd):
                return self._float(self.expr(node.operand))
            if isinstance(node.op, ast.Not):
                return b.not_(self._bool(self.expr(node.operand)))
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.Pow):
                return self.power(node)
            # a long sum prints as a left-nested chain (a + b + c + ...): walk its spine in a loop,
            # not by recursion, which a sum of a thousand terms would exhaust
            ops = {ast.Add: b.fadd, ast.Sub: b.fsub, ast.Mult: b.fmul, ast.Div: b.fdiv}
            chain = []
            while isinstance(node, ast.BinOp) and type(node.op) in ops:
                chain.append((ops[type(node.op)], node.right))
                node = node.left
            if chain:
                acc = self._float(self.expr(node))
                for op, right in reversed(chain):
                    acc = op(acc, self._float(self.expr(right)))
                return acc
        if isinstance(node, ast.Call) and not node.keywords:
            return self.call(node)
        if isinstance(node, ast.IfExp):
            return b.select(self._bool(self.expr(node.test)), self._float(self.expr(node.body)),
                            self._float(self.expr(node.orelse)))
        if isinstance(node, ast.Compare) and len(node.ops) == 1:
            # Python's comparisons of floats: ordered (False with a NaN) except != (True with a NaN)
            sym = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}
            op = sym.get(type(node.ops[0]))
            if op is not None:
                lhs, rhs = self._float(self.expr(node.left)), self._float(self.expr(node.comparators[0]))
                return b.fcmp_unordered(op, lhs, rhs) if op == "!=" else b.fcmp_ordered(op, lhs, rhs)
        if isinstance(node, ast.BoolOp):
            vals = [self._bool(self.expr(v)) for v in node.values]
            acc = vals[0]
            for v in vals[1:]:
                acc = b.and_(acc, v) if isinstance(node.op, ast.And) else b.or_(acc, v)
            return acc
        raise NotNativeError(f"expression {type(node).__name__}")

    def _int_exponent(self, node):
        if isinstance(node, ast.Constant) and type(node.value) is int:
            return node.value
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            k = self._int_exponent(node.operand)
            return None if k is None else -k
        return None

    def power(self, node):
        b = self.builder
        base = self._float(self.expr(node.left))
        k = self._int_exponent(node.right)
        if k is not None and abs(k) <= _MAX_STATIC_POWER:
            # numba's power by a constant integer: square-and-multiply from 1, then 1/r for k < 0
            res, a, e = self._const(1.0), base, abs(k)
            while e:
                if e & 1:
                    res = b.fmul(res, a)
                e >>= 1
                if e:
                    a = b.fmul(a, a)
            return b.fdiv(self._const(1.0), res) if k < 0 else res
        return self._intrinsic("llvm.pow", base, self._float(self.expr(node.right)))

    def _intrinsic(self, name, *args):
        fn = self.module.declare_intrinsic(name, [self.double])
        if name in ("llvm.sin", "llvm.cos"):
            self.trig[name].add(id(args[0]))
        return self.builder.call(fn, list(args))

    @property
    def sin_cos(self) -> bool:
        """Whether the function takes the sine and the cosine of one IR value (``_opt_level``)."""
        return bool(self.trig["llvm.sin"] & self.trig["llvm.cos"])

    def _libm(self, name, *args):
        ir = self.ir
        fn = self.module.globals.get(name)
        if fn is None:
            fn = ir.Function(self.module, ir.FunctionType(self.double, [self.double] * len(args)), name=name)
        return self.builder.call(fn, list(args))

    def call(self, node):
        f = node.func
        args = [self._float(self.expr(a)) for a in node.args]
        if isinstance(f, ast.Name) and f.id == "abs" and len(args) == 1:
            return self._intrinsic("llvm.fabs", args[0])
        if isinstance(f, ast.Name) and f.id in ("min", "max") and len(args) >= 2:
            # Python's min/max: keep the first unless a later one compares smaller (larger)
            acc = args[0]
            for x in args[1:]:
                better = self.builder.fcmp_ordered("<" if f.id == "min" else ">", x, acc)
                acc = self.builder.select(better, x, acc)
            return acc
        if isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) and f.value.id == "math":
            if f.attr in _INTRINSIC1 and len(args) == 1:
                return self._intrinsic(_INTRINSIC1[f.attr], args[0])
            if f.attr in _LIBM1 and len(args) == 1:
                return self._libm(f.attr, args[0])
            if f.attr in _LIBM2 and len(args) == 2:
                return self._libm(f.attr, *args)
            if f.attr == "pow" and len(args) == 2:
                return self._intrinsic("llvm.pow", *args)
            if f.attr == "copysign" and len(args) == 2:
                return self._intrinsic("llvm.copysign", *args)
        raise NotNativeError(f"call of {ast.unparse(f)}")


class NativeFunction(WrapperAddressProtocol):
    """One native model function as numba's first-class function type sees it: its address and
    its signature. Holds its engine so that the code lives as long as the function."""

    def __init__(self, name, addr, sig, engine):
        self.name, self._addr, self._sig, self._engine = name, addr, sig, engine

    def __wrapper_address__(self):
        return self._addr

    def signature(self):
        return self._sig

    def __repr__(self):
        return f"<native model function {self.name} {self._sig}>"


def _model_functions(tree):
    """{name: (FunctionDef, signature)} of the @_jit(_mt.<SIG>, ...) functions and the MODEL
    tuple's names, from the module's syntax tree."""
    fns, model = {}, None
    for node in tree.body:
        if isinstance(node, ast.FunctionDef):
            deco = node.decorator_list
            if (len(deco) != 1 or not isinstance(deco[0], ast.Call) or not deco[0].args
                    or not isinstance(deco[0].args[0], ast.Attribute)):
                raise NotNativeError(f"{node.name}: not a generated model function")
            sig = getattr(mt, deco[0].args[0].attr, None)
            if sig is None or not isinstance(sig, Signature):
                raise NotNativeError(f"{node.name}: unknown signature")
            fns[node.name] = (node, sig)
        elif (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
              and node.targets[0].id == "MODEL" and isinstance(node.value, ast.Tuple)):
            model = node.value.elts
    if model is None:
        raise NotNativeError("no MODEL tuple")
    return fns, model


def module_constants(source: str) -> dict:
    """The integer/bool/tuple constants of a model module (N_DOF, N_CON, FORM, HAS_N,
    HESS_PATTERN), read without executing it (a copy: the parse is kept per source)."""
    return dict(_constants(source))


@functools.lru_cache(maxsize=64)
def _constants(source: str) -> dict:
    out = {}
    for node in _tree(source).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            try:
                out[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                pass
    return out


@functools.lru_cache(maxsize=4)
def _tree(source: str):
    """The syntax tree of a model source, parsed once for its constants and its translation (a
    large model's parse is a tenth of a second); read only."""
    with SOURCE_LOCK:                 # ast.parse in two threads at once (gensource.SOURCE_LOCK)
        return ast.parse(source)


def compile_model(source: str, params=()) -> tuple:
    """The model tuple (n, functions..., [has_N]) of a generated model module as the kernels take
    it, each function native code behind the wrapper address protocol. A model with parameters
    (``N_PARAMS``) is compiled once per source with the values behind a pointer argument; each
    set of ``params`` (floats, in the system's order) then costs only small wrappers that pass a
    pointer to its own constant copy of the values (so that runs with different values can share
    the process, threads included). Raises NotNativeError when the source has a construct this
    translator does not take."""
    consts = module_constants(source)
    k = consts.get("N_PARAMS", 0)
    vals = tuple(float(x) for x in params)
    if type(k) is not int or k < 0 or len(vals) != k or not all(math.isfinite(x) for x in vals):
        raise NotNativeError(f"the model takes {k} finite parameter values, got {len(vals)}")
    from .cache import source_key
    key = source_key(source)
    # one thread at a time: _bind names each wrapper module by the count of those made so far
    # (two threads took the same name, and a run got the other's parameter values: 10 of 12
    # threads of integrate(params=...) wrong by up to 0.4) and adds it to the one shared MCJIT
    # engine, which is not thread-safe
    with _NATIVE_LOCK:
        base = _BASES.get(key)
        if base is None:
            base = _BASES[key] = _compile_functions(source, consts, k)
        engine, funcs, model = base
        if k:
            funcs = _bind(funcs, vals, engine)
    out = []
    for e in model:
        if isinstance(e, ast.Name) and e.id in funcs:
            out.append(funcs[e.id])
        elif isinstance(e, ast.Name) and e.id in consts and type(consts[e.id]) in (int, bool):
            out.append(consts[e.id])
        else:
            raise NotNativeError("MODEL tuple entry that is neither a function nor a constant")
    return tuple(out)


#: source digest -> (engine, {name: NativeFunction}, MODEL names): a process compiles a model once
_BASES: dict = {}
#: held while a model is compiled or its parameter values bound (``compile_model``)
_NATIVE_LOCK = threading.Lock()


def _target_machine(triple, opt):
    import llvmlite.binding as llvm
    return llvm.Target.from_triple(triple).create_target_machine(
        cpu=llvm.get_host_cpu_name(), features=llvm.get_host_cpu_features().flatten(), opt=opt, jit=True)


def _jit(module, opt):
    import llvmlite.binding as llvm
    _init_llvm()
    try:
        mod = llvm.parse_assembly(str(module))
        mod.verify()
    except RuntimeError as exc:
        raise NotNativeError(f"LLVM refused the model's IR ({str(exc).splitlines()[0][:80]})") from None
    engine = llvm.create_mcjit_compiler(mod, _target_machine(module.triple, opt))
    engine.finalize_object()
    return engine


def _compile_functions(source, consts, k):
    import llvmlite.binding as llvm
    from llvmlite import ir
    try:
        tree = _tree(source)
    except SyntaxError as exc:
        raise NotNativeError(f"model source does not parse ({exc.msg})") from None
    fns, model = _model_functions(tree)
    module = ir.Module(name="ldaspark_native_model")
    module.triple = llvm.get_process_triple()
    built, size, sin_cos = [], 0, False
    for name, (fdef, sig) in fns.items():
        fn = _Function(module, fdef, sig, k)
        built.append((name, fn.fn.name, sig))
        size += fn.count
        sin_cos = sin_cos or fn.sin_cos
    engine = _jit(module, _opt_level(size, consts.get("N_DOF"), sin_cos))
    funcs = {name: NativeFunction(name, engine.get_function_address(sym), sig, engine) for name, sym, sig in built}
    if any(f._addr == 0 for f in funcs.values()):
        raise NotNativeError("LLVM gave no address for a model function")
    return engine, funcs, model


def _bind(funcs, vals, base_engine):
    """Wrappers with the kernels' signatures around the parametric functions (called by their
    addresses), each passing a pointer to one constant copy of ``vals``. All wrappers live in one
    engine of this process (a module added per value: ~1 ms, where an engine of its own cost ~10 ms)."""
    import llvmlite.binding as llvm
    from llvmlite import ir
    ctx, double = _ctx(), ir.DoubleType()
    tag = f"p{len(_WRAPPERS)}"
    module = ir.Module(name=f"ldaspark_native_params_{tag}")
    module.triple = llvm.get_process_triple()
    arr = ir.ArrayType(double, len(vals))
    g = ir.GlobalVariable(module, arr, name=f"ldaspark_params_{tag}")
    g.global_constant, g.linkage = True, "internal"
    g.initializer = ir.Constant(arr, [ir.Constant(double, x) for x in vals])
    i64 = ir.IntType(64)
    for name, f in funcs.items():
        sig = f.signature()
        ret, args = ctx.get_value_type(sig.return_type), [ctx.get_value_type(a) for a in sig.args]
        wrapper = ir.Function(module, ir.FunctionType(ret, args), name=f"{name}__{tag}")
        b = ir.IRBuilder(wrapper.append_basic_block("entry"))
        target = b.inttoptr(ir.Constant(i64, f._addr), ir.FunctionType(ret, args + [double.as_pointer()]).as_pointer())
        r = b.call(target, list(wrapper.args) + [b.gep(g, [ir.Constant(ir.IntType(32), 0)] * 2)])
        b.ret(r)                       # numba gives void a value type too (what the kernels expect)
    _init_llvm()
    try:
        mod = llvm.parse_assembly(str(module))
        mod.verify()
    except RuntimeError as exc:
        raise NotNativeError(f"LLVM refused the wrappers' IR ({str(exc).splitlines()[0][:80]})") from None
    if not _WRAPPERS:
        empty = ir.Module(name="ldaspark_native_wrappers")
        empty.triple = module.triple
        _WRAPPERS.append(_jit(empty, 0))
    engine = _WRAPPERS[0]
    engine.add_module(mod)
    engine.finalize_object()
    _WRAPPERS.append(mod)
    out = {name: NativeFunction(name, engine.get_function_address(f"{name}__{tag}"), f.signature(),
                                (engine, base_engine))
           for name, f in funcs.items()}
    if any(f._addr == 0 for f in out.values()):
        raise NotNativeError("LLVM gave no address for a model function")
    return out


#: [the engine of every wrapper module, the modules added to it] (the modules' code lives as
#: long as the engine, i.e. the process)
_WRAPPERS: list = []


_LLVM_READY: list = []


def _init_llvm():
    if not _LLVM_READY:
        import llvmlite.binding as llvm
        import numba.core.codegen  # noqa: F401  (numba initialises LLVM's native target on import)
        llvm.initialize_native_target()
        llvm.initialize_native_asmprinter()
        _LLVM_READY.append(True)


def _python_code(source: str):
    """The code object of ``python_module`` (under ``SOURCE_LOCK``)."""
    import sys
    try:
        tree = ast.parse(source)
    except (RecursionError, MemoryError, SyntaxError) as exc:
        raise NotNativeError(f"the model's Python form does not parse ({type(exc).__name__})") from None
    tree.body = [n for n in tree.body if not (isinstance(n, ast.ImportFrom) and n.module == "ldaspark.compiled.cache")]
    limit = sys.getrecursionlimit()
    try:
        # the transformer's own recursion follows the nesting the parser accepted (ast.parse
        # builds deeper trees than compile takes)
        sys.setrecursionlimit(max(limit, 20000))
        tree = ast.fix_missing_locations(BalancedSums().visit(tree))
    finally:
        sys.setrecursionlimit(limit)
    try:
        return compile(tree, "<ldaspark model>", "exec")
    except (RecursionError, MemoryError) as exc:
        raise NotNativeError(f"the model's Python form does not compile ({type(exc).__name__})") from None


def python_module(source: str):
    """The model module's functions as plain Python (numpy arrays in and out), for the few calls
    made outside the kernels (the set-up checks): the generated source executed with the jit
    decorator replaced by the identity, nothing compiled. The source is codegen's own output,
    whose every name is checked (``codegen._only_generated_symbols``); long sums and products
    are rebalanced (``gensource.BalancedSums``) so that any model size compiles."""
    import types as _types
    with SOURCE_LOCK:                 # parse, recursion limit and compile: one thread at a time
        code = _python_code(source)
    mod = _types.ModuleType("ldaspark_model_python")
    mod.__dict__["_jit"] = lambda *args, **kwargs: (lambda f: f)
    exec(code, mod.__dict__)     # noqa: S102  (our generated code)
    return mod
