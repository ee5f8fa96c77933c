"""The small expression language of lesson files: ``h > 0.8 and in_box``, ``mode == "MANUAL"``, ``abs(h - 2) <= 0.2``.

A teacher writes goals, failures, penalties and the autopilot's waits as one-line expressions over the lesson's
variables (term/lessons/observe.py: ``NAMES``). They are parsed once, when the file is read, with Python's own
parser, and every node must be one of a few kinds: numbers, strings, ``True``/``False``, names from ``NAMES``,
``and``/``or``/``not``, comparisons (``== != < <= > >=``, ``in``/``not in`` a tuple of constants), ``+ - * / %``,
unary minus, and calls of ``abs``, ``min``, ``max``, ``round``. Anything else (attributes, subscripts, lambdas,
other calls) is a load error naming the file, the field and what is not allowed, so a lesson that loads is one
that can run. Evaluation walks the tree itself (never ``eval``); a type mismatch or a division by zero at run time
makes the expression's value ``None``, which conditions read as false.

Resource limits by construction (a file is data a stranger may have written): arithmetic is on numbers only (no
``'x' * 99999999999``, no ``(1,) * 999999999``, no ``'%999999d' % 1``: text and tuples are compared, never
built), a tuple is only the constant right side of ``in``, there is no power operator, and an expression has at
most ``MAX_CHARS`` characters, ``MAX_NODES`` nodes and ``MAX_DEPTH`` levels, so one evaluation is a few hundred
steps on numbers of bounded size. Whatever still goes wrong at run time (an overflow, a recursion) is ``None``.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Collection, Mapping
from typing import Any


class ExprError(ValueError):
    """An expression that cannot be a lesson expression: the message says what and where."""


_BOOL = (ast.And, ast.Or)
_BIN: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
    ast.Mod: operator.mod,
}
_CMP: dict[type, Callable[[Any, Any], bool]] = {
    ast.Eq: operator.eq, ast.NotEq: operator.ne, ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt,
    ast.GtE: operator.ge, ast.In: lambda a, b: a in b, ast.NotIn: lambda a, b: a not in b,
}
FUNCTIONS: dict[str, Callable[..., Any]] = {"abs": abs, "min": min, "max": max, "round": round}
ARITY: dict[str, tuple[int, int]] = {"abs": (1, 1), "min": (2, 8), "max": (2, 8), "round": (1, 2)}
MAX_CHARS = 500
MAX_NODES = 200
MAX_DEPTH = 32
ROUND_DIGITS = 15  # round(x, n): |n| at most this


class Expr:
    """One parsed expression; call it with a namespace to evaluate it."""

    __slots__ = ("text", "tree", "names")

    def __init__(self, text: str, names: Collection[str]) -> None:
        if not isinstance(text, str) or not text.strip():
            raise ExprError("an expression must be a non-empty string")
        if len(text) > MAX_CHARS:
            raise ExprError(f"an expression longer than {MAX_CHARS} characters")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as exc:
            raise ExprError(f"{_quoted(text)} is not an expression: {exc.msg}") from None
        except (RecursionError, MemoryError, ValueError):
            raise ExprError(f"{_quoted(text)} nests too deeply") from None
        nodes = sum(1 for _ in ast.walk(tree))
        if nodes > MAX_NODES:
            raise ExprError(f"{_quoted(text)}: more than {MAX_NODES} parts; split it")
        if _depth(tree.body) > MAX_DEPTH:
            raise ExprError(f"{_quoted(text)}: nests deeper than {MAX_DEPTH} levels")
        used: set[str] = set()
        _check(tree.body, names, used, text)
        self.text = text
        self.tree = tree.body
        self.names = frozenset(used)

    def __call__(self, ns: Mapping[str, Any]) -> Any:
        try:
            value = _eval(self.tree, ns)
        except (ArithmeticError, LookupError, TypeError, ValueError, RecursionError, MemoryError):
            return None  # a scored "expression failed": the condition reads false, a grade is "not measured"
        if isinstance(value, float) and math.isnan(value):
            return None
        return value

    def true(self, ns: Mapping[str, Any]) -> bool:
        return bool(self(ns))

    def __repr__(self) -> str:
        return f"Expr({self.text!r})"


def _quoted(text: str) -> str:
    return repr(text if len(text) <= 60 else text[:59] + "…")


def _depth(node: ast.AST) -> int:
    deepest, stack = 0, [(node, 1)]
    while stack:  # iterative: a deep tree must not recurse here
        n, d = stack.pop()
        deepest = max(deepest, d)
        stack.extend((c, d + 1) for c in ast.iter_child_nodes(n))
    return deepest


def _text_or_tuple(node: ast.AST) -> bool:
    return (isinstance(node, ast.Constant) and isinstance(node.value, str)
            or isinstance(node, ast.Tuple | ast.List | ast.JoinedStr))


def _check(node: ast.AST, names: Collection[str], used: set[str], text: str) -> None:
    def bad(what: str) -> ExprError:
        return ExprError(f"{_quoted(text)}: {what} is not allowed in a lesson expression")

    if isinstance(node, ast.Constant):
        if not isinstance(node.value, bool | int | float | str):
            raise bad(f"the constant {node.value!r}")
    elif isinstance(node, ast.Name):
        if node.id in FUNCTIONS:
            raise bad(f"{node.id} without a call")
        if node.id not in names:
            raise ExprError(f"{text!r}: unknown name {node.id!r}" + _suggest(node.id, names))
        used.add(node.id)
    elif isinstance(node, ast.BoolOp):
        for v in node.values:
            _check(v, names, used, text)
    elif isinstance(node, ast.UnaryOp):
        if not isinstance(node.op, ast.Not | ast.USub | ast.UAdd):
            raise bad(type(node.op).__name__)
        _check(node.operand, names, used, text)
    elif isinstance(node, ast.BinOp):
        if type(node.op) not in _BIN:
            raise bad(f"the operator {type(node.op).__name__}")
        if _text_or_tuple(node.left) or _text_or_tuple(node.right):
            raise bad("arithmetic on text or a tuple (text is compared, never built)")
        _check(node.left, names, used, text)
        _check(node.right, names, used, text)
    elif isinstance(node, ast.Compare):
        _check(node.left, names, used, text)
        for op, right in zip(node.ops, node.comparators, strict=True):
            if type(op) not in _CMP:
                raise bad(f"the comparison {type(op).__name__}")
            if isinstance(op, ast.In | ast.NotIn):
                if not isinstance(right, ast.Tuple | ast.List) or not all(isinstance(e, ast.Constant)
                                                                          for e in right.elts):
                    raise bad("'in' with anything but a tuple of constants")
                for e in right.elts:
                    _check(e, names, used, text)
            else:
                _check(right, names, used, text)
    elif isinstance(node, ast.Tuple | ast.List):
        raise bad("a tuple anywhere but after 'in'")
    elif isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            raise bad("a call of anything but " + ", ".join(FUNCTIONS))
        lo, hi = ARITY[node.func.id]
        if node.keywords or not lo <= len(node.args) <= hi or any(isinstance(a, ast.Starred) for a in node.args):
            raise bad(f"{node.func.id} without {lo}{'' if lo == hi else f' to {hi}'} plain arguments")
        for a in node.args:
            _check(a, names, used, text)
    else:
        raise bad(type(node).__name__)


def _suggest(name: str, names: Collection[str]) -> str:
    import difflib

    close = difflib.get_close_matches(name, list(names), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _number(v: Any) -> bool:
    return isinstance(v, int | float)


def _eval(node: ast.AST, ns: Mapping[str, Any]) -> Any:
    kind = type(node)
    if kind is ast.Constant:
        return node.value  # type: ignore[attr-defined]
    if kind is ast.Name:
        return ns[node.id]  # type: ignore[attr-defined]
    if kind is ast.Compare:
        left = _eval(node.left, ns)  # type: ignore[attr-defined]
        for op, comp in zip(node.ops, node.comparators, strict=True):  # type: ignore[attr-defined]
            right = _eval(comp, ns)
            if left is None or right is None or not _CMP[type(op)](left, right):
                return False
            left = right
        return True
    if kind is ast.BoolOp:
        if isinstance(node.op, ast.And):  # type: ignore[attr-defined]
            value: Any = True
            for v in node.values:  # type: ignore[attr-defined]
                value = _eval(v, ns)
                if not value:
                    return value
            return value
        value = False
        for v in node.values:  # type: ignore[attr-defined]
            value = _eval(v, ns)
            if value:
                return value
        return value
    if kind is ast.UnaryOp:
        v = _eval(node.operand, ns)  # type: ignore[attr-defined]
        op = node.op  # type: ignore[attr-defined]
        if isinstance(op, ast.Not):
            return not v
        if v is None:
            return None
        return -v if isinstance(op, ast.USub) else +v
    if kind is ast.BinOp:
        a, b = _eval(node.left, ns), _eval(node.right, ns)  # type: ignore[attr-defined]
        if not _number(a) or not _number(b):
            return None  # numbers only: a name holding text never repeats it
        return _BIN[type(node.op)](a, b)  # type: ignore[attr-defined]
    if kind in (ast.Tuple, ast.List):
        return tuple(_eval(e, ns) for e in node.elts)  # type: ignore[attr-defined]
    if kind is ast.Call:
        args = [_eval(a, ns) for a in node.args]  # type: ignore[attr-defined]
        if not all(_number(a) for a in args):
            return None
        if len(args) == 2 and node.func.id == "round" and not (  # type: ignore[attr-defined]
                isinstance(args[1], int) and abs(args[1]) <= ROUND_DIGITS):
            return None
        return FUNCTIONS[node.func.id](*args)  # type: ignore[attr-defined]
    raise TypeError(kind.__name__)
