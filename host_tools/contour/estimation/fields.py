"""Description of one documented setting (profile field or model option)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Field:
    """A setting: name (ending in its unit), default, meaning, how to measure.

    Numbers must lie strictly between ``low`` and ``high`` (or be 0 when
    ``zero_ok``); ``choices``
    lists the allowed strings of a choice; booleans are true/false.
    """

    name: str
    unit: str
    default: Any
    doc: str
    measure: str
    choices: tuple = ()
    low: float = 0.0
    high: float = math.inf
    zero_ok: bool = False  # 0 is allowed (means "off")
