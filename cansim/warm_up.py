"""Compiling kernels before a loop starts: a timed block that says so when it takes more than a second.

A model's ``warm_up()`` (:meth:`cansim.population.Population.warm_up`,
:meth:`cansim.models.whisker_ratslam.WhiskerRatSLAM.warm_up`) runs every compiled
kernel its configuration uses once, on scratch state, so that no compilation happens
inside the user's loop. With a warm cache this loads machine code from disk (numba's
cache, and :mod:`cansim.backends.kernel_cache` for generated kernels) in well under a
second; on a cold cache it compiles for up to a minute, once. :class:`WarmUp` times the
block and, when it runs longer than ``after_s``, logs one INFO line (and, with
``progress``, shows a tqdm line on stderr naming the stage being compiled).
"""

from __future__ import annotations

import logging
import sys
import threading
import time
from types import TracebackType
from typing import Any, Optional

__all__ = ["WarmUp"]

log = logging.getLogger(__name__)


class WarmUp:
    """Context manager timing a warm-up; ``stage(name)`` names the part being compiled.

    Parameters
    ----------
    what : str
        What is being warmed up (e.g. ``"WhiskerRatSLAM"``), for the messages.
    progress : bool
        Show a progress line on stderr (tqdm) once the block has run ``after_s``.
    after_s : float
        Seconds before anything is said (s).

    Attributes
    ----------
    elapsed_s : float
        Duration of the block (s), set on exit.
    """

    def __init__(self, what: str, *, progress: bool = False, after_s: float = 1.0) -> None:
        self.what = what
        self.progress = bool(progress)
        self.after_s = float(after_s)
        self.elapsed_s = 0.0
        self._stage = "starting"
        self._bar: Any = None
        self._lock = threading.Lock()
        self._timer: Optional[threading.Timer] = None
        self._start = 0.0
        self._announced = False

    def __enter__(self) -> "WarmUp":
        self._start = time.perf_counter()
        self._timer = threading.Timer(self.after_s, self._announce)
        self._timer.daemon = True
        self._timer.start()
        return self

    def _announce(self) -> None:
        with self._lock:
            if self._announced:
                return
            self._announced = True
            log.info("%s: compiling its kernels (%s); they are cached on disk, so this happens once", self.what, self._stage)
            if self.progress:
                from tqdm import tqdm

                self._bar = tqdm(desc=f"{self.what}: compiling kernels ({self._stage})", file=sys.stderr,
                                 bar_format="{desc} {elapsed}", leave=True)

    def stage(self, name: str) -> None:
        """Name the part being compiled now (shown on the progress line)."""
        with self._lock:
            self._stage = name
            if self._bar is not None:
                self._bar.set_description_str(f"{self.what}: compiling kernels ({name})")

    def __exit__(self, exc_type: Optional[type], exc: Optional[BaseException], tb: Optional[TracebackType]) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self.elapsed_s = time.perf_counter() - self._start
        with self._lock:
            self._announced = True  # a timer firing late says nothing
            if self._bar is not None:
                self._bar.set_description_str(f"{self.what}: kernels ready", refresh=False)  # close() draws it once
                self._bar.close()
                self._bar = None
        if self.elapsed_s > self.after_s:
            log.info("%s: kernels ready after %.1f s", self.what, self.elapsed_s)
