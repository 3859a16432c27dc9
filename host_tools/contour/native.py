"""Loads the host build of the firmware core (build/host/libcontour.so).

The job-time estimator and the simulator call the same C code as the drive
through this one library; ``make`` (or ``make host``) builds it. Set
CONTOUR_LIB to use another build.
"""

from __future__ import annotations

import ctypes
import os
from functools import lru_cache
from pathlib import Path

from contour.errors import UserError

REPO_ROOT = Path(__file__).resolve().parents[2]


def library_path() -> Path:
    env = os.environ.get("CONTOUR_LIB")
    if env:
        return Path(env)
    return REPO_ROOT / "build" / "host" / "libcontour.so"


@lru_cache(maxsize=1)
def load() -> ctypes.CDLL:
    path = library_path()
    if not path.exists():
        raise UserError(f"{path} not found: run `make` to build the host library")
    return ctypes.CDLL(str(path))
