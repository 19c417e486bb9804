"""MkDocs hook: the reference of every ``robointel`` command, generated from the command itself.

A page holding the marker below gets, in its place, what typer's own documentation generator
(``typer robointel.cli utils docs``) writes for the app: each command's help, usage, arguments and
options with their defaults, so the page cannot drift from the code.
"""
from __future__ import annotations

from typing import Any

import typer
from typer.cli import get_docs_for_click

from robointel.cli import app

MARKER = "<!-- robointel-cli-reference -->"


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    """Replace the marker with the generated reference (headings one level below the page title)."""
    if MARKER not in markdown:
        return markdown
    command = typer.main.get_command(app)
    ctx = typer.Context(command)
    reference = get_docs_for_click(obj=command, ctx=ctx, name="robointel", indent=1, title="Reference")
    return markdown.replace(MARKER, _escape_brackets(reference))


def _escape_brackets(text: str) -> str:
    """Escape ``[`` outside code: help texts such as ``fanuc://HOST[:RMI_PORT]`` are not Markdown links."""
    out, fenced = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced:
            parts = line.split("`")
            line = "`".join(p.replace("[", "\\[") if i % 2 == 0 else p for i, p in enumerate(parts))
        out.append(line)
    return "\n".join(out) + "\n"
