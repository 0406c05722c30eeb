"""The MO-Gymnasium adapter and the benchmark tool, checked against the raw MO-Gymnasium env."""

import json
import sys

import numpy as np
import pytest
import torch

mo_gymnasium = pytest.importorskip("mo_gymnasium")

from pchc_rsl.cli import train as train_cli  # noqa: E402
from pchc_rsl.envs.mo_gym import MOGymEnvConfig, MOGymVecEnv, make_mo_env  # noqa: E402
from tool_loader import load_tool  # noqa: E402

HOPPER = "mo-hopper-2obj-v5"


def _hopper(num_envs=3, seed=5, **overrides):
    cfg = MOGymEnvConfig(env_id=HOPPER, objective_names=["forward", "height"], **overrides)
    return MOGymVecEnv(cfg, num_envs, "cpu", seed)


def test_reward_groups_are_the_raw_vector_reward_of_an_identically_seeded_env():
    env = _hopper(num_envs=2, seed=5, reward_scale=0.1)
    reference = mo_gymnasium.make(HOPPER)
    obs, _ = reference.reset(seed=6)  # env 1 of the adapter is seeded seed + 1
    np.testing.assert_allclose(env.get_observations()["critic"][1].numpy(), obs, rtol=1e-6)
    actions = torch.linspace(-1.5, 1.5, 2 * env.num_actions).reshape(2, env.num_actions)  # beyond the bounds
    for _ in range(3):
        _, reward, _, extras = env.step(actions)
        obs, vector_reward, _, _, _ = reference.step(np.clip(actions[1].numpy(), -1.0, 1.0))
        groups = extras["reward_groups"]
        assert groups.shape == (2, 3)
        assert torch.all(groups[:, 0] == 0)  # no task reward configured
        np.testing.assert_allclose(groups[1, 1:].numpy(), 0.1 * vector_reward, rtol=1e-5)
        expected = 0.1 * float(np.dot(env.preference[1].numpy(), vector_reward))
        assert reward[1].item() == pytest.approx(expected, rel=1e-5)
        np.testing.assert_allclose(env.get_observations()["critic"][1].numpy(), obs, rtol=1e-6)


def test_time_limit_is_a_time_out_and_resets_immediately():
    env = _hopper(num_envs=2, make_kwargs={"max_episode_steps": 4})
    first = env.get_observations()["policy"].clone()
    for step in range(4):
        obs, _, dones, extras = env.step(torch.zeros(2, env.num_actions))
    assert dones.all() and extras["time_outs"].all()
    assert torch.all(env.episode_length_buf == 0)
    assert "Episode_Objective/forward" in extras["log"]
    # the returned observation is a fresh episode's: near the initial pose again, not the 4th step's state
    assert torch.allclose(obs["policy"][:, :1], first[:, :1], atol=0.02)


def test_falling_terminates_without_time_out():
    env = _hopper(num_envs=1)
    for _ in range(200):
        _, _, dones, extras = env.step(torch.ones(1, env.num_actions))
        if dones.any():
            break
    assert dones.all() and not extras["time_outs"].any()


def test_history_frames_are_stacked_newest_first():
    env = _hopper(num_envs=1, history_length=2)
    obs_dim = env.get_observations()["critic"].shape[1]
    frames = []
    for _ in range(3):
        obs, *_ = env.step(torch.zeros(1, env.num_actions))
        frames.append(obs["critic"][0])
    policy = obs["policy"][0].reshape(3, obs_dim)
    for k in range(3):
        assert torch.equal(policy[k], frames[2 - k])


def test_set_preference_holds_across_resets_and_is_validated():
    env = _hopper(num_envs=2, make_kwargs={"max_episode_steps": 2})
    env.set_preference([0.3, 0.7])
    for _ in range(5):
        obs, *_ = env.step(torch.zeros(2, env.num_actions))
    assert torch.allclose(obs["preference"], torch.tensor([[0.3, 0.7], [0.3, 0.7]]))
    with pytest.raises(ValueError, match="one weight per objective"):
        env.set_preference([0.2, 0.3, 0.5])
    env.set_preference(None)
    for _ in range(2):
        obs, *_ = env.step(torch.zeros(2, env.num_actions))
    assert not torch.allclose(obs["preference"], torch.tensor([[0.3, 0.7], [0.3, 0.7]]))


def test_task_reward_weights_build_the_task_group():
    env = _hopper(num_envs=1, task_reward_weights=[0.5, 0.0])
    _, _, _, extras = env.step(torch.zeros(1, env.num_actions))
    assert extras["reward_groups"][0, 0].item() == pytest.approx(0.5 * extras["reward_groups"][0, 1].item())


def test_wrong_objective_names_and_missing_extra_fail_clearly(monkeypatch):
    with pytest.raises(ValueError, match="2 objectives"):
        MOGymVecEnv(MOGymEnvConfig(env_id=HOPPER, objective_names=["a", "b", "c"]), 1)
    monkeypatch.setitem(sys.modules, "mo_gymnasium", None)
    with pytest.raises(ImportError, match=r'pip install -e "\.\[mo-gym\]"'):
        make_mo_env(HOPPER)


def test_pchc_train_runs_on_an_mo_gym_task(tmp_path):
    train_cli.main(["--task", HOPPER, "--num-envs", "2", "--max-iterations", "1", "--log-dir", str(tmp_path)])
    checkpoint = torch.load(tmp_path / "model_0.pt", weights_only=True)
    assert checkpoint["config"]["task"] == HOPPER


def _hypervolume_2d(points, ref):
    """Independent 2-D hypervolume (maximisation): sweep the points by decreasing first objective."""
    volume, best_y = 0.0, ref[1]
    for x, y in sorted(points, key=lambda p: -p[0]):
        if y > best_y and x > ref[0]:
            volume += (x - ref[0]) * (y - best_y)
            best_y = y
    return volume


def test_benchmark_tool_trains_evaluates_and_reports_the_front(tmp_path):
    benchmark = load_tool("studies/mo_benchmark")
    result = benchmark.main(["--task", HOPPER, "--variant", "pci", "--steps", "2048", "--num-envs", "4",
                             "--preferences", "3", "--episodes", "2", "--out", str(tmp_path)])
    saved = json.loads((tmp_path / "result.json").read_text())
    assert (tmp_path / "pareto.png").is_file()
    assert saved["env_steps"] == 2048 and len(saved["rows"]) == 3
    points = [row["mean_return"] for row in saved["rows"]]
    assert saved["hypervolume"] == pytest.approx(_hypervolume_2d(points, (-100.0, -100.0)), rel=1e-9)
    assert result["num_points"] == len(saved["front"]) >= 1


def test_three_objective_evaluation_covers_the_simplex_lattice():
    preferences = load_tool("studies/mo_benchmark").evaluation_preferences(3, 11, 6)
    assert len(preferences) == 28  # (6 + 2 choose 2)
    points = np.array(preferences)
    np.testing.assert_allclose(points.sum(1), 1.0, atol=1e-6)
    assert (points >= 0).all()
    for vertex in np.eye(3):
        assert np.abs(points - vertex).sum(1).min() < 1e-6


def test_benchmark_evaluates_on_a_step_grid_and_keeps_each_evaluations_returns(tmp_path):
    """4 envs x 128 steps = 512 per update; a 600-step grid lands after updates 2 and 3 (1024 and 1536 steps)."""
    benchmark = load_tool("studies/mo_benchmark")
    benchmark.main(["--task", HOPPER, "--variant", "pci", "--steps", "1536", "--num-envs", "4", "--preferences", "3",
                    "--episodes", "1", "--eval-every", "600", "--out", str(tmp_path)])
    saved = json.loads((tmp_path / "result.json").read_text())
    assert [h["env_steps"] for h in saved["history"]] == [1024, 1536]
    low, high = np.array(benchmark.OBJECTIVE_RANGES[HOPPER])
    preferences = np.array(saved["preferences"])
    for evaluation in saved["history"]:
        returns = np.array(evaluation["mean_returns"])
        assert returns.shape == (3, 2)
        by_hand = np.mean([lam @ ((r - low) / (high - low)) for lam, r in zip(preferences, returns)])
        assert evaluation["expected_utility"] == pytest.approx(by_hand, rel=1e-9)
    assert saved["history"][-1]["mean_returns"] == [row["mean_return"] for row in saved["rows"]]
    mass = np.array(saved["routing_mass"]["per_expert"])  # [experts, rollouts]
    assert mass.shape == (5, 3) and saved["routing_mass"]["iterations"] == [0, 1, 2]
    np.testing.assert_allclose(mass.sum(0), 1.0, atol=1e-5)


def test_evaluation_grid_is_in_env_steps_and_ends_at_the_last_update():
    grid = load_tool("studies/mo_benchmark").evaluation_iterations
    # 2048 steps per update, 2M steps: 977 updates; 250k-step marks after updates 123, 245, ..., 977 (= the last)
    iterations = grid(977, 2048, 250_000)
    assert iterations[:2] == [123, 245] and iterations[-1] == 977 and len(iterations) == 8
    assert all(it * 2048 >= k * 250_000 > (it - 1) * 2048 for k, it in enumerate(iterations, start=1))
    assert grid(10, 2048, 0) == [10]


def test_the_matched_gate_has_pcis_expert_count_and_parameter_count():
    """The paper's ablation swaps the routing only: same number of experts, parameters as close as a whole expert
    width allows (within 1.5% here: one unit of width is 400-900 parameters)."""
    from pchc_rsl.configs import matched_gate, task_config

    for task, experts in [("mo-halfcheetah-v5", 5), ("mo-hopper-v5", 6)]:
        cfg = task_config(task)
        env = MOGymVecEnv(cfg.env, 1, "cpu", 0)
        obs, groups = env.get_observations(), {"actor": cfg.runner.obs_groups["actor"]}
        pci = matched_gate.build_actor(cfg.runner.actor, obs, groups, env.num_actions)
        gated_cfg, counts = matched_gate.matched_gate(cfg.runner.actor, obs, groups, env.num_actions)
        gated = matched_gate.build_actor(gated_cfg, obs, groups, env.num_actions)
        env.close()
        assert type(gated).__name__ == "GatedMoEActor" and gated.mlp.experts.weights[0].shape[0] == experts
        assert pci.mlp.positions.shape[0] == experts
        n_pci, n_gated = (sum(p.numel() for p in m.parameters()) for m in (pci, gated))
        assert (counts["pci"], counts["gated"]) == (n_pci, n_gated)
        assert abs(n_gated - n_pci) / n_pci < 0.015
    # mo-halfcheetah-v5 by hand: 17 observations + 2 preferences in, 6 action means out, 6 log-stds.
    # PCI: 5 experts x (19*64 + 64 + 64*64 + 64 + 64*6 + 6) + 6 = 29,156.
    # Gate with [62, 62] experts: 5 x (19*62 + 62 + 62*62 + 62 + 62*6 + 6) + gate (19*64 + 64 + 64*5 + 5) + 6 = 29,231.
    assert gated_counts("mo-halfcheetah-v5", matched_gate) == (29_156, 29_231, [62, 62])


def test_residual_experts_are_sized_like_pci_by_hand():
    """mo-halfcheetah-v5 residual experts: a shared network and 5 experts, all [57, 57]: 6 x (19*57 + 57 + 57*57 + 57
    + 57*6 + 6) + 6 = 28,770 (one unit wider, [58, 58]: 29,724), the closest to PCI's 29,156."""
    import copy

    from pchc_rsl.configs import matched_gate, task_config

    cfg = task_config("mo-halfcheetah-v5")
    env = MOGymVecEnv(cfg.env, 1, "cpu", 0)
    residual = copy.deepcopy(cfg.runner.actor)
    residual.kwargs["residual_experts"] = True
    sized, counts = matched_gate.matched_pci_variant(cfg.runner.actor, residual, env.get_observations(),
                                                     {"actor": cfg.runner.obs_groups["actor"]}, env.num_actions)
    env.close()
    per_network = 19 * 57 + 57 + 57 * 57 + 57 + 57 * 6 + 6
    assert counts == {"pci": 29_156, "matched": 6 * per_network + 6, "expert_hidden_dims": [57, 57]}
    assert sized.hidden_dims == [57, 57] and sized.kwargs["residual_experts"] is True


def gated_counts(task, matched_gate):
    from pchc_rsl.configs import task_config

    cfg = task_config(task)
    env = MOGymVecEnv(cfg.env, 1, "cpu", 0)
    _, counts = matched_gate.matched_gate(cfg.runner.actor, env.get_observations(),
                                          {"actor": cfg.runner.obs_groups["actor"]}, env.num_actions)
    env.close()
    return counts["pci"], counts["gated"], counts["expert_hidden_dims"]


@pytest.mark.slow
def test_an_interrupted_benchmark_resumes_and_redoes_a_lost_evaluation_exactly(tmp_path):
    """Run 3 updates evaluated after updates 2 and 3; then lose everything after update 2's checkpoint, as a run
    stopped during its evaluation would, and resume: the lost evaluation is redone from the checkpoint."""
    benchmark = load_tool("studies/mo_benchmark")
    argv = ["--task", HOPPER, "--variant", "pci", "--steps", "1536", "--num-envs", "4", "--preferences", "3",
            "--episodes", "1", "--eval-every", "600", "--out", str(tmp_path)]
    benchmark.main(argv)
    first = json.loads((tmp_path / "result.json").read_text())
    for name in ["result.json", "progress.json", "train/model_2.pt", "train/model_final.pt"]:
        (tmp_path / name).unlink()
    benchmark.main([*argv, "--resume"])
    resumed = json.loads((tmp_path / "result.json").read_text())
    assert [h["env_steps"] for h in resumed["history"]] == [1024, 1536]
    assert resumed["history"][0] == first["history"][0]  # same checkpoint, same seeded episodes
    assert resumed["resumed"] == 1 and resumed["cpu_seconds_complete"] is False
    assert resumed["routing_mass"]["iterations"] == [0, 1, 2]
    assert (tmp_path / "train_resumed1" / "model_2.pt").is_file()  # the continued training's own folder
    assert benchmark.main([*argv, "--resume"])["history"] == resumed["history"]  # finished: left as it is
    # stopped after its last checkpoint and evaluation: nothing is trained or evaluated again
    (tmp_path / "result.json").unlink()
    (tmp_path / "train_resumed1" / "model_final.pt").unlink()
    again = benchmark.main([*argv, "--resume"])
    assert again["history"] == resumed["history"] and again["resumed"] == 2
    assert not list((tmp_path / "train_resumed2").glob("model_[0-9]*.pt"))
