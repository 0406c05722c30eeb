"""Timing of the sim-to-sim loop: pchc-deploy --sim against pchc-sim-bridge over DDS on loopback, repeated.

Prints, per run and as medians: the deploy's 50 Hz loop (ticks, overruns, worst lateness), the bridge's 500 Hz
physics loop (share of steps on time, worst lateness), and LowCmd / LowState counts (sent, received, bad CRC).

    python tools/bench_deploy_loop.py policies/g1_walk.onnx --runs 3 --seconds 10
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("policy")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--preference", default="1,0")
    args = parser.parse_args(argv)
    rows = []
    for run in range(args.runs):
        report_file = Path(tempfile.mkdtemp()) / "deploy.json"
        done = subprocess.run([sys.executable, "-m", "pchc_rsl.cli.deploy", args.policy, "--sim", "--preference",
                               args.preference, "--seconds", str(args.seconds), "--report", str(report_file)],
                              capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"run {run}: {done.stderr.strip()}")
        r = json.loads(report_file.read_text())
        b = r["bridge"]
        row = {"deploy_ticks": r["loop"]["ticks"], "deploy_overruns": r["loop"]["overruns"],
               "deploy_worst_late_ms": r["loop"]["worst_late_ms"], "bridge_steps": b["loop"]["ticks"],
               "bridge_on_time": b["real_time_share"], "bridge_worst_late_ms": b["loop"]["worst_late_ms"],
               "lowcmd_sent": r["messages_sent"], "lowcmd_received": b["commands_received"],
               "bad_crc": b["commands_bad_crc"], "lowstate_received": r["messages_received"], "fell": r["fell"]}
        rows.append(row)
        print(f"run {run}: " + ", ".join(f"{k} {v}" for k, v in row.items()), flush=True)
    for key in ("deploy_overruns", "deploy_worst_late_ms", "bridge_on_time", "bridge_worst_late_ms"):
        print(f"median {key}: {statistics.median(row[key] for row in rows)}")
    return rows


if __name__ == "__main__":
    main()
