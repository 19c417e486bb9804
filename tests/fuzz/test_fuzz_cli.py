"""The command line's numeric options under garbage numbers: one ``error:`` line and exit code 2 before
any work starts, never a traceback; and the range check itself over every number."""
from __future__ import annotations

import math

import pytest
import typer
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from robointel.cli import app
from robointel.commands.option_checks import RANGES, check_number

runner = CliRunner()

#: (command words, option, int or float) -- each with a required argument filled in where needed
OPTIONS = [(["grasp", "trial"], "--n", int), (["grasp", "trial"], "--seed", int),
           (["skill", "insert"], "--time-limit", float), (["skill", "insert"], "--clearance", float),
           (["skill", "grind"], "--stall-ms", float), (["skill", "grind"], "--speed", float),
           (["teleop"], "--port", int), (["teleop"], "--duration", float),
           (["guide"], "--duration", float), (["keypoints"], "--tolerance", float),
           (["learn", "insertion"], "--trials", int), (["batch", "report", "x"], "--confidence", float),
           (["jog", "--joint", "1"], "--by", float), (["jog", "--joint", "1", "--by", "1"], "--speed", float),
           (["run", "moves"], "--seed", int)]


def _accepted(text: str, kind: type, option: str) -> bool:
    """Would a correct command take ``text`` for ``option``? (then the test would start real work)"""
    try:
        v = kind(text)
    except (ValueError, OverflowError):
        return False
    try:
        check_number(v, option, RANGES.get(option))
    except typer.BadParameter:
        return False
    return True


NUMBERS = st.one_of(st.integers(-(10 ** 20), 10 ** 20).map(str), st.floats().map(repr),
                    st.sampled_from(["nan", "-nan", "inf", "-inf", "1e400", "-1e400", "1e-400", "", " ", "0x10",
                                     "1,5", "--", "١٢", "٣.٥", "NaN", "Infinity", "9" * 30, "-0", "+-1"]),
                    st.text(max_size=6))


@settings(max_examples=30)
@given(case=st.sampled_from(OPTIONS), value=NUMBERS)
def test_garbage_numbers_are_one_line_refusals(case, value):
    words, option, kind = case
    assume(not _accepted(value, kind, option))
    r = runner.invoke(app, [*words, f"{option}={value}"])
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.strip()]
    assert r.exit_code == 2, (words, option, value, lines)
    assert len(lines) == 1 and lines[0].startswith("error: "), lines


@given(option=st.sampled_from(sorted(k for k in RANGES if isinstance(k, str))),
       value=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-(10 ** 12), 10 ** 12)))
def test_the_range_check_keeps_exactly_the_finite_numbers_in_range(option, value):
    rule = RANGES[option]
    try:
        assert check_number(value, option, rule) == value or math.isnan(value)
        ok = True
    except typer.BadParameter as exc:
        assert option in str(exc) or "must be" in str(exc)
        ok = False
    inside = math.isfinite(float(value)) and rule.contains(float(value))
    assert ok == inside


@pytest.mark.parametrize("args", [["grasp", "trial", "--n", "-1"], ["skill", "insert", "--time-limit", "nan"],
                                  ["skill", "grind", "--stall-ms", "-5"]])
def test_the_named_garbage_numbers(args):
    r = runner.invoke(app, args)
    lines = [ln for ln in (r.stdout + r.stderr).splitlines() if ln.strip()]
    assert r.exit_code == 2 and len(lines) == 1 and args[2] in lines[0], lines
