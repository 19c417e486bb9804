"""Offscreen rendering of a :class:`~robointel.sim.Workcell` to PNG with ``mujoco.Renderer``.

MuJoCo needs an offscreen OpenGL context: EGL (GPU or Mesa) or OSMesa (software). The backend is
chosen by the ``MUJOCO_GL`` environment variable before ``mujoco`` is imported; when it is unset
we try ``egl`` then ``osmesa`` in a subprocess probe and report clearly if neither works.
"""
from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from robointel.errors import InvalidInput, RobointelError


class Workcell(Protocol):
    """What rendering reads of a :class:`~robointel.sim.Workcell`: its MuJoCo model and data, its joints."""

    @property
    def model(self) -> Any:
        """The ``mujoco.MjModel``."""

    @property
    def data(self) -> Any:
        """The ``mujoco.MjData``."""

    @property
    def n(self) -> int:
        """Number of arm joints."""

    @property
    def qpos_index(self) -> Any:
        """(n,) indices of the arm's joints in ``qpos``."""

_PROBE = ("import mujoco, numpy as np\n"
          "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\".1\"/></worldbody></mujoco>')\n"
          "r = mujoco.Renderer(m, 8, 8); d = mujoco.MjData(m); mujoco.mj_forward(m, d)\n"
          "r.update_scene(d); r.render(); print('ok')\n")


@lru_cache(maxsize=1)
def available_backend() -> str | None:
    """The first offscreen backend that works here (``MUJOCO_GL`` if set, else egl / osmesa), or None."""
    cands = [os.environ["MUJOCO_GL"]] if os.environ.get("MUJOCO_GL") else ["egl", "osmesa"]
    for b in cands:
        try:
            r = subprocess.run([sys.executable, "-c", _PROBE], env={**os.environ, "MUJOCO_GL": b},
                               capture_output=True, text=True, timeout=60)
        except (OSError, subprocess.TimeoutExpired):
            continue
        if r.returncode == 0 and "ok" in r.stdout:
            return b
    return None


_SUBPROCESS = """
import sys, numpy as np, mujoco
model = mujoco.MjModel.from_binary_path(sys.argv[1])
st = np.load(sys.argv[2])
d = mujoco.MjData(model)
cam = mujoco.MjvCamera(); cam.lookat[:] = st["lookat"]
cam.distance, cam.azimuth, cam.elevation = (float(x) for x in st["view"])
imgs = []
with mujoco.Renderer(model, int(st["size"][0]), int(st["size"][1])) as r:
    for qpos in st["qpos"]:
        d.qpos[:] = qpos; d.mocap_pos[:] = st["mocap_pos"]; d.mocap_quat[:] = st["mocap_quat"]
        mujoco.mj_forward(model, d)
        r.update_scene(d, camera=cam)
        imgs.append(r.render().copy())
np.save(sys.argv[3], np.array(imgs))
"""


def render(workcell: Workcell, path: str | Path | None = None, *, width: int = 640, height: int = 480,
           camera: dict | None = None) -> np.ndarray:
    """Render ``workcell`` as it is now to an (h, w, 3) uint8 image; write a PNG when ``path``.

    ``camera``: dict with ``lookat`` (3,), ``distance`` (m), ``azimuth``, ``elevation`` (deg).
    In-process when ``MUJOCO_GL`` was set to a working backend before ``mujoco`` was imported;
    otherwise in a subprocess with the working backend (about a second per call).

    Raises:
        RobointelError: no offscreen OpenGL backend (EGL or OSMesa) works on this machine.
    """
    return render_frames(workcell, np.array([workcell.data.qpos]), path, width=width, height=height,
                         camera=camera, columns=1)


def render_frames(workcell: Workcell, qpos: Sequence[npt.ArrayLike] | np.ndarray, path: str | Path | None = None, *,
                  width: int = 480, height: int = 360, camera: dict | None = None,
                  columns: int | None = None) -> np.ndarray:
    """Render several states of ``workcell`` into one montage image.

    Render several states of ``workcell`` (full MuJoCo ``qpos`` vectors, or robot joint vectors (n,) with everything
    else as it is now) into one montage image, ``columns`` per row (default all in one row); write a PNG when
    ``path``. Obstacles are drawn where they are now.

    Returns:
        (rows * height, columns * width, 3) uint8 image.

    Raises:
        RobointelError: no offscreen OpenGL backend works on this machine.
        InvalidInput: a state of the wrong size.
    """
    import mujoco

    backend = available_backend()
    if backend is None:
        raise RobointelError("offscreen rendering is unavailable: neither MUJOCO_GL=egl nor MUJOCO_GL=osmesa "
                             "works here (install libegl1/libosmesa6 or run with a display)")
    d = workcell.data
    full = []
    for x in qpos:
        x = np.asarray(x, dtype=float)
        if x.shape == (workcell.model.nq,):
            full.append(x)
        elif x.shape == (workcell.n,):
            y = d.qpos.copy()
            y[workcell.qpos_index] = x
            full.append(y)
        else:
            raise InvalidInput(f"each state must be (nq,) = ({workcell.model.nq},) or (n,) = ({workcell.n},), "
                               f"got {x.shape}", value=x)
    if not full:
        raise InvalidInput("no states to render")
    c = {"lookat": (0.35, 0.0, 0.35), "distance": 2.2, "azimuth": 135.0, "elevation": -25.0, **(camera or {})}
    if os.environ.get("MUJOCO_GL") == backend:
        cam = mujoco.MjvCamera()
        cam.lookat[:] = c["lookat"]
        cam.distance, cam.azimuth, cam.elevation = c["distance"], c["azimuth"], c["elevation"]
        dd = mujoco.MjData(workcell.model)
        imgs = []
        try:
            with mujoco.Renderer(workcell.model, height, width) as r:
                for x in full:
                    dd.qpos[:] = x
                    dd.mocap_pos[:], dd.mocap_quat[:] = d.mocap_pos, d.mocap_quat
                    mujoco.mj_forward(workcell.model, dd)
                    r.update_scene(dd, camera=cam)
                    imgs.append(r.render().copy())
        except Exception as exc:
            raise RobointelError(f"offscreen rendering failed with MUJOCO_GL={backend}: {exc}") from None
        frames = np.array(imgs)
    else:
        frames = _render_subprocess(workcell, np.array(full), backend, width, height, c)
    cols = len(frames) if columns is None else max(1, int(columns))
    rows = -(-len(frames) // cols)
    canvas = np.full((rows * height, cols * width, 3), 255, dtype=np.uint8)
    for k, img in enumerate(frames):
        r_, c_ = divmod(k, cols)
        canvas[r_ * height:(r_ + 1) * height, c_ * width:(c_ + 1) * width] = img
    if path is not None:
        import matplotlib.image as mpimg

        Path(path).parent.mkdir(parents=True, exist_ok=True)
        mpimg.imsave(str(path), canvas)
    return canvas


def _render_subprocess(workcell: Workcell, qpos: np.ndarray, backend: str, width: int, height: int,
                       c: dict) -> np.ndarray:
    import tempfile

    import mujoco

    d = workcell.data
    with tempfile.TemporaryDirectory() as tmp:
        mjb, st, out = (str(Path(tmp) / n) for n in ("m.mjb", "s.npz", "img.npy"))
        mujoco.mj_saveModel(workcell.model, mjb, None)
        np.savez(st, qpos=qpos, mocap_pos=d.mocap_pos, mocap_quat=d.mocap_quat, lookat=np.asarray(c["lookat"]),
                 view=np.array([c["distance"], c["azimuth"], c["elevation"]]), size=np.array([height, width]))
        r = subprocess.run([sys.executable, "-c", _SUBPROCESS, mjb, st, out],
                           env={**os.environ, "MUJOCO_GL": backend}, capture_output=True, text=True, timeout=300)
        if r.returncode != 0:
            raise RobointelError(f"offscreen rendering failed with MUJOCO_GL={backend}: {r.stderr.strip()[-400:]}")
        return np.load(out)
