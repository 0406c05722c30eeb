"""tools/studies/pci_vs_gated.py: the paired interval, each run's figure from the evaluation grid, and the report's
rows."""

import json
import math

import numpy as np
import pytest
from tool_loader import load_tool

pci_vs_gated = load_tool("studies/pci_vs_gated")


def test_paired_log_ratio_interval_is_scipys_paired_t_interval():
    from scipy import stats

    pci = [1.2e7, 2.0e7, 1.5e7, 0.9e7, 1.8e7]
    gated = [1.5e7, 1.9e7, 2.1e7, 1.2e7, 1.6e7]
    result = pci_vs_gated.paired_log_ratio(pci, gated)
    reference = stats.ttest_rel(np.log(pci), np.log(gated)).confidence_interval(0.95)
    assert result["n"] == 5
    assert result["mean_log_ratio"] == pytest.approx(np.mean(np.log(pci) - np.log(gated)))
    assert result["ci95"] == pytest.approx([reference.low, reference.high], rel=1e-9)
    assert result["ratio_ci95"] == pytest.approx([math.exp(reference.low), math.exp(reference.high)], rel=1e-9)


def test_pairs_for_power_matches_the_published_paired_t_sizes_and_a_simulation():
    """Cohen's paired-t table (alpha 0.05 two-sided, power 0.8): d = 0.5 needs 34 pairs, d = 0.8 needs 15 (G*Power:
    actual power 0.821). A simulation of 20,000 studies agrees: 82% reject at 15 pairs, fewer than 78% at 13."""
    from scipy import stats

    assert pci_vs_gated.pairs_for_power(0.5) == 34
    assert pci_vs_gated.pairs_for_power(0.8) == 15
    assert pci_vs_gated.pairs_for_power(0.0) is None
    rng = np.random.default_rng(0)

    def rejected(n, effect=0.8):
        d = rng.normal(effect, 1.0, size=(20_000, n))
        t = d.mean(1) / (d.std(1, ddof=1) / math.sqrt(n))
        return float((np.abs(t) > stats.t.ppf(0.975, n - 1)).mean())

    assert rejected(15) == pytest.approx(0.821, abs=0.01)
    assert rejected(13) < 0.78


def test_the_report_sizes_a_study_from_the_measured_spread():
    pci, gated = [1.0, 1.3, 0.9, 1.2], [1.1, 1.0, 1.0, 1.0]
    result = pci_vs_gated.paired_log_ratio(pci, gated)
    d = np.log(pci) - np.log(gated)
    assert result["sd_log_ratio"] == pytest.approx(d.std(ddof=1))
    assert result["pairs_for_80pct_power"] == pci_vs_gated.pairs_for_power(abs(d.mean()) / d.std(ddof=1))
    text = pci_vs_gated.verdict(result, "hypervolume")
    assert f"{result['pairs_for_80pct_power']} pairs would show it 80% of the time" in text


def test_one_pair_has_no_interval():
    result = pci_vs_gated.paired_log_ratio([2.0], [1.0])
    assert result["n"] == 1 and result["ratio"] == pytest.approx(2.0)
    assert all(math.isnan(x) for x in result["ci95"])


def fake_result(variant, seed, hv_scale, eu_scale):
    """A result.json of a 2M-step run: evaluations just past each 250k mark (2048 steps per update)."""
    iterations = [math.ceil(k * 250_000 / 2048) for k in range(1, 9)]
    history = [{"env_steps": it * 2048, "hypervolume": hv_scale * k, "expected_utility": eu_scale * k,
                "mean_returns": [[100.0 * k, -10.0 * k], [0.0, -1.0]]} for k, it in enumerate(iterations, start=1)]
    return {"variant": variant, "seed": seed, "env_steps": iterations[-1] * 2048, "history": history,
            "routing_mass": {"iterations": list(range(20)), "per_expert": [[0.2] * 20] * 5},
            "cpu_seconds_complete": True}


def write_run(root, result, cpu_seconds):
    folder = root / pci_vs_gated.TASK / f"{result['variant']}_seed{result['seed']}"
    folder.mkdir(parents=True)
    (folder / "result.json").write_text(json.dumps({**result, "cpu_seconds": cpu_seconds}))


def test_report_pairs_the_seeds_and_averages_the_last_three_evaluations(tmp_path):
    """Seed 0: PCI at twice gated's HV and equal EU; seed 1: PCI at half gated's HV. Seed 2 has no gated run yet."""
    write_run(tmp_path, fake_result("pci", 0, 2.0, 1.0), 1800)
    write_run(tmp_path, fake_result("gated", 0, 1.0, 1.0), 1800)
    write_run(tmp_path, fake_result("pci", 1, 1.0, 1.0), 3600)
    write_run(tmp_path, fake_result("gated", 1, 2.0, 1.0), 3600)
    write_run(tmp_path, fake_result("pci", 2, 1.0, 1.0), 3600)
    started = tmp_path / pci_vs_gated.TASK / "gated_seed2" / "train"
    started.mkdir(parents=True)
    (started / "model_99.pt").write_bytes(b"")
    docs = tmp_path / "docs"
    docs.mkdir()
    (docs / "mo_study.md").write_text("# MO-Gymnasium study\n\nearlier sections\n")
    study = pci_vs_gated.write_report(str(tmp_path), [0, 1, 2], str(docs))

    saved = json.loads((docs / "pci_vs_gated.json").read_text())
    assert saved == json.loads(json.dumps(study))
    assert [(r["variant"], r["seed"]) for r in saved["runs"]] == [("pci", 0), ("gated", 0), ("pci", 1), ("gated", 1),
                                                                   ("pci", 2)]
    row = saved["runs"][0]
    assert [e["grid_steps"] for e in row["evaluations"]] == [250_000 * k for k in range(1, 9)]
    assert row["evaluations"][5] == {"env_steps": 733 * 2048, "grid_steps": 1_500_000, "hypervolume": 12.0,
                                     "expected_utility": 6.0, "mean_returns": [[600.0, -60.0], [0.0, -1.0]]}
    assert saved["core_hours"] == pytest.approx((2 * 1800 + 3 * 3600) / 3600)
    # final window: grid points 6, 7, 8 -> mean 7 x the scale
    assert pci_vs_gated.run_figure(row, "hypervolume", pci_vs_gated.FINAL_WINDOW) == pytest.approx(14.0)
    hv = saved["paired_log_ratio_pci_over_gated"]["final/hypervolume"]
    assert hv["n"] == 2 and hv["seeds"] == [0, 1]
    assert hv["log_ratios"] == pytest.approx([math.log(2), -math.log(2)])
    assert hv["mean_log_ratio"] == pytest.approx(0.0, abs=1e-12)
    eu = saved["paired_log_ratio_pci_over_gated"]["1M/expected_utility"]
    assert eu["log_ratios"] == pytest.approx([0.0, 0.0])
    page = (docs / "mo_study.md").read_text()
    assert page.startswith("# MO-Gymnasium study\n\nearlier sections\n")
    assert "**5 of 6 runs finished, 2 of 3 pairs.** The intervals below are provisional: 2 of the 3" in page
    assert "not finished (they resume from their checkpoints): gated seed 2 (204,800 env steps checkpointed)." in page
    # writing the report again replaces the section instead of adding a second one
    pci_vs_gated.write_report(str(tmp_path), [0, 1, 2], str(docs))
    assert (docs / "mo_study.md").read_text() == page
    assert (docs / "pci_vs_gated.png").stat().st_size > 0


def test_cells_run_seed_by_seed_with_the_studys_settings():
    cells = pci_vs_gated.study_cells([0, 1])
    assert [(c.name, c.seed) for c in cells] == [("pci", 0), ("gated", 0), ("pci", 1), ("gated", 1)]
    pci, gated = cells[0].args, cells[1].args
    assert pci[pci.index("--routing-scale") + 1] == "3" and "--match-pci-parameters" in gated
    for args in (pci, gated):
        assert args[args.index("--steps") + 1] == "2000000" and args[args.index("--eval-every") + 1] == "250000"


def test_runs_of_the_landed_report_count_as_finished_and_are_not_trained_again(tmp_path, monkeypatch):
    """A new machine's empty run folder: the landed report's pci seed 0 and gated seed 0 stay in the report and only
    seed 1's cells run; a run finished in the folder wins over the landed row of the same cell."""
    first = tmp_path / "first"
    write_run(first, fake_result("pci", 0, 2.0, 1.0), 1800)
    write_run(first, fake_result("gated", 0, 1.0, 1.0), 1800)
    landed_path = tmp_path / "landed.json"
    landed_path.write_text(json.dumps(pci_vs_gated.write_report(str(first), [0, 1], None)))
    ran = []
    monkeypatch.setattr(pci_vs_gated, "run_cell", lambda cell, root: ran.append((cell.name, cell.seed)))
    monkeypatch.setattr(pci_vs_gated, "plot", lambda study, path: None)
    second = tmp_path / "second"
    study = pci_vs_gated.main(["--out", str(second), "--seeds", "0", "1", "--landed", str(landed_path)])
    assert ran == [("pci", 1), ("gated", 1)]
    assert [(r["variant"], r["seed"]) for r in study["runs"]] == [("pci", 0), ("gated", 0)]
    assert study["paired_log_ratio_pci_over_gated"]["final/hypervolume"]["log_ratios"] == pytest.approx([math.log(2)])
    assert study["core_hours"] == pytest.approx(1.0)
    write_run(second, fake_result("pci", 0, 4.0, 1.0), 900)
    study = pci_vs_gated.main(["--out", str(second), "--seeds", "0", "1", "--landed", str(landed_path),
                               "--report-only"])
    assert study["paired_log_ratio_pci_over_gated"]["final/hypervolume"]["log_ratios"] == pytest.approx([math.log(4)])


def test_a_landed_report_of_another_study_is_refused(tmp_path):
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"task": "mo-hopper-2obj-v5", "steps": 1_000_000, "runs": []}))
    with pytest.raises(SystemExit, match="not of mo-halfcheetah-v5 at 2000000"):
        pci_vs_gated.main(["--out", str(tmp_path / "runs"), "--landed", str(other), "--report-only"])
