"""What every dialect's blocks share: comments, operation names from the post's comments, and
the arithmetic of parameter expressions (Fanuc / LinuxCNC ``#`` variables in ``[...]``, Siemens
R parameters and ``DEF`` variables, Heidenhain Q parameters), evaluated only where they hold
values (no control flow: a loop or a branch is named by the reader, not executed)."""

from __future__ import annotations

import ast
import math
import operator
import re

from camsmooth.post.core import Skip

__all__ = ["split_comments", "operation_name", "evaluate", "tool_comment"]

_PAREN = re.compile(r"\(([^()]*)\)")


def split_comments(line: str, semicolon: bool = True, paren: bool = True) -> tuple[str, list[str]]:
    """(code, comments) of one line: ``( ... )`` comments anywhere (``paren``) and a ``;`` comment
    to the end of the line (``semicolon``)."""
    comments: list[str] = []
    code = line
    if semicolon and ";" in code:
        if paren:
            # a ';' inside a '( ... )' comment is part of that comment
            depth, cut = 0, -1
            for i, ch in enumerate(code):
                if ch == "(":
                    depth += 1
                elif ch == ")":
                    depth = max(0, depth - 1)
                elif ch == ";" and depth == 0:
                    cut = i
                    break
            if cut >= 0:
                comments.append(code[cut + 1:])
                code = code[:cut]
        else:
            code, _, rest = code.partition(";")
            comments.append(rest)
    if paren and "(" in code:
        found = _PAREN.findall(code)
        comments = found + comments
        code = _PAREN.sub(" ", code)
    return code, comments


_EXPLICIT = [
    re.compile(r"^\s*operation\s*name\s*[:=]\s*(.+?)\s*$", re.I),
    re.compile(r"^\s*operation\s*[:=]\s*(.+?)\s*$", re.I),
    re.compile(r"^\s*path\s*:\s*(.+?)\s*$", re.I),
    re.compile(r"^\s*-*\s*(operation\s+\S.*?)\s*-*\s*$", re.I),
    re.compile(r"^\s*\((.+?)\)\s*$"),  # ';(NAME)' (NX Sinumerik posts)
    re.compile(r"^\s*-\s+(?:JOB:\s*)?([^-\s].*?)\s*$"),  # Heidenhain '* - NAME' (not '* --- rule ---')
]


def operation_name(comment: str, star: bool = False) -> str | None:
    """The operation name a comment gives explicitly ("Operation Name: X", "OPERATION= X",
    "Path : X", "--- Operation 1", ";(X)"; with ``star`` a Heidenhain ``* - X`` section), else
    None. Whitespace runs become one space; the name is never truncated."""
    pats = _EXPLICIT if star else _EXPLICIT[:5]
    for p in pats:
        m = p.match(comment)
        if m:
            name = " ".join(m.group(1).split())
            return name or None
    return None


_TOOLISH = re.compile(r"^\s*(T\d+\b|TOOL\b|TOOLS\b|D\s*=|DIA|TL\b|T\s*=)", re.I)


def tool_comment(comment: str) -> bool:
    """A comment that describes a tool (not an operation name)."""
    return bool(_TOOLISH.match(comment))


_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
        ast.Mod: operator.mod, ast.Pow: operator.pow}
_FUNCS = {"SIN": lambda x: math.sin(math.radians(x)), "COS": lambda x: math.cos(math.radians(x)),
          "TAN": lambda x: math.tan(math.radians(x)), "ASIN": lambda x: math.degrees(math.asin(x)),
          "ACOS": lambda x: math.degrees(math.acos(x)), "ATAN": lambda x: math.degrees(math.atan(x)),
          "SQRT": math.sqrt, "SQR": math.sqrt, "ABS": abs, "ROUND": round, "FIX": math.floor, "FUP": math.ceil,
          "TRUNC": math.trunc, "EXP": math.exp, "LN": math.log, "POT": lambda x: x * x}


def evaluate(expr: str, lookup: dict[str, float]) -> float:
    """The value of an arithmetic expression of numbers, variables already replaced by the caller's
    names in ``lookup`` (``v_...`` identifiers), + - * / MOD, ``[ ]`` or ``( )`` and the
    functions of _FUNCS (degrees). Skip naming what is not arithmetic (a comparison, an unknown
    variable or function)."""
    text = expr.replace("[", "(").replace("]", ")")
    text = re.sub(r"\bMOD\b", "%", text, flags=re.I)
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError):
        raise Skip(f"expression {expr.strip()!r} is not arithmetic") from None

    def ev(node: ast.AST) -> float:
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            return float(node.value)
        if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
            return float(_OPS[type(node.op)](ev(node.left), ev(node.right)))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            v = ev(node.operand)
            return -v if isinstance(node.op, ast.USub) else v
        if isinstance(node, ast.Name):
            if node.id in lookup:
                return float(lookup[node.id])
            raise Skip(f"variable {node.id.removeprefix('v_')} has no value here")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id.upper() in _FUNCS \
                and len(node.args) == 1:
            return float(_FUNCS[node.func.id.upper()](ev(node.args[0])))
        raise Skip(f"expression {expr.strip()!r} is not arithmetic")

    try:
        value = ev(tree)
    except (ZeroDivisionError, OverflowError, ValueError):
        raise Skip(f"expression {expr.strip()!r} has no value (division by zero or out of range)") from None
    if not math.isfinite(value):
        raise Skip(f"expression {expr.strip()!r} has no finite value")
    return value
