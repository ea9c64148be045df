"""Success criteria: a safe expression over a run's metrics.

A criterion is a Python-like expression parsed with :mod:`ast` and walked node by node; nothing
is passed to ``eval``. Allowed: numbers, ``true``/``false`` (or ``True``/``False``), metric
names (dotted: ``tracking.free_error_max``), ``+ - * / **``, comparisons (chained too),
``and``, ``or``, ``not``, parentheses and the functions ``abs``, ``min``, ``max``,
``isfinite``, ``isnan``. A metric that is missing or NaN makes every comparison with it false,
so a run without the figure does not pass.

Example: ``max_penetration < 1e-3 and weak_stability.cycles_complete``.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from ucontrol.exceptions import CriterionError

_COMPARE: dict[type[ast.cmpop], Callable[[Any, Any], bool]] = {
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
}
_BINARY: dict[type[ast.operator], Callable[[Any, Any], Any]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "abs": abs,
    "min": min,
    "max": max,
    "isfinite": lambda x: math.isfinite(float(x)),
    "isnan": lambda x: math.isnan(float(x)),
}
_CONSTANTS = {"true": True, "false": False, "True": True, "False": False}


@dataclass(frozen=True)
class Criterion:
    """A parsed success criterion.

    Attributes:
        expression: The text of the criterion.
        names: The metric names it reads, in order of appearance.
    """

    expression: str
    names: tuple[str, ...]

    def __call__(self, metrics: Mapping[str, Any]) -> bool:
        """Whether the metrics pass (False when a metric is missing, None or NaN)."""
        tree = ast.parse(self.expression, mode="eval")
        try:
            return bool(_evaluate(tree.body, metrics))
        except (ArithmeticError, TypeError, ValueError):
            return False


def parse_criterion(expression: str) -> Criterion:
    """Check a criterion and list the metric names it reads.

    Raises:
        CriterionError: Not a string, a syntax error, or a construct outside the allowed set
            (attribute of a call, subscripts, lambdas, unknown functions, strings, ...).
    """
    if not isinstance(expression, str) or not expression.strip():
        raise CriterionError(str(expression), "must be a non-empty string")
    expression = " ".join(expression.split())  # a criterion may span lines in TOML
    try:
        tree = ast.parse(expression, mode="eval")
    except SyntaxError as error:
        raise CriterionError(expression, f"syntax error: {error.msg}") from error
    names: list[str] = []
    _check(tree.body, expression, names)
    return Criterion(expression, tuple(dict.fromkeys(names)))


def _check(node: ast.AST, text: str, names: list[str]) -> None:
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or isinstance(node.value, int | float):
            return
        raise CriterionError(text, f"constant {node.value!r} is not a number")
    if isinstance(node, ast.Name | ast.Attribute):
        name = _dotted(node, text)
        if any(part.startswith("_") for part in name.split(".")):
            raise CriterionError(text, f"{name!r}: names starting with '_' are not metrics")
        if name not in _CONSTANTS:
            names.append(name)
        return
    if isinstance(node, ast.BoolOp):
        for value in node.values:
            _check(value, text, names)
        return
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not | ast.USub | ast.UAdd):
        _check(node.operand, text, names)
        return
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        _check(node.left, text, names)
        _check(node.right, text, names)
        return
    if isinstance(node, ast.Compare) and all(type(op) in _COMPARE for op in node.ops):
        for operand in (node.left, *node.comparators):
            _check(operand, text, names)
        return
    if (
        isinstance(node, ast.Call)
        and isinstance(node.func, ast.Name)
        and node.func.id in _FUNCTIONS
        and not node.keywords
    ):
        for argument in node.args:
            _check(argument, text, names)
        return
    raise CriterionError(
        text,
        f"{ast.unparse(node)!r} is not allowed (numbers, metric names, arithmetic, comparisons, "
        f"and/or/not and {', '.join(_FUNCTIONS)} only)",
    )


def _dotted(node: ast.AST, text: str) -> str:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return f"{_dotted(node.value, text)}.{node.attr}"
    raise CriterionError(text, f"{ast.unparse(node)!r} is not a metric name")


def _evaluate(node: ast.AST, metrics: Mapping[str, Any]) -> Any:
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name | ast.Attribute):
        name = _dotted(node, "")
        if name in _CONSTANTS:
            return _CONSTANTS[name]
        value = metrics.get(name)
        return math.nan if value is None else value
    if isinstance(node, ast.BoolOp):
        if isinstance(node.op, ast.And):
            return all(_truth(_evaluate(value, metrics)) for value in node.values)
        return any(_truth(_evaluate(value, metrics)) for value in node.values)
    if isinstance(node, ast.UnaryOp):
        operand = _evaluate(node.operand, metrics)
        if isinstance(node.op, ast.Not):
            return not _truth(operand)
        return -operand if isinstance(node.op, ast.USub) else +operand
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](_evaluate(node.left, metrics), _evaluate(node.right, metrics))
    if isinstance(node, ast.Compare):
        left = _evaluate(node.left, metrics)
        for op, comparator in zip(node.ops, node.comparators, strict=True):
            right = _evaluate(comparator, metrics)
            if not _COMPARE[type(op)](left, right):
                return False
            left = right
        return True
    assert isinstance(node, ast.Call) and isinstance(node.func, ast.Name)  # checked at parse
    return _FUNCTIONS[node.func.id](*(_evaluate(argument, metrics) for argument in node.args))


def _truth(value: Any) -> bool:
    """Truth of a metric: NaN (a missing figure) is false."""
    if isinstance(value, float) and math.isnan(value):
        return False
    return bool(value)
