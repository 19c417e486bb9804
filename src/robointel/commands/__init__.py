"""CLI commands and demo stages of each phase, loaded by :mod:`robointel.cli`.

A module here defines ``register(app)`` to add typer commands and optionally
``demo_stage(ctx) -> robointel.report.demo.StageResult`` for ``robointel demo``.
"""
