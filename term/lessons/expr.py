"""The small expression language of lesson files: ``h > 0.8 and in_box``, ``mode == "MANUAL"``, ``abs(h - 2) <= 0.2``.

A teacher writes goals, failures, penalties and the autopilot's waits as one-line expressions over the lesson's
variables (term/lessons/observe.py: ``NAMES``). They are parsed once, when the file is read, with Python's own
parser, and every node must be one of a few kinds: numbers, strings, ``True``/``False``, names from ``NAMES``,
``and``/``or``/``not``, comparisons (``== != < <= > >=``, ``in``/``not in`` a tuple of constants), ``+ - * / %``,
unary minus, and calls of ``abs``, ``min``, ``max``, ``round``. Anything else (attributes, subscripts, lambdas,
other calls) is a load error naming the file, the field and what is not allowed, so a lesson that loads is one
that can run. Evaluation walks the tree itself (never ``eval``); a type mismatch or a division by zero at run time
makes the expression's value ``None``, which conditions read as false.
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


class Expr:
    """One parsed expression; call it with a namespace to evaluate it."""

    __slots__ = ("text", "tree", "names")

    def __init__(self, text: str, names: Collection[str]) -> None:
        if not isinstance(text, str) or not text.strip():
            raise ExprError("an expression must be a non-empty string")
        if len(text) > 500:
            raise ExprError("an expression longer than 500 characters")
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as exc:
            raise ExprError(f"{text!r} is not an expression: {exc.msg}") from None
        used: set[str] = set()
        _check(tree.body, names, used, text)
        self.text = text
        self.tree = tree.body
        self.names = frozenset(used)

    def __call__(self, ns: Mapping[str, Any]) -> Any:
        try:
            value = _eval(self.tree, ns)
        except (TypeError, ValueError, ZeroDivisionError, OverflowError, KeyError):
            return None
        if isinstance(value, float) and math.isnan(value):
            return None
        return value

    def true(self, ns: Mapping[str, Any]) -> bool:
        return bool(self(ns))

    def __repr__(self) -> str:
        return f"Expr({self.text!r})"


def _check(node: ast.AST, names: Collection[str], used: set[str], text: str) -> None:
    def bad(what: str) -> ExprError:
        return ExprError(f"{text!r}: {what} is not allowed in a lesson expression")

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
            _check(right, names, used, text)
    elif isinstance(node, ast.Tuple | ast.List):
        for e in node.elts:
            _check(e, names, used, text)
    elif isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            raise bad("a call of anything but " + ", ".join(FUNCTIONS))
        if node.keywords or not node.args:
            raise bad(f"{node.func.id} without plain arguments")
        for a in node.args:
            _check(a, names, used, text)
    else:
        raise bad(type(node).__name__)


def _suggest(name: str, names: Collection[str]) -> str:
    import difflib

    close = difflib.get_close_matches(name, list(names), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


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
        if a is None or b is None:
            return None
        return _BIN[type(node.op)](a, b)  # type: ignore[attr-defined]
    if kind in (ast.Tuple, ast.List):
        return tuple(_eval(e, ns) for e in node.elts)  # type: ignore[attr-defined]
    if kind is ast.Call:
        args = [_eval(a, ns) for a in node.args]  # type: ignore[attr-defined]
        if any(a is None for a in args):
            return None
        return FUNCTIONS[node.func.id](*args)  # type: ignore[attr-defined]
    raise TypeError(kind.__name__)
