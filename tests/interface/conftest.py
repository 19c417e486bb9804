import dataclasses

import pytest


@pytest.fixture(scope="session")
def frmp_segment():
    """The first segment of the FRMP on the built-in table71 scene (CFS + temporal optimization)."""
    from robointel.planning import plan_scene
    from robointel.planning.scene import load_scene

    s = load_scene("table71")
    short = dataclasses.replace(s, waypoints=s.waypoints[:2], steps=s.steps[:1], waypoint_names=s.waypoint_names[:2])
    return plan_scene(short).trajectory
