"""A resumed run continues exactly: 10 + 10 toy iterations equal 20 in one go, weights and statistics alike."""

import torch

from pchc_rsl.cli import train as train_cli


def run(args):
    try:
        train_cli.main(["--task", "toy", "--num-envs", "16", "--seed", "3", *args])
    except SystemExit as stop:  # the CLI may exit 0 after its summary
        assert not stop.code, stop.code


def test_ten_plus_ten_iterations_equal_twenty_in_one_go(tmp_path):
    run(["--max-iterations", "20", "--log-dir", str(tmp_path / "one_go")])
    run(["--max-iterations", "10", "--log-dir", str(tmp_path / "first")])
    run(["--resume", str(tmp_path / "first" / "model_9.pt"), "--max-iterations", "10",
         "--log-dir", str(tmp_path / "second")])
    one_go = torch.load(tmp_path / "one_go" / "model_19.pt", weights_only=True)
    resumed = torch.load(tmp_path / "second" / "model_19.pt", weights_only=True)
    for key in ("actor_state_dict", "critic_state_dict", "value_normalizer_state_dict"):
        assert one_go[key].keys() == resumed[key].keys()
        for name, tensor in one_go[key].items():
            assert torch.equal(tensor, resumed[key][name]), f"{key}.{name} differs after resuming"
    # the check can fail: a run from another seed differs
    run(["--max-iterations", "20", "--seed", "4", "--log-dir", str(tmp_path / "other")])
    other = torch.load(tmp_path / "other" / "model_19.pt", weights_only=True)
    assert any(not torch.equal(t, other["actor_state_dict"][n]) for n, t in one_go["actor_state_dict"].items())
