"""xacro expressions evaluated as data: ``${...}`` and ``$(eval ...)`` without Python's ``eval``.

xacro evaluates both with Python's ``eval`` (its guard, refusing the text ``__``, is easily
passed by escapes), so expanding a file would run the code it carries. Here an expression is
parsed with :mod:`ast` and walked by an allowlist: number, text, boolean and ``None``
literals; lists, tuples (and dicts in ``$(eval)``); names that are xacro properties (or, in
``$(eval)``, xacro arguments); the math constants and functions of :data:`MATH_NAMES`; the
builtins of :data:`BUILTIN_NAMES`; ``xacro.arg``, ``xacro.load_yaml`` (YAML is read with
PyYAML's safe loader) and ``xacro.fatal``/``warning``/``message``/``error``;
arithmetic, comparison and boolean operators; ``a if c else b``; subscripts; and
``ns.name`` only on a xacro namespace (an include's ``ns``, a YAML mapping, ``math``,
``python``, ``xacro``), read as a lookup, never as a Python attribute.

Anything else (attribute access, other calls, ``lambda``, comprehensions, f-strings, a
double underscore anywhere in the text, a result beyond :data:`MAX_INT_BITS` bits or
:data:`MAX_LENGTH` items) raises :class:`~hybrid_force.errors.RobotError` saying how to opt in
to xacro's own evaluation (``robot.xacro_trust = true``, ``--trust-xacro``). An ordinary
mistake (an undefined name, a division by zero, a type error) raises the same Python error
that xacro's evaluation would, so xacro's message about it is unchanged.
"""

from __future__ import annotations

import ast
import builtins
import math
import operator
import re
from collections.abc import Callable, Mapping
from typing import Any

from hybrid_force.errors import RobotError

__all__ = [
    "BUILTIN_NAMES",
    "MATH_NAMES",
    "MAX_INT_BITS",
    "MAX_LENGTH",
    "MAX_MACRO_CALLS",
    "TRUST_HINT",
    "counted_macro_calls",
    "eval_expression",
    "eval_substitution",
]

#: Largest integer a safe expression may make or hold [bits] (a ``9**9**9`` is refused).
MAX_INT_BITS = 4096
#: Most characters of a text, or items of a list or tuple, a safe expression may make.
MAX_LENGTH = 100_000
#: Most macro calls one expansion may make (nested macros could otherwise grow it without bound).
MAX_MACRO_CALLS = 5_000
#: Longest expression text and most syntax nodes and nesting levels of one expression.
_MAX_TEXT = 10_000
_MAX_NODES = 2_000
_MAX_DEPTH = 100

TRUST_HINT = (
    "xacro expressions are evaluated as data (numbers, texts, properties, math); to let xacro "
    "run this file's Python, trust it: robot.xacro_trust = true in the scenario's [robot] "
    "table, --trust-xacro on the command line, or load_robot(..., xacro_trust=True)"
)


class _Function:
    """A callable a safe expression may call (nothing else is called)."""

    __slots__ = ("fn", "name")

    def __init__(self, name: str, fn: Callable[..., Any]) -> None:
        self.name = name
        self.fn = fn

    def __repr__(self) -> str:
        return f"<function {self.name}>"


class _Namespace:
    """A fixed mapping read by ``ns.name`` (``math``, ``python``, ``xacro``)."""

    __slots__ = ("items", "name")

    def __init__(self, name: str, items: Mapping[str, Any]) -> None:
        self.name = name
        self.items = dict(items)

    def __repr__(self) -> str:
        return f"<namespace {self.name}>"


def _sum(values: Any) -> Any:
    return builtins.sum(values)  # one argument: no list concatenation through start=[]


def _round(number: Any, ndigits: Any = None) -> Any:
    # round(n, -k) of an integer computes 10**k first: k is bounded
    if isinstance(ndigits, int) and abs(ndigits) > 400:
        raise _Refused(f"rounds to {ndigits} digits (at most 400)")
    return round(number, ndigits)


_MATH_FUNCTIONS = (
    "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "asinh",
    "acosh", "atanh", "sqrt", "exp", "log", "log10", "log2", "pow", "hypot", "radians",
    "degrees", "floor", "ceil", "trunc", "fabs", "fmod", "copysign", "isclose", "isfinite",
    "isinf", "isnan",
)  # fmt: skip
#: The math names a safe expression knows, directly and as ``math.NAME``.
MATH_NAMES: dict[str, Any] = {
    **{k: getattr(math, k) for k in ("pi", "e", "tau", "inf", "nan")},
    **{k: _Function(k, getattr(math, k)) for k in _MATH_FUNCTIONS},
}
_BUILTINS: dict[str, Callable[..., Any]] = {
    "abs": abs, "min": min, "max": max, "float": float, "int": int, "str": str,
    "bool": bool, "len": len, "round": _round, "sum": _sum, "sorted": sorted,
    "list": list, "tuple": tuple,
}  # fmt: skip
#: The builtins a safe expression may call, directly and as ``python.NAME``.
BUILTIN_NAMES: dict[str, _Function] = {k: _Function(k, f) for k, f in _BUILTINS.items()}

_BINARY: dict[type[ast.operator], Callable[[Any, Any], Any]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.FloorDiv: operator.floordiv,
    ast.Mod: operator.mod,
    ast.Pow: operator.pow,
}
_UNARY: dict[type[ast.unaryop], Callable[[Any], Any]] = {
    ast.UAdd: operator.pos,
    ast.USub: operator.neg,
    ast.Not: operator.not_,
    ast.Invert: operator.invert,
}
_COMPARE: dict[type[ast.cmpop], Callable[[Any, Any], Any]] = {
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.In: lambda a, b: a in b,
    ast.NotIn: lambda a, b: a not in b,
    ast.Is: operator.is_,
    ast.IsNot: operator.is_not,
}
_NUMBERS = (bool, int, float, complex)
_SCALARS = (*_NUMBERS, str, type(None))
# a printf conversion of "text % values": its width and precision are bounded below
_PERCENT = re.compile(r"%(?:\([^)]*\))?[-#0 +]*(\*|\d*)(?:\.(\*|\d*))?[hlL]?.")


class _Refused(Exception):
    """An expression outside the allowlist (turned into a RobotError by the caller)."""


def _short(text: str, limit: int = 80) -> str:
    text = " ".join(text.split())
    return text if len(text) <= limit else text[: limit - 1] + "…"


class _Evaluator:
    """Walks one parsed expression, one method per allowed node type (any other is refused);
    ``lookup(name)`` gives a name's value (or raises NameError or _Refused), ``member(owner,
    name)`` the value of ``owner.name`` (or raises _Refused)."""

    def __init__(self, lookup: Callable[[str], Any], member: Callable[[Any, str], Any]) -> None:
        self.lookup = lookup
        self.member = member

    def value(self, node: ast.AST) -> Any:
        method = getattr(self, f"_{type(node).__name__}", None)
        if method is None:
            raise _Refused(f"uses {_describe(node)}")
        return method(node)

    # --- leaves ----------------------------------------------------------------------------
    def _Constant(self, node: ast.Constant) -> Any:
        if not isinstance(node.value, _SCALARS):
            raise _Refused(f"uses a {type(node.value).__name__} literal")
        return _checked(node.value)

    def _Name(self, node: ast.Name) -> Any:
        if node.id.startswith("__"):
            raise _Refused(f"uses the double-underscore name {node.id!r}")
        return _checked_value(self.lookup(node.id), node.id)

    # --- containers ------------------------------------------------------------------------
    def _List(self, node: ast.List) -> Any:
        return [self.value(e) for e in node.elts]

    def _Tuple(self, node: ast.Tuple) -> Any:
        return tuple(self.value(e) for e in node.elts)

    def _Dict(self, node: ast.Dict) -> Any:
        if any(k is None for k in node.keys):
            raise _Refused("unpacks a mapping (**)")
        return {self.value(k): self.value(v) for k, v in zip(node.keys, node.values, strict=True)}  # type: ignore[arg-type]

    # --- operators -------------------------------------------------------------------------
    def _BinOp(self, node: ast.BinOp) -> Any:
        op = _BINARY.get(type(node.op))
        if op is None:
            raise _Refused(f"uses the operator {type(node.op).__name__}")
        left, right = self.value(node.left), self.value(node.right)
        _check_bounds(type(node.op), left, right)
        return _checked(op(left, right))

    def _UnaryOp(self, node: ast.UnaryOp) -> Any:
        return _checked(_UNARY[type(node.op)](self.value(node.operand)))

    def _BoolOp(self, node: ast.BoolOp) -> Any:
        result: Any = None
        for item in node.values:  # short-circuit as Python does, giving the deciding operand
            result = self.value(item)
            if isinstance(node.op, ast.And) and not result:
                return result
            if isinstance(node.op, ast.Or) and result:
                return result
        return result

    def _Compare(self, node: ast.Compare) -> Any:
        left = self.value(node.left)
        for op, item in zip(node.ops, node.comparators, strict=True):
            right = self.value(item)
            if not _COMPARE[type(op)](left, right):
                return False
            left = right
        return True

    def _IfExp(self, node: ast.IfExp) -> Any:
        return self.value(node.body) if self.value(node.test) else self.value(node.orelse)

    # --- look-ups and calls ----------------------------------------------------------------
    def _Subscript(self, node: ast.Subscript) -> Any:
        from xacro import Table

        container = self.value(node.value)
        key = self.value(node.slice)
        if isinstance(container, Table):  # a namespace: its own properties, never xacro's root
            found, value = _table_get(container, key) if isinstance(key, str) else (False, None)
            if not found:
                raise KeyError(key)
            return _checked_value(value, key)
        if not isinstance(container, (str, list, tuple, dict)):
            raise _Refused(f"subscripts a {type(container).__name__}")
        return _checked_value(container[key], "a subscript")

    def _Slice(self, node: ast.Slice) -> Any:
        parts = [None if p is None else self.value(p) for p in (node.lower, node.upper, node.step)]
        if not all(p is None or isinstance(p, int) for p in parts):
            raise _Refused("slices with something that is not an integer")
        return slice(*parts)

    def _Attribute(self, node: ast.Attribute) -> Any:
        if node.attr.startswith("_"):
            raise _Refused(f"reads the attribute {node.attr!r}")
        owner = self.value(node.value)
        return _checked_value(self.member(owner, node.attr), node.attr)

    def _Call(self, node: ast.Call) -> Any:
        function = self.value(node.func)
        if not isinstance(function, _Function):
            raise _Refused(
                f"calls {_describe(node.func)}, which is not one of the allowed functions"
            )
        if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
            raise _Refused(f"calls {function.name} with keyword or * arguments")
        args = [self.value(a) for a in node.args]
        return _checked(function.fn(*args))


def _describe(node: ast.AST) -> str:
    """What a refused node is, for the message."""
    names = {
        "Lambda": "a lambda",
        "ListComp": "a comprehension",
        "SetComp": "a comprehension",
        "DictComp": "a comprehension",
        "GeneratorExp": "a generator expression",
        "JoinedStr": "an f-string",
        "NamedExpr": "an assignment expression (:=)",
        "Attribute": "an attribute",
        "Starred": "* unpacking",
        "Set": "a set",
    }
    kind = type(node).__name__
    if isinstance(node, ast.Name):
        return f"{node.id!r}"
    if isinstance(node, ast.Attribute):
        return f"the attribute {node.attr!r}"
    return names.get(kind, f"a {kind} expression")


def _checked(value: Any) -> Any:
    """The value, if within the bounds (integer size, text and list length)."""
    if isinstance(value, int) and not isinstance(value, bool):
        if value.bit_length() > MAX_INT_BITS:
            raise _Refused(f"makes an integer of more than {MAX_INT_BITS} bits")
    elif isinstance(value, (str, list, tuple, dict)):
        size = len(value) if isinstance(value, str) else _size(value)
        if size > MAX_LENGTH:
            raise _Refused(f"makes a text or list of more than {MAX_LENGTH} items")
    return value


def _size(value: Any) -> int:
    """Items and characters of a nested list, tuple or dict, counted up to just past
    :data:`MAX_LENGTH` (a list repeated inside a list is counted each time: it is printed
    each time)."""
    total, stack = 0, [value]
    while stack and total <= MAX_LENGTH:
        item = stack.pop()
        total += 1
        if isinstance(item, str):
            total += len(item)
        elif isinstance(item, dict):
            stack.extend(item.keys())
            stack.extend(item.values())
        elif isinstance(item, (list, tuple)):
            stack.extend(item[: MAX_LENGTH + 1])
    return total


def _checked_value(value: Any, name: str) -> Any:
    """A looked-up value, if of a kind a safe expression may hold."""
    from xacro import NameSpace

    if isinstance(value, (*_SCALARS, list, tuple, dict, NameSpace, _Function, _Namespace)):
        return _checked(value)
    raise _Refused(f"uses {name!r}, a {type(value).__name__} value")


def _check_bounds(op: type[ast.operator], left: Any, right: Any) -> None:
    """Refuse an operation whose result would exceed the bounds before it is made."""

    def bits(x: Any) -> int:
        return abs(x).bit_length() if isinstance(x, int) else 0

    if op is ast.Pow and isinstance(left, int) and isinstance(right, int) and right > 0:
        if bits(left) > 1 and (bits(left) - 1) * right > MAX_INT_BITS:
            raise _Refused(f"makes an integer of more than {MAX_INT_BITS} bits")
    elif op is ast.Mult:
        sizes = [len(x) for x in (left, right) if isinstance(x, (str, list, tuple))]
        counts = [x for x in (left, right) if isinstance(x, int)]
        if sizes and counts and sizes[0] * max(counts[0], 0) > MAX_LENGTH:
            raise _Refused(f"makes a text or list of more than {MAX_LENGTH} items")
        if len(counts) == 2 and bits(left) + bits(right) > MAX_INT_BITS + 1:
            raise _Refused(f"makes an integer of more than {MAX_INT_BITS} bits")
    elif op is ast.Mod and isinstance(left, str):
        for width, precision in _PERCENT.findall(left):
            for part in (width, precision):
                if part == "*" or len(part) > 4:
                    raise _Refused("formats text with a width or precision above 9999")


def _parse(text: str) -> ast.expr:
    """The expression's syntax tree, within the size bounds."""
    if len(text) > _MAX_TEXT:
        raise _Refused(f"is longer than {_MAX_TEXT} characters")
    if "__" in text:  # before parsing: even an unfinished expression is refused for it
        raise _Refused("contains a double underscore (__)")
    try:
        tree = ast.parse(text.strip(), mode="eval")  # a SyntaxError is xacro's to report
    except (RecursionError, MemoryError):
        raise _Refused("is nested too deeply") from None
    count = 0
    stack: list[tuple[ast.AST, int]] = [(tree.body, 1)]
    while stack:
        node, depth = stack.pop()
        count += 1
        if count > _MAX_NODES or depth > _MAX_DEPTH:
            raise _Refused("is too large or nested too deeply")
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
    return tree.body


def _run(text: str, lookup: Callable[[str], Any], member: Callable[[Any, str], Any]) -> Any:
    """Evaluate ``text``; a refusal is a RobotError naming the expression."""
    try:
        return _Evaluator(lookup, member).value(_parse(text))
    except _Refused as exc:
        raise RobotError(f"the expression '{_short(text)}' {exc}; {TRUST_HINT}") from None
    except RecursionError:
        raise RobotError(f"the expression '{_short(text)}' is nested too deeply") from None


def _unknown(name: str) -> NameError | _Refused:
    """The error for a name that is neither a property nor allowed: a Python builtin (or a
    name of xacro's Python namespace) is refused, anything else is undefined as in xacro."""
    if hasattr(builtins, name) or name in ("python", "xacro", "math"):
        return _Refused(f"uses {name!r}, which is not one of the allowed names")
    return NameError(f"name '{name}' is not defined")


def _table_get(table: Any, name: str) -> tuple[bool, Any]:
    """(found, value) of a property in a xacro Table and its parents, never its root (xacro's
    own global symbols, which hold Python's builtins and modules)."""
    root = getattr(table, "root", None)
    while hasattr(table, "parent") and table is not root:
        if dict.__contains__(table, name):
            return True, table[name]  # Table.__getitem__: a lazy property is evaluated here
        table = table.parent
    return False, None


def _xacro_namespace() -> _Namespace:
    """``xacro.arg``, ``xacro.load_yaml`` and xacro's message functions."""
    import xacro

    own = dict.get(xacro._global_symbols, "xacro", {})
    items: dict[str, Any] = {
        "arg": _Function("xacro.arg", lambda name: xacro.substitution_args_context["arg"][name]),
        "load_yaml": _Function("xacro.load_yaml", xacro.load_yaml),
    }
    for name in ("fatal", "warning", "message", "error"):
        if dict.__contains__(own, name):
            items[name] = _Function(f"xacro.{name}", dict.__getitem__(own, name))
    return _Namespace("xacro", items)


def _member(owner: Any, name: str) -> Any:
    """``owner.name`` for the owners that allow it: a lookup, never Python's getattr."""
    from xacro import NameSpace, YamlDictWrapper

    if isinstance(owner, _Namespace):
        if name in owner.items:
            return owner.items[name]
        raise _Refused(f"uses {owner.name}.{name}, which is not one of the allowed names")
    if isinstance(owner, NameSpace):
        found, value = _table_get(owner, name)
        if found:
            return value
        raise NameError(f"name '{name}' is not defined")
    if isinstance(owner, YamlDictWrapper):  # a YAML mapping's dotted access
        return owner[name]
    raise _Refused(f"reads the attribute {name!r} of a {type(owner).__name__}")


def eval_expression(text: str, symbols: Any) -> Any:
    """The value of a ``${...}`` expression with the xacro properties ``symbols``.

    Names: a property (``symbols`` and its parent tables), then :data:`MATH_NAMES`,
    :data:`BUILTIN_NAMES`, ``True``/``False``, ``load_yaml`` and the namespaces ``math``,
    ``python`` and ``xacro``.

    Raises:
        RobotError: the expression is outside the allowlist (see the module docstring).
        NameError, TypeError, ValueError, ZeroDivisionError, …: as Python's ``eval`` would.
    """
    xacro_ns = _xacro_namespace()
    fixed: dict[str, Any] = {
        **MATH_NAMES,
        **BUILTIN_NAMES,
        "True": True,
        "False": False,
        "load_yaml": xacro_ns.items["load_yaml"],
        "math": _Namespace("math", MATH_NAMES),
        "python": _Namespace("python", BUILTIN_NAMES),
        "xacro": xacro_ns,
    }

    def lookup(name: str) -> Any:
        found, value = _table_get(symbols, name)
        if found:
            return value
        if name in fixed:
            return fixed[name]
        raise _unknown(name)

    return _run(str(text), lookup, _member)


def eval_substitution(text: str, context: dict[str, Any]) -> str:
    """The text of ``$(eval TEXT)`` with xacro's substitution context (its ``arg`` values).

    Names as xacro's ``$(eval)`` knows them: ``arg(name)``, ``env(name)``,
    ``optenv(name[, default])``, ``dirname()``, ``find(package)``, ``true``/``false``, the
    math names; any other name is the xacro argument of that name (a number when it reads as
    one).

    Raises:
        RobotError: the expression is outside the allowlist.
        NameError, TypeError, …: as Python's ``eval`` would.
    """
    from xacro import substitution_args as sa

    args: dict[str, str] = context.setdefault("arg", {})
    fixed: dict[str, Any] = {
        **MATH_NAMES,
        "true": True,
        "false": False,
        "True": True,
        "False": False,
        "arg": _Function("arg", lambda name: sa.convert_value(sa._eval_arg(name, args), "auto")),
        "dirname": _Function("dirname", lambda: sa._eval_dirname(context.get("filename"))),
        "env": _Function("env", sa._eval_env),
        "optenv": _Function("optenv", sa._eval_optenv),
        "find": _Function("find", lambda name: sa._eval_dict["find"](name)),
    }

    def lookup(name: str) -> Any:
        if name in fixed:
            return fixed[name]
        if name in args:
            return sa.convert_value(args[name], "auto")
        raise _unknown(name)

    return str(_run(str(text), lookup, _member))


def counted_macro_calls(handle: Callable[..., bool]) -> Callable[..., bool]:
    """xacro's ``handle_macro_call``, refusing the call after :data:`MAX_MACRO_CALLS` macro
    calls (of this wrapper: one per expansion)."""
    calls = 0

    def counted(node: Any, macros: Any, symbols: Any) -> bool:
        nonlocal calls
        if str(getattr(node, "tagName", "")).startswith("xacro:"):
            calls += 1
            if calls > MAX_MACRO_CALLS:
                raise RobotError(
                    f"more than {MAX_MACRO_CALLS} macro calls (the last one: <{node.tagName}>): "
                    f"the expansion is refused as unbounded; {TRUST_HINT}"
                )
        return handle(node, macros, symbols)

    return counted
