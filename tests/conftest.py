"""Shared fixtures. Reference data is read from ../shared/data through ``shared_data``: a missing
file skips the test, or fails it when ROBOINTEL_REQUIRE_DATA=1 (CI)."""
from __future__ import annotations

import os

import pytest

from robointel.errors import DataMissing
from robointel.io.reference import data_path


def _shared_data(*parts: str):
    try:
        return data_path(*parts)
    except DataMissing as exc:
        if os.environ.get("ROBOINTEL_REQUIRE_DATA") == "1":
            pytest.fail(f"required reference data missing: {exc}")
        pytest.skip(f"reference data missing: {exc}")


@pytest.fixture
def shared_data():
    """Call ``shared_data("kinect", "joints.csv")`` to get a Path (skip/fail when missing)."""
    return _shared_data


@pytest.fixture(scope="session")
def lrmate():
    from robointel.robot import Robot

    return Robot.load("lrmate200id7l")
