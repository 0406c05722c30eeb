"""tools/studies/mo_study.py: the routing table's expert shares and the report."""

import numpy as np
from tool_loader import load_tool

mo_study = load_tool("studies/mo_study")


def test_expert_training_shares_match_an_integral_of_the_beta_density():
    """Reference: integrate the normalised Beta densities at the (clamped) positions over lambda_1 ~ Beta(c, c)."""
    from scipy import integrate
    from scipy.stats import beta

    positions = np.clip([0.0, 0.25, 0.5, 0.75, 1.0], 0.01, 0.99)

    def weight(lam_1, j, scale):
        densities = beta.pdf(positions, 1 + scale * lam_1, 1 + scale * (1 - lam_1))
        return densities[j] / densities.sum()

    for scale, concentration in [(10.0, 1.0), (3.0, 1.0), (10.0, 0.5)]:
        expected = [integrate.quad(lambda x: weight(x, j, scale) * beta.pdf(x, concentration, concentration), 0, 1,
                                   limit=200)[0] for j in range(5)]
        np.testing.assert_allclose(mo_study.expert_training_shares(scale, concentration), expected, atol=2e-3)


def fake_run(task, variant, seed, hv):
    return {"task": task, "variant": variant, "seed": seed, "hypervolume": hv, "sparsity": 0.0, "num_points": 2,
            "rows": [{"mean_return": [1.0, 2.0]}, {"mean_return": [2.0, 1.0]}], "front": [[1.0, 2.0], [2.0, 1.0]],
            "history": []}


def test_report_tests_pci_against_the_gate_and_gives_three_objectives_their_own_section(tmp_path):
    from scipy import stats

    pci, gated = [1.0e7, 1.4e7, 0.9e7], [1.3e7, 1.5e7, 1.6e7]
    results = {}
    for task in mo_study.TASKS:
        for variant in mo_study.VARIANTS:
            values = pci if variant == "pci" else gated
            results[(task, variant)] = [fake_run(task, variant, s, v) for s, v in zip([1, 2, 3], values)]
    results[("mo-hopper-v5", "gated-matched")] = [fake_run("mo-hopper-v5", "gated-matched", 1, 2.0e7)]
    page = mo_study.markdown_report(results, [1, 2, 3], 1000, 90, str(tmp_path))
    main_table, rest = page.split("## Three objectives")[0], page.split("## Three objectives")[1]
    assert "| mo-hopper-v5 |" not in main_table and "| mo-halfcheetah-v5 |" in main_table
    p = stats.ttest_ind(pci, gated, equal_var=False).pvalue
    ratio = f"{np.mean(pci) / np.mean(gated):.2f}"  # every variant but pci has the gate's values here
    assert f"| mo-walker2d-v5 | {ratio} | {ratio} | {ratio} | {p:.2f} |" in main_table
    assert "| gated-matched | 2e+07 | 0 | 2 | 1 |" in rest
    assert f"over the matched six-expert gate: {np.mean(pci) / 2.0e7:.2f}" in rest


def test_marked_sections_of_the_old_page_survive_a_rewrite():
    old = "# old\n\nstale text\n\n<!-- pci-vs-gated:start -->\n## Does PCI help?\nrows\n<!-- pci-vs-gated:end -->\n"
    new = mo_study.carry_marked_sections(old, "# new\n")
    assert new == "# new\n\n<!-- pci-vs-gated:start -->\n## Does PCI help?\nrows\n<!-- pci-vs-gated:end -->\n"
    assert mo_study.carry_marked_sections("# no blocks\n", "# new\n") == "# new\n"
