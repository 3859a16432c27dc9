"""CSP with SYNC on a bus of simulated drives, in simulated time: the
figures `canopen_csp_sync_hz` and `canopen_drive_skew_us` (docs/canopen.md,
"Figures"; `bash bench/bench-canopen.sh`).

A master written here (no python-can: frames go straight onto the
simulated bus of `sim serve`, contour.sim.serve.SimBus, at 1 Mbit/s with
every frame's exact bits) starts two drives (NMT), sets CSP (0x6060 = 8)
and the interpolation period (0x60C2) by SDO, enables them through 0x6040,
then every cycle sends each drive its RPDO2 (controlword, target position:
a ramp of 1 mm/s) followed by a SYNC. The drives (the firmware core, in
lockstep, one tick at a time) answer with their TPDO2 (statusword,
position actual).

A cycle is missed when, before the next SYNC is due, the bus has not
carried everything (RPDOs, SYNC, both TPDO2s), a drive did not sample the
SYNC exactly once, sent other than one TPDO2, or refused the target
(co_drive_csp_missed). canopen_csp_sync_hz is the highest rate of
RATES_HZ (divisors of the 10 kHz tick) at which CYCLES cycles run without a
miss. canopen_drive_skew_us is the largest difference, over every SYNC of
that run, between the times of the ticks whose positions the two drives
sampled for it (co_drive_sync_tick).
"""

from __future__ import annotations

import struct

from contour.sim.serve import SimBus, SimServer

RATES_HZ = (500, 1000, 1250, 2000, 2500)
CYCLES = 400
RAMP_NM_S = 1_000_000


def _sdo(bus: SimBus, node: int, index: int, sub: int, value: int, size: int) -> None:
    cmd = 0x23 | ((4 - size) << 2)
    bus.send(SimBus.HOST, 0x600 + node, struct.pack("<BHBI", cmd, index, sub, value & 0xFFFFFFFF))


class Run:
    def __init__(self, rate_hz: int, drives: int = 2) -> None:
        self.server = SimServer(drives=drives, ptys=False)
        self.bus = self.server.bus
        self.drives = self.server.drives
        tick_hz = self.server.tick_hz
        if tick_hz % rate_hz:
            raise ValueError(f"{rate_hz} Hz does not divide the {tick_hz} Hz tick")
        self.ticks_per_cycle = tick_hz // rate_hz
        self.period_us = 1_000_000 // rate_hz
        self.rate_hz = rate_hz
        self.host_frames: list[tuple[int, bytes]] = []
        self.server._to_host = lambda cid, data: self.host_frames.append((cid, data))

    def settle(self, ticks: int) -> None:
        for _ in range(ticks):
            self.server.step(1)

    def setup(self) -> None:
        self.settle(10)
        self.bus.send(SimBus.HOST, 0x000, bytes([0x01, 0]))  # NMT start, all nodes
        for d in self.drives:
            n = d.node
            # 0x60C2 = period in us (index -6) when it fits a byte, else in ms
            if self.period_us <= 255:
                _sdo(self.bus, n, 0x60C2, 2, 0xFA, 1)
                _sdo(self.bus, n, 0x60C2, 1, self.period_us, 1)
            else:
                _sdo(self.bus, n, 0x60C2, 1, self.period_us // 1000, 1)
            _sdo(self.bus, n, 0x6060, 0, 8, 1)
            for cw in (0x06, 0x07, 0x0F):
                _sdo(self.bus, n, 0x6040, 0, cw, 2)
        self.settle(200)

    def cycles(self, n: int) -> tuple[int, float]:
        """(cycles missed, worst skew in us) over n cycles."""
        missed = 0
        skew_ticks = 0
        tick_us = 1e6 / self.server.tick_hz
        before = [d.sync_info() for d in self.drives]
        for k in range(1, n + 1):
            target = RAMP_NM_S * k // self.rate_hz
            for d in self.drives:
                self.bus.send(SimBus.HOST, 0x300 + d.node, struct.pack("<Hi", 0x0F, target))
            self.bus.send(SimBus.HOST, 0x080, b"")
            self.host_frames.clear()
            for _ in range(self.ticks_per_cycle):
                self.server.step(1)
            after = [d.sync_info() for d in self.drives]
            ids = [cid for cid, _ in self.host_frames]
            tpdo2 = [ids.count(0x280 + d.node) for d in self.drives]
            ok = self.bus.pending() == 0 and all(
                a[0] == b[0] + 1 and a[2] == b[2] for a, b in zip(after, before)
            )
            ok = ok and tpdo2 == [1] * len(self.drives)
            missed += not ok
            ticks = [a[1] for a in after]
            skew_ticks = max(skew_ticks, max(ticks) - min(ticks))
            before = after
        return missed, skew_ticks * tick_us


def measure(rates=RATES_HZ, cycles: int = CYCLES) -> tuple[int, float]:
    """(highest SYNC rate without a missed cycle, 0 if none; worst skew at
    that rate in us)."""
    best, best_skew = 0, 0.0
    for rate in rates:
        run = Run(rate)
        try:
            run.setup()
            missed, skew = run.cycles(cycles)
        finally:
            run.server.close()
        if missed:
            break
        best, best_skew = rate, skew
    return best, best_skew


def main() -> int:
    hz, skew = measure()
    print(f"canopen_csp_sync_hz: {hz} Hz")
    print(f"canopen_drive_skew_us: {skew:g} us")
    return 0 if hz > 0 else 1


if __name__ == "__main__":
    raise SystemExit(main())
