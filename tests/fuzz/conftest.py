"""Property-based tests (hypothesis) over what robointel reads from outside: a bounded, seeded budget.

Each test runs a fixed number of examples from a fixed seed (``derandomize``), no example database
is written, and no example may take longer than the deadline: the whole directory stays within a
few tens of seconds of the suite.
"""
from __future__ import annotations

import json
import math

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

settings.register_profile("robointel", max_examples=60, deadline=2000, derandomize=True, database=None,
                          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                                 HealthCheck.data_too_large])
settings.load_profile("robointel")

#: scalars a file or a message may hold where a number was expected: huge, tiny, NaN, inf, text, null
SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(10 ** 30), max_value=10 ** 30),
    st.sampled_from([10 ** 400, -(10 ** 400), 0, -1, 1, 2 ** 63, 2 ** 64]),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=12),
    st.sampled_from(["nan", "inf", "-1", "1e400", "0x10", "", "🤖", "\x00"]),
)
#: any JSON-like value (nested lists and mappings of the scalars)
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=7),
                                                        st.dictionaries(st.text(max_size=8), inner, max_size=5)),
                      max_leaves=20)


def paths(d, prefix=()):
    """Every (path, value) in a nested structure of dicts and lists."""
    yield prefix, d
    if isinstance(d, dict):
        for k, v in d.items():
            yield from paths(v, (*prefix, k))
    elif isinstance(d, list):
        for i, v in enumerate(d):
            yield from paths(v, (*prefix, i))


@st.composite
def mutated(draw, base):
    """``base`` (a JSON-like document) with 1-3 values replaced, keys dropped or added at random places."""
    doc = json.loads(json.dumps(base, default=str))
    for _ in range(draw(st.integers(1, 3))):
        spots = list(paths(doc))
        path, _ = spots[draw(st.integers(0, len(spots) - 1))]
        action = draw(st.sampled_from(["replace", "drop", "add"]))
        if not path:
            if action == "replace":
                doc = draw(VALUES)
            continue
        parent = doc
        for p in path[:-1]:
            parent = parent[p]
        key = path[-1]
        if action == "replace":
            parent[key] = draw(VALUES)
        elif action == "drop":
            del parent[key]
        elif isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=8))] = draw(VALUES)
        else:
            parent.insert(key, draw(VALUES))
    return doc


def finite(x) -> bool:
    """A real number that a float holds (no bool, NaN, inf, 10**400)."""
    if isinstance(x, bool) or not isinstance(x, int | float):
        return False
    try:
        return math.isfinite(float(x))
    except OverflowError:
        return False
