"""The expressions a gym space file may write: bounded arithmetic and conditions, parsed, never ``eval``-ed.

Two kinds, both read with :mod:`ast` and walked by a small evaluator:

- *arithmetic* (``[env] derived``): numbers, names and ``+ - * / **`` (``total_mass = "masspole + masscart"``);
- *conditions* (a measure's ``when``, a fault's ``condition``): arithmetic plus comparisons, ``and``, ``or``,
  ``not`` and constant subscripts over a fixed set of names (``obs[6] > 0 or obs[7] > 0``,
  ``info["is_success"]``).

A space file is data a user may receive from someone else, so no expression may hang the audit: the text is at
most :data:`MAX_LENGTH` characters and :data:`MAX_DEPTH` levels deep, every number is a 64-bit float (Python would
compute ``9**9**9`` as a 370-million-digit integer; :func:`math.pow` refuses it at once), and the parts made of
constants alone are computed when the expression is read, so ``9**9**9`` is refused then, in one line.
"""

from __future__ import annotations

import ast
import dataclasses
import functools
import math
import operator
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from dsage_ray.domains.gym.errors import SpaceError

#: The longest expression a space file may write (CartPole's longest is 19 characters).
MAX_LENGTH = 300
#: The deepest nesting of operations and parentheses.
MAX_DEPTH = 24

_ARITHMETIC: dict[type, Callable[..., float]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
    # math.pow, not **: in floats (no unbounded integers), a domain error for (-8) ** 0.5 instead of a complex.
    ast.Pow: math.pow, ast.USub: operator.neg, ast.UAdd: operator.pos}
_COMPARISONS: dict[type, Callable[[float, float], bool]] = {
    ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge, ast.Eq: operator.eq,
    ast.NotEq: operator.ne}
_ARITHMETIC_NODES = (ast.Expression, ast.BinOp, ast.UnaryOp, ast.Name, ast.Load, ast.Constant, ast.Subscript,
                     *_ARITHMETIC)
_CONDITION_NODES = (*_ARITHMETIC_NODES, ast.Compare, ast.BoolOp, ast.And, ast.Or, ast.Not, *_COMPARISONS)


class ExpressionError(SpaceError):
    """An expression of a space file that is not bounded arithmetic (or a condition); the message names it."""


@dataclasses.dataclass(frozen=True)
class Expression:
    """A checked expression; :meth:`value` computes it with given names.

    Build one with :func:`parse_arithmetic` or :func:`parse_condition`.

    Attributes:
        text: The expression as written.
        condition: Whether comparisons and ``and``/``or``/``not`` are allowed (then :meth:`holds` reads it).
    """

    text: str
    condition: bool = False

    @functools.cached_property
    def _tree(self) -> ast.expr:
        return ast.parse(self.text, mode="eval").body

    def value(self, names: Mapping[str, Any]) -> float:
        """The expression's value with ``names`` as its variables, a float (a condition: 1.0 or 0.0).

        Raises:
            KeyError: A name (or an ``info`` key) that ``names`` lacks; callers say whose.
            IndexError: An index past an array's end.
            ArithmeticError, ValueError: Division by zero, an overflow, a negative number to a fractional power.
        """
        return _evaluate(self._tree, names)

    def holds(self, names: Mapping[str, Any]) -> bool:
        """Whether a condition is true with ``names`` (a number is true when it is not zero)."""
        return bool(_evaluate(self._tree, names))


def parse_arithmetic(text: Any, *, where: str) -> Expression:
    """A bounded arithmetic expression: numbers, names, constant subscripts and ``+ - * / **``.

    Raises:
        ExpressionError: Anything else, too long or too deep, or constants whose arithmetic overflows (one line,
            starting with ``where``).
    """
    return _parse(text, where=where, nodes=_ARITHMETIC_NODES, names=None,
                  allowed="numbers, names and + - * / **")


def parse_condition(text: Any, *, where: str, names: Sequence[str]) -> Expression:
    """A bounded condition over ``names``: arithmetic, comparisons, ``and``/``or``/``not``, ``obs[6]``, ``info["k"]``.

    Raises:
        ExpressionError: Anything else, a name not in ``names``, too long or too deep (one line).
    """
    return _parse(text, where=where, nodes=_CONDITION_NODES, names=tuple(names),
                  allowed=f"numbers, {', '.join(names)}, subscripts, + - * / **, comparisons, and, or, not")


def _parse(text: Any, *, where: str, nodes: tuple[type, ...], names: tuple[str, ...] | None,
           allowed: str) -> Expression:
    if not isinstance(text, str):
        raise ExpressionError(f"{where}: expected an expression as a string, got {text!r}")
    shown = text if len(text) <= 60 else text[:57] + "..."
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"{where}: {shown!r} is {len(text)} characters long (at most {MAX_LENGTH})")
    try:
        tree = ast.parse(text, mode="eval")
    except (SyntaxError, ValueError, MemoryError, RecursionError):  # huge literals, deep nesting: the parser's limits
        raise ExpressionError(f"{where}: {shown!r} is not an expression") from None
    if _depth(tree.body) > MAX_DEPTH:
        raise ExpressionError(f"{where}: {shown!r} nests more than {MAX_DEPTH} levels deep")
    for node in ast.walk(tree):
        if not isinstance(node, nodes):
            raise ExpressionError(f"{where}: {shown!r} may hold only {allowed}")
        if isinstance(node, ast.Constant) and (isinstance(node.value, bool)
                                               or not isinstance(node.value, (int, float, str))):
            raise ExpressionError(f"{where}: {shown!r} may hold only {allowed}")
        if isinstance(node, ast.Subscript) and not (isinstance(node.value, ast.Name)
                                                    and isinstance(node.slice, ast.Constant)):
            raise ExpressionError(f"{where}: {shown!r}: a subscript is NAME[INDEX] or NAME[\"KEY\"]")
        if names is not None and isinstance(node, ast.Name) and node.id not in names:
            raise ExpressionError(f"{where}: {shown!r} names {node.id!r} (known: {', '.join(names)})")
    strings = {id(node.slice) for node in ast.walk(tree) if isinstance(node, ast.Subscript)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in strings:
            raise ExpressionError(f"{where}: {shown!r}: text is allowed only as a key, as in info[\"KEY\"]")
    _fold(tree.body, where=where, shown=shown)
    return Expression(text=text, condition=names is not None)


def _depth(node: ast.AST) -> int:
    # Iterative: a deep tree must not exhaust the stack while it is measured.
    deepest, stack = 0, [(node, 1)]
    while stack:
        current, depth = stack.pop()
        deepest = max(deepest, depth)
        if depth <= MAX_DEPTH:
            stack.extend((child, depth + 1) for child in ast.iter_child_nodes(current))
    return deepest


def _fold(node: ast.AST, *, where: str, shown: str) -> bool:
    """Computes every part made of constants alone (so ``9**9**9`` fails here); whether ``node`` is one."""
    children = [child for child in ast.iter_child_nodes(node) if isinstance(child, ast.expr)]
    constant = all([_fold(child, where=where, shown=shown) for child in children])  # every child folded
    if isinstance(node, ast.Constant):
        try:
            float(node.value) if not isinstance(node.value, str) else None
        except OverflowError:
            raise ExpressionError(f"{where}: {shown!r} holds a number too large for a 64-bit float") from None
        return not isinstance(node.value, str)
    if not constant or isinstance(node, (ast.Name, ast.Subscript)):
        return False
    try:
        result = _evaluate(node, {})
    except (ArithmeticError, ValueError) as exc:
        raise ExpressionError(f"{where}: {shown!r} cannot be computed in 64-bit floats "
                              f"({type(exc).__name__}: {exc})") from None
    if not math.isfinite(result):
        raise ExpressionError(f"{where}: {shown!r} overflows a 64-bit float")
    return True


def _number(value: Any) -> float:
    array = np.asarray(value, dtype=np.float64)
    if array.size != 1:
        raise ValueError(f"an array of shape {array.shape} where a number is expected (index it: NAME[0])")
    return float(array.reshape(()))


def _evaluate(node: ast.AST, names: Mapping[str, Any]) -> float:
    if isinstance(node, ast.Constant):
        return float(node.value)
    if isinstance(node, ast.Name):
        if node.id not in names:
            raise KeyError(node.id)
        return _number(names[node.id])
    if isinstance(node, ast.Subscript):
        container, key = names[node.value.id] if node.value.id in names else None, node.slice.value
        if container is None:
            raise KeyError(node.value.id)
        if isinstance(key, str):
            return _number(container[key])
        return _number(np.asarray(container, dtype=np.float64).ravel()[int(key)])
    if isinstance(node, ast.UnaryOp):
        operand = _evaluate(node.operand, names)
        return float(not operand) if isinstance(node.op, ast.Not) else _ARITHMETIC[type(node.op)](operand)
    if isinstance(node, ast.BinOp):
        return float(_ARITHMETIC[type(node.op)](_evaluate(node.left, names), _evaluate(node.right, names)))
    if isinstance(node, ast.BoolOp):
        values = (_evaluate(v, names) for v in node.values)
        return float(all(values) if isinstance(node.op, ast.And) else any(values))
    if isinstance(node, ast.Compare):
        left = _evaluate(node.left, names)
        for op, right_node in zip(node.ops, node.comparators):
            right = _evaluate(right_node, names)
            if not _COMPARISONS[type(op)](left, right):
                return 0.0
            left = right
        return 1.0
    raise TypeError(f"unchecked expression node {type(node).__name__}")  # parse refuses every other node


def check_expression(expression: Any, *, where: str) -> None:
    """Refuses anything but bounded arithmetic in a derived attribute (:func:`parse_arithmetic`)."""
    parse_arithmetic(expression, where=where)


@functools.lru_cache(maxsize=256)
def _checked(expression: str) -> Expression:
    return parse_arithmetic(expression, where="expression")


def evaluate_expression(expression: str, names: Mapping[str, Any]) -> float:
    """The value of a bounded arithmetic expression with ``names`` as its variables.

    Raises:
        ExpressionError: Not bounded arithmetic.
        KeyError: A name ``names`` lacks.
        ArithmeticError, ValueError: Its arithmetic fails with these values (division by zero, an overflow).
    """
    return _checked(expression).value(names)
