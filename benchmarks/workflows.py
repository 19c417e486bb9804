"""The operator's workflows measured at size (the jog's part).

    python benchmarks/workflows.py --json

``jog_dropped``: targets the streaming server dropped in a 500-target jog (``robointel jog`` through
``robointel teleop``'s streaming interface) on a host with two busy loops beside them
(:mod:`benchmarks._jog`, with the jog's other figures).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Any

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from _jog import jog_dropped  # noqa: E402


def measure_jog() -> dict[str, Any]:
    """The jog figures (``jog_dropped`` and its companions)."""
    return jog_dropped()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    out: dict[str, Any] = {}
    out.update(measure_jog())
    if args.json:
        print(json.dumps(out))
    else:
        for k, v in out.items():
            print(f"{k:28s} {v}")


if __name__ == "__main__":
    main()
