"""Several cameras by name, and frames from all of them at once (software-synchronised).

Fixed cameras in a cell look at a part that does not move, so their frames need no robot motion
between them; they are triggered together: one thread per camera, all released by one barrier,
each frame stamped with the monotonic time its grab started and ended. The *skew* is the spread
of the start times (how far apart the triggers were); it is recorded with the cycle. What this
does not do: hardware triggering or exposure timestamps from the cameras themselves (a software
trigger's skew is the scheduler's, typically well under a millisecond to a few milliseconds).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from controller.errors import CameraError, SeamguideError
from drivers.cameras import Camera


@dataclass(frozen=True)
class Frame:
    """One camera's frame of a synchronised capture, with its grab times (monotonic, s)."""

    camera: str
    image: NDArray[np.uint8]
    t_start_s: float
    t_end_s: float


class CameraSet(Mapping[str, Camera]):
    """The cell's cameras by name (a read-only mapping); :meth:`close` closes them all."""

    def __init__(self, cameras: Mapping[str, Camera]) -> None:
        self._cameras = dict(cameras)

    def __getitem__(self, name: str) -> Camera:
        return self._cameras[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._cameras)

    def __len__(self) -> int:
        return len(self._cameras)

    def close(self) -> None:
        """Close every camera (errors of one do not keep the others open)."""
        for cam in self._cameras.values():
            with contextlib.suppress(SeamguideError):
                cam.close()


def grab_together(cameras: Mapping[str, Camera], names: Sequence[str],
                  timeout_s: float) -> tuple[list[Frame], float]:
    """Trigger ``names`` at once; returns their frames (in ``names`` order) and the skew (s).

    Each camera grabs in its own thread; a barrier releases them together. Raises
    :class:`CameraError` naming the camera when a grab fails or does not finish within
    ``timeout_s`` (the thread is left to finish on its own; its frame is discarded).
    """
    missing = [n for n in names if n not in cameras]
    if missing:
        raise CameraError(f"no camera called {missing[0]!r} (cameras: {', '.join(cameras)})")
    barrier = threading.Barrier(len(names))
    results: dict[str, Frame | BaseException] = {}

    def worker(name: str) -> None:
        try:
            barrier.wait(timeout=timeout_s)
            t0 = time.monotonic()
            image = cameras[name].grab()
            results[name] = Frame(name, image, t0, time.monotonic())
        except BaseException as err:  # noqa: BLE001 - reported to the caller below
            results[name] = err

    threads = [threading.Thread(target=worker, args=(n,), name=f"grab-{n}", daemon=True)
               for n in names]
    deadline = time.monotonic() + timeout_s
    for t in threads:
        t.start()
    for t in threads:
        t.join(max(deadline - time.monotonic(), 0.0))
    frames = []
    for n in names:
        r = results.get(n)
        if r is None:
            raise CameraError(f"camera {n}: no frame within {timeout_s:.1f} s", camera=n)
        if isinstance(r, SeamguideError):
            raise CameraError(f"camera {n}: {r}", camera=n) from r
        if isinstance(r, BaseException):
            raise CameraError(f"camera {n}: grab failed: {type(r).__name__}: {r}",
                              camera=n) from r
        frames.append(r)
    starts = [f.t_start_s for f in frames]
    return frames, float(max(starts) - min(starts))
