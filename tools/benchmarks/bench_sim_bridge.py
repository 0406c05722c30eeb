"""Cost of one physics step of pchc-sim-bridge, by part: the MuJoCo step (PD law and physics), reading the state,
building and publishing rt/lowstate (message, CRC, DDS write), and receiving one rt/lowcmd (decoding, CRC check,
conversion).

The bridge keeps real time when a whole step costs less than the timestep (2 ms at 500 Hz, 5 ms at 200 Hz) on
the machine that runs it, with the deploy beside it. Runs on loopback, DDS domain 231, nothing else is needed.

    python tools/benchmarks/bench_sim_bridge.py --steps 2000
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def timed(fn, n: int) -> float:
    """Mean seconds per call over n calls."""
    start = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - start) / n


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--domain", type=int, default=231)
    args = parser.parse_args(argv)

    from pchc_rsl.deploy.g1_motors import MOTOR_DEFAULT_POS
    from pchc_rsl.deploy.robot_io import MotorCommand
    from pchc_rsl.deploy.sdk import DdsBridgeEnd, lowcmd_message
    from pchc_rsl.deploy.sim_bridge import G1_MODE_MACHINE
    from pchc_rsl.deploy.simulator import G1Simulator

    sim = G1Simulator(hold_up_s=1e9)
    received = []
    end = DdsBridgeEnd(args.domain, "lo", received.append)
    cmd = MotorCommand(q=MOTOR_DEFAULT_POS.copy(), kp=np.full(29, 100.0), kd=np.full(29, 2.0))
    sim.apply(cmd)
    state = sim.state()
    incoming = lowcmd_message(cmd, G1_MODE_MACHINE)
    sample = incoming.serialize()
    parts = {
        "physics step": timed(sim.step, args.steps),
        "read state": timed(sim.state, args.steps),
        "publish LowState": timed(lambda: end.publish(state, G1_MODE_MACHINE), args.steps),
        "receive LowCmd": timed(lambda: end._on_sample(sample, 0.0), args.steps),
    }
    end.close()
    total = sum(parts.values())
    for name, seconds in parts.items():
        print(f"{name:>18}: {seconds * 1e6:8.1f} us")
    print(f"{'per step':>18}: {total * 1e6:8.1f} us (one LowCmd per step, as at 500 Hz LowCmd and 500 Hz physics)")
    return {name: seconds * 1e6 for name, seconds in parts.items()} | {"total_us": total * 1e6}


if __name__ == "__main__":
    main()
