"""How every ``robointel`` command reports bad arguments and bad files: one line, exit code 2."""
from __future__ import annotations

from typing import NoReturn

import typer


def error_line(problem: BaseException | str) -> str:
    """The message of ``problem`` on one line (newlines and runs of spaces folded)."""
    text = str(problem) if not isinstance(problem, BaseException) else (str(problem) or type(problem).__name__)
    return "error: " + " ".join(text.split())


def fail(problem: BaseException | str) -> NoReturn:
    """Print ``error: <message>`` as one line on stderr and exit with code 2.

    Args:
        problem: a :class:`robointel.errors.RobointelError` (or any exception) or a message.

    Raises:
        typer.Exit: always, with code 2.
    """
    typer.echo(error_line(problem), err=True)
    raise typer.Exit(2)
