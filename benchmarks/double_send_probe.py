"""Where the emulator's double-send flag comes from: N open/stream/hold/close sessions on one strict emulator.

    python benchmarks/double_send_probe.py 30

The emulator (``EmulatorProcess(record_arrivals=True)``) logs every CommandPacket's kernel arrival time
and sequence number; for each flagged packet the output has the arrival gaps (ms) and sequence
numbers of the three packets before it and the three after (``flag_context``), and per session the
phase the flag came in (open, stream, close) with the driver core's own counters (TX count, ticks,
skipped windows, TX gap max, ``double_send_guard``).
"""
import json
import sys
import time

import numpy as np

from robointel.interface import open_robot
from robointel.interface.realtime import realtime_thread, sleep_until
from robointel.testing.emulator import EmulatorProcess


def main(n: int) -> None:
    emu = EmulatorProcess(record_arrivals=True)
    per = []
    try:
        for _ in range(n):
            v0 = len(emu.call("violations"))
            with open_robot(emu.url) as r:
                v1 = len(emu.call("violations"))
                q0 = r.state().q
                with realtime_thread():
                    t0 = time.perf_counter()
                    for k in range(250):
                        sleep_until(t0 + k * 0.008)
                        r.stream(q0 + np.r_[0.05 * np.sin(2 * np.pi * 0.5 * k * 0.008), np.zeros(5)])
                r.hold()
                v2 = len(emu.call("violations"))
                stats = r.timing_stats()
            v3 = len(emu.call("violations"))
            per.append({"open": v1 - v0, "stream": v2 - v1, "close": v3 - v2,
                        "tx": stats.get("tx_count"), "ticks": stats.get("tick_count"),
                        "skipped": stats.get("skipped_tick_windows"), "tx_max_ms": stats.get("tx_interval_max_ms"),
                        "guard": stats.get("double_send_guard")})
        ctx = emu.call("arrival_context")
    finally:
        v = emu.close()
    print(json.dumps({"sessions": n, "violations": v, "flag_context": ctx,
                      "flagged_sessions": [(i, p) for i, p in enumerate(per) if p["open"] or p["stream"] or p["close"]],
                      "tx_max_ms": max(p["tx_max_ms"] or 0 for p in per)}))

if __name__ == "__main__":
    main(int(sys.argv[1]))
