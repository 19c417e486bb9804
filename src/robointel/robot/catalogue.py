"""The robots known by name: the built-in descriptions and the arms of ``example-robot-data``.

:func:`find_urdf` turns what a user gives :meth:`robointel.robot.Robot.load` (a built-in name, an
``example-robot-data`` arm or a URDF path) into the URDF file, the robot's short name and the flange
frame its maker names.
"""
from __future__ import annotations

import sys
from pathlib import Path

from robointel._extras import missing_extra
from robointel.errors import UnknownRobot

DESCRIPTIONS = Path(__file__).resolve().parent / "descriptions"
"""The folder of the built-in URDF descriptions."""
BUILTIN = {
    "lrmate200id7l": DESCRIPTIONS / "lrmate200id7l.urdf",
    "scara2": DESCRIPTIONS / "scara2.urdf",
}
"""Built-in name -> its URDF file."""
_EXAMPLES = {"ur5": "ur_description/urdf/ur5_robot.urdf", "panda": "panda_description/urdf/panda.urdf"}
#: the frame the TCP is reported at, for an ``example-robot-data`` arm loaded by name
_EXAMPLE_FLANGES = {"ur5": "tool0", "panda": "panda_hand"}


def builtin_names() -> list[str]:
    """Names accepted by :meth:`~robointel.robot.Robot.load` besides URDF paths."""
    return sorted(BUILTIN)


def example_robot_data_dir() -> Path | None:
    """The ``robots`` folder of the installed ``example-robot-data`` (None when it is not installed)."""
    for base in [Path(sys.prefix)] + [Path(p) for p in sys.path]:
        d = base / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if d.is_dir():
            return d
    return None


def example_robot_urdf(name: str) -> Path:
    """Path of a URDF shipped by ``example-robot-data``: ``"ur5"``, ``"panda"``, or a path below its ``robots`` folder.

    Raises:
        MissingExtra: example-robot-data is not installed (the ``robots`` extra).
        UnknownRobot: it has no such file.
    """
    d = example_robot_data_dir()
    if d is None:
        raise missing_extra("robots", f"the example-robot-data robot {name!r}", "example-robot-data")
    rel = _EXAMPLES.get(name, name)
    if not (d / rel).is_file():
        raise UnknownRobot(f"example-robot-data has no robot {name!r}: name one of {sorted(_EXAMPLES)} or a URDF path "
                           f"below {d}", value=name)
    return d / rel


def find_urdf(name_or_path: str | Path) -> tuple[Path, str, str | None]:
    """The URDF file a built-in name, an ``example-robot-data`` arm name or a path stands for.

    Args:
        name_or_path: ``"lrmate200id7l"``, ``"scara2"``, ``"ur5"``, ``"panda"`` or a URDF file path.

    Returns:
        (path, name, flange): the URDF file, the robot's short name (the file's stem for a path) and
        the frame its maker names the flange (None: the model decides).

    Raises:
        UnknownRobot: the name is not known and no such file exists.
        MissingExtra: an ``example-robot-data`` arm while that package is not installed.
    """
    key = str(name_or_path)
    if key in BUILTIN:
        return BUILTIN[key], key, None
    if key in _EXAMPLES:
        return example_robot_urdf(key), key, _EXAMPLE_FLANGES[key]
    path = Path(key).expanduser()
    if not path.exists():
        raise UnknownRobot(
            f"unknown robot {key!r}: not a built-in name ({', '.join(builtin_names() + list(_EXAMPLES))}) "
            "and no URDF file at that path", value=key)
    return path, path.stem, None
