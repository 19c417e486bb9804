"""Fixtures for the dataset tests: small episodes."""
from __future__ import annotations

import numpy as np
import pytest

from robointel.io.episode import Episode


def wave(n: int, seed: int, *, task: str = "wave", hz: float = 50.0) -> Episode:
    rng = np.random.default_rng(seed)
    t = 3.0 + np.arange(n) / hz
    q = np.stack([np.sin(2 * np.pi * 0.4 * t + rng.uniform(0, 3)), 0.5 * np.cos(2 * np.pi * 0.3 * t)], axis=1)
    labels = (t > t[n // 2]).astype(np.int64)
    return Episode.create(t, {"state": q, "velocity": np.gradient(q, t, axis=0), "label": labels},
                          q + rng.normal(0, 0.01, q.shape), names={"state": ("j1", "j2"), "action": ("j1", "j2")},
                          task=task, kind="test", name=f"wave {seed}", meta={"seed": seed, "units": {"t": "s"}})


@pytest.fixture
def make_wave():
    """``make_wave(n, seed, task=..., hz=...)``: a 2-joint episode with an int label observation."""
    return wave
