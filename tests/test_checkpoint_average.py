"""Averaging checkpoints of one run: the parameters are the element-wise mean, the rest is the newest's; the result
evaluates and resumes like any checkpoint."""

import pytest
import torch

from pchc_rsl.cli import eval as eval_cli
from pchc_rsl.cli import runs as runs_cli
from pchc_rsl.cli import train as train_cli


@pytest.fixture(scope="module")
def two_checkpoints(tmp_path_factory):
    root = tmp_path_factory.mktemp("avg")
    train_cli.main(["--task", "toy", "--max-iterations", "2", "--log-dir", str(root / "a")])
    train_cli.main(["--resume", str(root / "a" / "model_1.pt"), "--max-iterations", "2", "--log-dir", str(root / "b")])
    return root, str(root / "a" / "model_1.pt"), str(root / "b" / "model_3.pt")


def test_parameters_are_the_mean_and_the_rest_is_the_newest(two_checkpoints):
    root, old, new = two_checkpoints
    out = str(root / "avg.pt")
    runs_cli.main(["average", new, old, "--out", out])  # order does not matter
    averaged = torch.load(out, weights_only=True)
    a, b = torch.load(old, weights_only=True), torch.load(new, weights_only=True)
    for key in ("actor_state_dict", "critic_state_dict", "value_normalizer_state_dict"):
        for name, tensor in a[key].items():
            if name.endswith("_std"):  # the std of the averaged variance, not the mean of the stds
                var = (a[key][name[:-4] + "_var"] + b[key][name[:-4] + "_var"]) / 2
                assert torch.allclose(averaged[key][name], var.sqrt()), name
                if not torch.equal(a[key][name], b[key][name]):
                    assert not torch.allclose(averaged[key][name], (tensor + b[key][name]) / 2), name
            elif tensor.is_floating_point():
                assert torch.allclose(averaged[key][name], (tensor + b[key][name]) / 2), name
    changed = [n for n, t in a["actor_state_dict"].items() if t.is_floating_point()
               and not torch.equal(t, b["actor_state_dict"][n])]
    assert changed  # the test means something only if training moved the parameters
    assert averaged["iter"] == b["iter"] == 3 and "optimizer_state_dict" not in averaged
    assert averaged["averaged_from"] == ["a/model_1.pt@1", "b/model_3.pt@3"]
    eval_cli.main([out, "--num-envs", "4", "--episodes", "1", "--preferences", "2", "--output", str(root / "e")])
    assert (root / "e" / "table.md").is_file()
    train_cli.main(["--resume", out, "--max-iterations", "1", "--log-dir", str(root / "more")])
    assert torch.load(root / "more" / "model_4.pt", weights_only=True)["iter"] == 4


def test_checkpoints_of_different_networks_are_refused(two_checkpoints):
    root, old, new = two_checkpoints
    other = torch.load(old, weights_only=True)
    name = next(n for n, t in other["actor_state_dict"].items() if t.is_floating_point() and t.dim() == 2)
    other["actor_state_dict"][name] = torch.zeros(3, 3)
    torch.save(other, root / "other.pt")
    with pytest.raises(SystemExit, match="^pchc-runs average: .*not the same network"):
        runs_cli.main(["average", str(root / "other.pt"), new, "--out", str(root / "x.pt")])
    with pytest.raises(SystemExit, match="^pchc-runs average: give at least two checkpoints"):
        runs_cli.main(["average", new, "--out", str(root / "x.pt")])
    assert not (root / "x.pt").exists()


def test_weights_interpolate_and_actor_only_keeps_the_newest_critics(two_checkpoints):
    root, old, new = two_checkpoints
    a, b = torch.load(old, weights_only=True), torch.load(new, weights_only=True)
    widened = torch.load(old, weights_only=True)  # a critic of another shape, as --init-from widens one
    name = next(n for n, t in widened["critic_state_dict"].items() if t.is_floating_point() and t.dim() == 2)
    widened["critic_state_dict"][name] = torch.zeros(3, 3)
    torch.save(widened, root / "widened.pt")
    with pytest.raises(SystemExit, match="not the same network"):
        runs_cli.main(["average", str(root / "widened.pt"), new, "--weights", "1", "3", "--out", str(root / "x.pt")])
    runs_cli.main(["average", new, str(root / "widened.pt"), "--weights", "3", "1", "--actor-only", "--out",
                   str(root / "w.pt")])
    mixed = torch.load(root / "w.pt", weights_only=True)
    for name, tensor in a["actor_state_dict"].items():
        if tensor.is_floating_point() and not name.endswith("_std"):
            assert torch.allclose(mixed["actor_state_dict"][name], 0.25 * tensor + 0.75 * b["actor_state_dict"][name])
    for key in ("critic_state_dict", "value_normalizer_state_dict"):
        for name, tensor in b[key].items():
            assert torch.equal(mixed[key][name], tensor), name
    assert mixed["averaged_weights"] == [0.25, 0.75]
    for bad, message in ((["1"], "one weight per checkpoint"), (["1", "-1"], ">= 0"), (["0", "0"], ">= 0")):
        with pytest.raises(SystemExit, match=f"^pchc-runs average: --weights.*{message}"):
            runs_cli.main(["average", new, old, "--weights", *bad, "--out", str(root / "x.pt")])


def test_expert_weights_move_each_expert_by_its_own_share(two_checkpoints):
    """Given newest first: each expert is (1 - share) x the first + share x the second, the rest of the actor takes
    --weights, the critics are the newest's."""
    root, old, new = two_checkpoints
    a, b = torch.load(new, weights_only=True), torch.load(old, weights_only=True)
    experts = a["actor_state_dict"]["mlp.experts.weights.0"].shape[0]
    shares = [i / (experts - 1) for i in range(experts)]
    runs_cli.main(["average", new, old, "--weights", "1", "0", "--expert-weights", *map(str, shares), "--out",
                   str(root / "e.pt")])
    mixed = torch.load(root / "e.pt", weights_only=True)
    moved = 0
    for name, tensor in a["actor_state_dict"].items():
        if name.startswith("mlp.experts."):
            for expert, share in enumerate(shares):
                expected = (1 - share) * tensor[expert] + share * b["actor_state_dict"][name][expert]
                assert torch.allclose(mixed["actor_state_dict"][name][expert], expected, atol=1e-7), (name, expert)
            moved += not torch.equal(tensor, b["actor_state_dict"][name])
        elif tensor.is_floating_point():
            assert torch.allclose(mixed["actor_state_dict"][name], tensor), name
    assert moved  # training moved the experts, so the shares are seen
    for name, tensor in a["critic_state_dict"].items():
        assert torch.equal(mixed["critic_state_dict"][name], tensor), name
    for bad, message in ((shares[:-1], "one share in"), ([2.0] * experts, "one share in")):
        with pytest.raises(SystemExit, match=f"^pchc-runs average: --expert-weights.*{message}"):
            runs_cli.main(["average", new, old, "--expert-weights", *map(str, bad), "--out", str(root / "x.pt")])
    with pytest.raises(SystemExit, match="--expert-weights mixes two checkpoints"):
        runs_cli.main(["average", new, old, old, "--expert-weights", *map(str, shares), "--out", str(root / "x.pt")])
