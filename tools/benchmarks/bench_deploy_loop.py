"""Timing of the sim-to-sim loop: pchc-deploy --sim against pchc-sim-bridge over DDS on loopback, repeated.

Prints, per run and as medians: the deploy's 50 Hz loop (ticks, overruns, worst lateness), the bridge's 500 Hz
physics loop (real-time factor, share of late steps, slowest step), and LowCmd / LowState counts (sent, received,
bad CRC). A run that fell behind real time is reported like the others (pchc-deploy exits non-zero for it).

    python tools/benchmarks/bench_deploy_loop.py policies/g1_walk.onnx --runs 3 --seconds 10
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
        if not report_file.exists():
            raise SystemExit(f"run {run}: {done.stderr.strip()}")
        r = json.loads(report_file.read_text())
        b = r["bridge"]
        row = {"deploy_ticks": r["loop"]["ticks"], "deploy_overruns": r["loop"]["overruns"],
               "deploy_worst_late_ms": r["loop"]["worst_late_ms"], "bridge_steps": b["loop"]["ticks"],
               "bridge_real_time_factor": b["real_time_factor"], "bridge_late_share": b["late_share"],
               "bridge_slowest_step_ms": b["slowest_step_ms"],
               "lowcmd_sent": r["messages_sent"], "lowcmd_received": b["commands_received"],
               "bad_crc": b["commands_bad_crc"], "lowstate_received": r["messages_received"], "fell": r["fell"]}
        rows.append(row)
        print(f"run {run}: " + ", ".join(f"{k} {v}" for k, v in row.items()), flush=True)
    for key in ("deploy_overruns", "deploy_worst_late_ms", "bridge_real_time_factor", "bridge_late_share",
                "bridge_slowest_step_ms"):
        print(f"median {key}: {statistics.median(row[key] for row in rows)}")
    return rows


if __name__ == "__main__":
    main()
