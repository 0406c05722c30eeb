"""Every preference of an evaluation in one batch of envs (lambda per env), progress with the time left, and what an
interrupted evaluation leaves written."""

import io
import json

import pytest
import torch

from pchc_rsl.evaluation.progress import Progress
from pchc_rsl.evaluation.runs import run_episodes, run_preference_batch


class EpisodeCounter:
    """An env whose env i ends an episode every i + 2 steps and reports the preference it held then."""

    def __init__(self, num_envs: int) -> None:
        self.num_envs, self.max_episode_length, self.t = num_envs, 10, 0
        self.preference = torch.zeros(num_envs, 2)

    def set_preference(self, lam) -> None:
        self.preference[:] = torch.as_tensor(lam, dtype=torch.float32).expand(self.num_envs, 2)

    def reset(self) -> None:
        self.t = 0

    def get_observations(self):
        return torch.zeros(self.num_envs, 1)

    def step(self, actions):
        self.t += 1
        done = torch.tensor([self.t % (i + 2) == 0 for i in range(self.num_envs)])
        ids = done.nonzero().flatten()
        groups = torch.cat([torch.ones(self.num_envs, 1), self.preference], 1)
        metrics = {"env_ids": ids, "held": self.preference[ids, 0]}
        return None, None, done, {"reward_groups": groups, "episode_metrics": metrics}


def test_each_block_of_envs_runs_its_own_preference_to_the_episode_count():
    env = EpisodeCounter(6)
    preferences = [(1.0, 0.0), (0.5, 0.5), (0.0, 1.0)]
    runs = run_preference_batch(env, lambda obs: obs, preferences, episodes=3)
    for (lam, (results, curve)) in zip(preferences, runs):
        assert len(results) == 2 * 3  # 2 envs per preference, 3 episodes each
        assert {r["held"] for r in results} == {lam[0]}
        assert curve.shape == (10, 3) and (curve[:, 1] == lam[0]).all()
    single, _ = run_episodes(EpisodeCounter(2), lambda obs: obs, (0.25, 0.75), episodes=2)
    assert len(single) == 4 and {r["held"] for r in single} == {0.25}
    with pytest.raises(ValueError, match="7 envs cannot be split evenly among 3 preferences"):
        run_preference_batch(EpisodeCounter(7), lambda obs: obs, preferences, episodes=1)


def test_progress_shows_the_time_left_and_writes_a_line_per_tenth_to_a_log():
    log = io.StringIO()
    progress = Progress("eval", 200, stream=log)
    assert progress.line(50, now=progress.start + 30) .endswith("50/200 steps, 0:01:30 left")
    assert "estimating" in progress.line(0)
    for done in range(0, 201, 5):
        progress.update(done)
    assert len(log.getvalue().splitlines()) == 10


def interrupt_the_second_call(monkeypatch, module, name: str) -> None:
    """``module.name`` as it is, except that its second call raises KeyboardInterrupt (Ctrl-C in mid-run)."""
    original, calls = getattr(module, name), []

    def interrupted_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(module, name, interrupted_second)


def test_an_interrupted_robustness_run_leaves_the_finished_conditions_marked_partial(walk_checkpoint, tmp_path,
                                                                                       monkeypatch):
    from pchc_rsl.cli import eval as eval_cli
    from pchc_rsl.cli import eval_run
    from pchc_rsl.evaluation import robustness

    interrupt_the_second_call(monkeypatch, robustness, "evaluate_checkpoint")
    monkeypatch.setattr(eval_run, "written_partial", [])
    out = tmp_path / "rob"
    with pytest.raises(SystemExit, match="interrupted; the conditions that finished are in"):
        eval_cli.main([walk_checkpoint, "--robustness", "--condition", "nominal", "--condition", "latency 20 ms",
                       "--num-envs", "2", "--episodes", "1", "--preferences", "2", "--episode-length", "0.3",
                       "--output", str(out)])
    report = json.loads((out / "robustness.json").read_text())
    assert report["partial"] is True and report["conditions"] == ["nominal"]
    assert [r["preference"] for r in report["rows"]] == [[1.0, 0.0], [0.0, 1.0]]
    assert "**Partial**" in (out / "robustness.md").read_text()


def test_an_interrupted_evaluation_leaves_its_first_push_preset_written_marked_partial(walk_checkpoint, tmp_path,
                                                                                       monkeypatch):
    from pchc_rsl.cli import eval as eval_cli
    from pchc_rsl.cli import eval_run
    from pchc_rsl.evaluation import checkpoint

    interrupt_the_second_call(monkeypatch, checkpoint, "run_preference_batch")
    monkeypatch.setattr(eval_run, "written_partial", [])
    out = tmp_path / "eval"
    with pytest.raises(SystemExit, match="interrupted; the part that finished is in"):
        eval_cli.main([walk_checkpoint, "--num-envs", "2", "--episodes", "1", "--preferences", "2",
                       "--episode-length", "0.3", "--output", str(out)])
    results = json.loads((out / "results.json").read_text())
    assert results["partial"] is True and list(results["results"][0]["push_presets"]) == ["mild"]
    assert [r["episodes"] for r in results["results"][0]["rows"]] == [2, 2]
    assert (out / "table.md").read_text().startswith("**Partial**")
