"""Scene files: read and write the YAML document of a planning scene as plain data.

The scene type, its validation and the built-in scenes live in :mod:`robointel.planning.scene`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from robointel.errors import InvalidInput

__all__ = ["read_scene_file", "write_scene_file"]


def read_scene_file(path: str | Path) -> Any:
    """Parse a scene YAML file.

    Args:
        path: The ``.yaml`` file.

    Returns:
        The parsed document (a mapping for a valid scene; checked by the planning phase).

    Raises:
        InvalidInput: the file does not exist or is not valid YAML.
    """
    p = Path(path)
    if not p.is_file():
        raise InvalidInput(f"scene file {p} does not exist", value=str(p))
    try:
        return yaml.safe_load(p.read_text())
    except yaml.YAMLError as exc:
        raise InvalidInput(f"{p}: not valid YAML: {' '.join(str(exc).split())}", value=str(p)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInput(f"cannot read scene {p}: {exc}", value=str(p)) from None


def write_scene_file(data: dict[str, Any], path: str | Path) -> Path:
    """Write a scene document as YAML (keys in the given order).

    Args:
        data: Plain data (lists, numbers, strings, mappings).
        path: Target file.

    Returns:
        The path written.
    """
    p = Path(path)
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p

