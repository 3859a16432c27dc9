"""Assemble cyclic messages (status, progress, path, pos_n, ferr_n) into one
record per cycle, keyed by the 16-bit cycle sequence number, and count gaps.

A cycle starts with its ``status`` message; every later message of the same
cycle carries the same ``seq``. :meth:`Assembler.add` returns the previous
cycle when a new one starts (:meth:`flush` returns the last). ``gaps`` counts
missing cycle numbers (wrap-around at 65536 handled).
"""

from __future__ import annotations

from typing import Optional

from contour.link.codec import Decoded

CYCLE_PARTS = ("status", "progress", "path")


class Assembler:
    def __init__(self, axes: int) -> None:
        self.axes = axes
        self.cur: Optional[dict] = None
        self.last_seq: Optional[int] = None
        self.gaps = 0
        self.cycles = 0
        self.stray = 0  # parts whose cycle already ended or never started

    def add(self, ts: float, m: Decoded) -> Optional[dict]:
        f = m.fields
        if "seq" not in f:
            return None
        seq = f["seq"]
        if m.name == "status":
            done = self.cur
            if self.last_seq is not None:
                step = (seq - self.last_seq) & 0xFFFF
                if step == 0:
                    self.stray += 1
                    return None
                self.gaps += step - 1
            self.last_seq = seq
            self.cycles += 1
            self.cur = {
                "seq": seq,
                "time": ts,
                "state": f["state"],
                "enabled": f["enabled"],
                "faults": f["faults"],
                "free_slots": f["free_slots"],
            }
            return done
        if self.cur is None or seq != self.cur["seq"]:
            self.stray += 1
            return None
        if m.name == "progress":
            self.cur["queued_us"] = f["queued_us"]
            self.cur["blocks_done"] = f["blocks_done"]
        elif m.name == "path":
            self.cur["contour_err_nm"] = f["contour_err"]
            self.cur["feed_mm_min"] = f["feed"]
        elif m.name.startswith("pos_"):
            self.cur[f"pos{m.name[4:]}_nm"] = f["pos"]
        elif m.name.startswith("ferr_"):
            k = m.name[5:]
            self.cur[f"ferr{k}_nm"] = f["ferr"]
            self.cur[f"cmd{k}_mv"] = f["cmd"] * 10
        return None

    def flush(self) -> Optional[dict]:
        done, self.cur = self.cur, None
        return done

    def columns(self) -> list[str]:
        cols = ["seq", "time", "state", "enabled", "faults", "free_slots"]
        cols += ["queued_us", "blocks_done", "contour_err_nm", "feed_mm_min"]
        for i in range(self.axes):
            cols += [f"pos{i}_nm", f"ferr{i}_nm", f"cmd{i}_mv"]
        return cols
