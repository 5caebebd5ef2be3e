"""What the mutation run of camsmooth/post/words.py (benchmarks/mutation.py, target "post-words")
showed the reader tests leave open: the comment splitting, operation and tool comments and the
parameter arithmetic, each checked directly against values worked by hand (the functions in
degrees, as the controllers' manuals define SIN / ATAN / FIX / FUP ...)."""

from __future__ import annotations

import pytest

from camsmooth.post.core import Skip
from camsmooth.post.words import evaluate, operation_name, split_comments, tool_comment


# ---- comments ------------------------------------------------------------------------------------------
def test_a_semicolon_inside_parentheses_belongs_to_that_comment():
    """'G1 X1 (a;b) ; tail': the ';' at depth 0 starts the line comment, the one inside '(a;b)' does
    not; the parenthesised comment comes first, its text replaced by a blank."""
    code, comments = split_comments("G1 X1 (a;b) ; tail")
    assert comments == ["a;b", " tail"]
    assert code.split() == ["G1", "X1"]
    assert code == "G1 X1   "


def test_a_closed_comment_does_not_hide_the_semicolon_after_it():
    """After '(a)' the depth is back to 0, and a stray ')' does not make it negative: the ';'
    after either is the line comment."""
    assert split_comments("X1 (a) Y2 ; c") == ("X1   Y2 ", ["a", " c"])
    assert split_comments("X1 ) Y2 ; c") == ("X1 ) Y2 ", [" c"])
    assert split_comments("X1 (a (b) ; c") == ("X1 (a (b) ; c".replace("(b)", " "), ["b"])


def test_without_parentheses_the_semicolon_cuts_at_the_first_one():
    """paren=False (Heidenhain ';' comments): the line is cut at its first ';' whatever the
    brackets, and '( ... )' stay in the code."""
    assert split_comments("L X+1 (a;b) ; c", paren=False) == ("L X+1 (a", ["b) ; c"])
    assert split_comments("L X+1 (a)", paren=False) == ("L X+1 (a)", [])


def test_without_semicolon_comments_only_parentheses_are_comments():
    assert split_comments("X1 ; not a comment (c)", semicolon=False) == ("X1 ; not a comment  ", ["c"])
    assert split_comments("X1 (c1) Y2 (c2)") == ("X1   Y2  ", ["c1", "c2"])
    assert split_comments("X1 Y2") == ("X1 Y2", [])


# ---- operation and tool comments -------------------------------------------------------------------------
@pytest.mark.parametrize("comment, name", [
    ("Operation Name: Rough   pocket ", "Rough pocket"),
    ("operation name = Finish", "Finish"),
    ("OPERATION= Drill 6", "Drill 6"),
    ("OPERATION : Face", "Face"),
    ("Path : Contour 2", "Contour 2"),
    ("--- Operation 1 ---", "Operation 1"),
    ("  operation  Adaptive clearing", "operation Adaptive clearing"),
    ("(SPIRAL_FINISH)", "SPIRAL_FINISH"),
    ("T1 D=10", None),
    ("just a remark", None),
    ("- Contour", None),          # the Heidenhain section form only with star
])
def test_operation_names_from_comments(comment, name):
    assert operation_name(comment) == name


@pytest.mark.parametrize("comment, name", [
    ("- Contour", "Contour"),
    ("  -   JOB: FACE  MILL", "FACE MILL"),
    ("--- rule ---", None),
    ("Operation Name: X", "X"),
])
def test_heidenhain_star_sections(comment, name):
    assert operation_name(comment, star=True) == name


@pytest.mark.parametrize("comment, toolish", [
    ("T1 D=10 CR=0", True), ("t12", True), ("TOOL 3 BALL 6", True), ("Tools used", True), ("D = 6", True),
    ("DIA 10", True), ("TL 5", True), ("T = 4", True), ("T1A", False), ("Operation 1", False),
    ("Toolpath finish", False), ("  T3", True),
])
def test_tool_comments(comment, toolish):
    assert tool_comment(comment) is toolish


# ---- arithmetic --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("expr, value", [
    ("[1+2]*3", 9.0), ("10/4", 2.5), ("1-2.5", -1.5), ("7 MOD 3", 1.0), ("7 mod 3", 1.0), ("2**3", 8.0),
    ("-[2]", -2.0), ("+[2]", 2.0), ("- -3", 3.0),
    ("SIN[30]", 0.5), ("COS[60]", 0.5), ("TAN[45]", 1.0), ("ASIN[0.5]", 30.0), ("ACOS[0.5]", 60.0),
    ("ATAN[1]", 45.0), ("SQRT[16]", 4.0), ("SQR[9]", 3.0), ("ABS[-2]", 2.0), ("ROUND[2.6]", 3.0),
    ("FIX[2.7]", 2.0), ("FIX[-2.5]", -3.0), ("FUP[2.1]", 3.0), ("FUP[-2.1]", -2.0), ("TRUNC[-2.7]", -2.0),
    ("EXP[0]", 1.0), ("LN[1]", 0.0), ("POT[3]", 9.0), ("sin(90)", 1.0), ("2*(3+4)", 14.0),
])
def test_arithmetic_worked_by_hand(expr, value):
    assert evaluate(expr, {}) == pytest.approx(value, abs=1e-12)


def test_variables_come_from_the_lookup():
    """'-v_1 + v_2 * 2' with #1 = 5, #2 = 1.5: -5 + 3 = -2; an unknown variable is named without
    the 'v_' prefix the callers add."""
    assert evaluate("-v_1 + v_2 * 2", {"v_1": 5.0, "v_2": 1.5}) == pytest.approx(-2.0)
    with pytest.raises(Skip, match=r"^variable 7 has no value here$"):
        evaluate("v_7 + 1", {"v_1": 5.0})


@pytest.mark.parametrize("expr, why", [
    ("1 < 2", "is not arithmetic"), ("FOO[1]", "is not arithmetic"), ("SIN(1, 2)", "is not arithmetic"),
    ("'a'", "is not arithmetic"), ("1 +", "is not arithmetic"), ("x.y", "is not arithmetic"),
    ("1/0", "has no value"), ("7 MOD 0", "has no value"), ("ACOS[2]", "has no value"), ("EXP[1000]", "has no value"),
    ("1e308*10", "has no finite value"),
])
def test_what_is_not_arithmetic_is_skipped_with_its_reason(expr, why):
    with pytest.raises(Skip) as exc:
        evaluate(expr, {})
    assert why in exc.value.reason
    assert repr(expr) in exc.value.reason
