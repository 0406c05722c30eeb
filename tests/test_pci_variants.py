"""The PCI variants screen: pairing with the gate's runs by seed, the low-mode count, the report."""

import json
import math

import pytest
from tool_loader import load_tool

pci_variants = load_tool("studies/pci_variants")


def row(variant, seed, hv_at_1m, forward=1000.0):
    """A run row with evaluations at 250k..1M (the 1M one given) and per-preference returns."""
    evaluations = [{"env_steps": k * 250_000 + 1024, "grid_steps": k * 250_000, "hypervolume": hv_at_1m * k / 4,
                    "expected_utility": 0.5 + 0.05 * k, "mean_returns": [[forward * k / 4, -100.0], [1.0, -1.0]]}
                   for k in range(1, 5)]
    return {"variant": variant, "seed": seed, "env_steps": 1_000_000, "evaluations": evaluations,
            "preferences": [[1.0, 0.0], [0.0, 1.0]], "routing_mass_last_tenth": [0.2] * 5}


def test_variants_pair_with_the_gate_by_seed_and_count_runs_below_every_gate_run():
    """Gate runs at 2, 4, 2 (seeds 0-2); the variant at 4, 2, 1: log-ratios log 2, log 0.5, log 0.5; one run (1)
    below the lowest gate run (2). Seed 3 has no gate run and is not paired."""
    gates = [row("gated", 0, 2.0), row("gated", 1, 4.0), row("gated", 2, 2.0)]
    runs = [row("pci-s0", 0, 4.0), row("pci-s0", 1, 2.0), row("pci-s0", 2, 1.0), row("pci-s0", 3, 9.0)]
    result = pci_variants.compare(runs, gates, (1_000_000,))["hypervolume"]
    assert result["seeds"] == [0, 1, 2]
    assert result["log_ratios"] == pytest.approx([math.log(2), math.log(0.5), math.log(0.5)])
    assert result["below_every_gate_run"] == 1 and result["lowest_gate"] == 2.0
    assert result["ratio"] == pytest.approx(math.exp((math.log(2) - 2 * math.log(2)) / 3))


def test_the_report_section_replaces_its_old_self_and_keeps_the_rest(tmp_path, monkeypatch):
    gates = [row("gated", s, 2.0) for s in range(2)]
    for seed, hv in ((0, 3.0), (1, 1.0)):
        folder = tmp_path / "runs" / pci_variants.TASK / f"pci-floor_seed{seed}"
        folder.mkdir(parents=True)
        r = row("pci", seed, hv, forward=2000.0)
        history = [{"env_steps": e["env_steps"], "hypervolume": e["hypervolume"],
                    "expected_utility": e["expected_utility"], "mean_returns": e["mean_returns"]}
                   for e in r["evaluations"]]
        (folder / "result.json").write_text(json.dumps({"variant": "pci-floor", "seed": seed,
                                                        "env_steps": 1_000_000, "history": history,
                                                        "preferences": r["preferences"]}))
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "mo_study.md").write_text("# Study\n\nbefore\n\n<!-- pci-variants:start -->\nold\n"
                                      "<!-- pci-variants:end -->\n\nafter\n")
    landed_pci = [row("pci", s, 1.0) for s in range(2)]
    for r in landed_pci:  # the landed study kept no per-preference returns
        for e in r["evaluations"]:
            del e["mean_returns"]
    study = pci_variants.write_report(str(tmp_path / "runs"), ["pci-floor"], [0, 1], 1_000_000, str(docs), gates,
                                      gaits=False, landed_pci=landed_pci)
    page = (docs / "mo_study.md").read_text()
    assert page.startswith("# Study\n\nbefore\n\n<!-- pci-variants:start -->") and page.endswith("\nafter\n")
    assert "old" not in page and "| pci-floor |" in page and "1 of 2" in page
    assert "| 2000 |" in page  # the mean return at (1, 0) at 1M over the two runs
    saved = json.loads((docs / "pci_variants.json").read_text())
    assert saved["screen"]["pci-floor"]["against_gate"]["hypervolume"]["n"] == 2
    assert study["gate_runs"]["hypervolume"] == [2.0, 2.0]
    # the study's PCI is the first row, paired with the same gate runs: 1 against 2 in both pairs
    assert page.index("| pci | PCI as in the paired study") < page.index("| pci-floor |")
    assert "| 0.50 [0.50, 0.50], n = 2 |" in page and "| 2 of 2 | - |" in page
