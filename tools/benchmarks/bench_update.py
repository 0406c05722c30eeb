"""The PPO update's gathers timed against rsl-rl's, on the same rollout, in the same run.

    python tools/benchmarks/bench_update.py [--num-envs 1024] [--threads 2] [--repeats 5] \
        [--motion-files $PCHC_MOTION_DIR/lafan1_walk1_subject1.csv]

One rollout of the task as it trains (AMP with motion files, the mirror augmentation), then the update run
alternately from the same saved state (weights, optimizer, storage, random stream) with two implementations of its
row and column gathers:
- "reference": rsl-rl's mini-batch generator (advanced indexing of rows) and the mirror by advanced indexing of
  columns on a copy of every observation group;
- "current": the storage's generator and the mirror as they are (``index_select``, groups that do not mirror are
  not copied).
Prints each one's update time (median of the repeats) and their ratio, and checks that both end at the same
weights: the same update, only faster. Then the floor the update cannot go under on this machine without learning
something else: the matrix products its layers need (forward, the weight gradients, the input gradients of every
layer but the first), timed alone at the mini-batch's size, times the mini-batches of an update.
"""

from __future__ import annotations

import argparse
import copy
import statistics
import time

import torch
from tensordict import TensorDict

from rsl_rl.storage import RolloutStorage

from pchc_rsl.configs import task_config
from pchc_rsl.envs.g1 import symmetry as g1_symmetry
from pchc_rsl.storage import MultiCriticRolloutStorage
from pchc_rsl.training.build import make_runner


def reference_apply(values: torch.Tensor, permutation) -> torch.Tensor:
    index, sign = permutation
    return values[..., index] * sign.to(values.dtype)


def reference_observations(self, obs: TensorDict) -> TensorDict:
    mirrored = obs.clone()
    for group, permutation in self.groups.items():
        if group in obs.keys():
            mirrored[group] = reference_apply(obs[group], permutation)
    return mirrored


IMPLEMENTATIONS = {
    "reference": (RolloutStorage.mini_batch_generator, staticmethod(reference_apply), reference_observations),
    "current": (MultiCriticRolloutStorage.mini_batch_generator, g1_symmetry.G1Mirror.__dict__["apply"],
                g1_symmetry.G1Mirror.observations),
}


def layer_shapes(alg) -> list[tuple[int, int, bool]]:
    """(inputs, outputs, needs the input gradient) of every matrix product of the actor and the critic. The first
    linear layer of each (the actor's history encoder, the critic's) reads the observation alone: no input gradient.
    The experts read the encoder's output too, so theirs is needed."""
    shapes = []
    for model in (alg.actor, alg.critic):
        linears = [m for m in model.modules() if isinstance(m, torch.nn.Linear)]
        shapes += [(m.in_features, m.out_features, i > 0) for i, m in enumerate(linears)]
        experts = getattr(getattr(model, "mlp", None), "experts", None)
        if experts is not None:
            for weight in experts.weights:
                shapes += [(weight.shape[1], weight.shape[2], True)] * weight.shape[0]
    return shapes


def matmul_floor(alg, batch: int, repeats: int = 5) -> float:
    """Seconds of matrix products in one update: every layer's forward and weight gradient, and its input gradient
    unless it reads the observation, for ``batch`` rows, times the update's mini-batches."""
    total = 0.0
    for fan_in, fan_out, input_grad in layer_shapes(alg):
        x, w, g = torch.randn(batch, fan_in), torch.randn(fan_in, fan_out), torch.randn(batch, fan_out)
        products = [lambda: x @ w, lambda: x.T @ g] + ([lambda: g @ w.T] if input_grad else [])
        for product in products:
            product()
            start = time.perf_counter()
            for _ in range(repeats):
                product()
            total += (time.perf_counter() - start) / repeats
    return total * alg.num_learning_epochs * alg.num_mini_batches


def use(name: str) -> None:
    generator, apply, observations = IMPLEMENTATIONS[name]
    MultiCriticRolloutStorage.mini_batch_generator = generator
    g1_symmetry.G1Mirror.apply = apply
    g1_symmetry.G1Mirror.observations = observations


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="g1-walk-fast")
    parser.add_argument("--num-envs", type=int, default=1024)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5, help="updates timed per implementation, alternating")
    parser.add_argument("--motion-files", nargs="+", metavar="PATH")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    cfg = task_config(args.task)
    cfg.num_envs, cfg.env.num_threads = args.num_envs, args.threads
    if args.motion_files:
        cfg.runner.algorithm.amp_cfg.motion_files = list(args.motion_files)
    runner = make_runner(cfg)
    runner.alg.train_mode()
    alg = runner.alg
    obs = runner.rollout(runner.env.get_observations())
    with torch.inference_mode():
        alg.compute_returns(obs)
    parts = ("actor", "critic", "optimizer", "amp", "value_normalizer", "learning_rate")
    saved = copy.deepcopy(tuple(getattr(alg, name) for name in parts))  # one copy: the optimizer keeps its weights
    step, rng = alg.storage.step, torch.get_rng_state()

    def restore() -> None:
        for name, value in zip(parts, copy.deepcopy(saved)):
            setattr(alg, name, value)
        alg.storage.step = step
        torch.set_rng_state(rng)

    times: dict[str, list[float]] = {name: [] for name in IMPLEMENTATIONS}
    weights: dict[str, list[torch.Tensor]] = {}
    for repeat in range(args.repeats + 1):  # the first round warms up
        for name in IMPLEMENTATIONS:
            restore()
            use(name)
            start = time.perf_counter()
            alg.update()
            elapsed = time.perf_counter() - start
            if repeat > 0:
                times[name].append(elapsed)
            weights[name] = [p.detach().clone() for m in (alg.actor, alg.critic) for p in m.parameters()]
    use("current")
    same = all(torch.equal(a, b) for a, b in zip(weights["reference"], weights["current"]))
    reference, current = (statistics.median(times[n]) for n in ("reference", "current"))
    print(f"{args.task}, {args.num_envs} envs, {args.threads} thread(s), AMP {'on' if args.motion_files else 'off'}: "
          f"the update, median of {args.repeats}")
    print(f"  reference (rsl-rl's gathers) {reference:.3f} s, current {current:.3f} s: ratio {current / reference:.2f}")
    print(f"  all {len(times['reference'])} runs: reference {[round(t, 3) for t in times['reference']]}, "
          f"current {[round(t, 3) for t in times['current']]}")
    print(f"  the same actor and critic weights after the update: {same}")
    batch = alg.storage.num_envs * alg.storage.num_transitions_per_env // alg.num_mini_batches
    batch *= 2 if alg.symmetry is not None and alg.symmetry.use_data_augmentation else 1
    floor = matmul_floor(alg, batch)
    print(f"  the matrix products alone ({len(layer_shapes(alg))} layers, mini-batches of {batch} rows): {floor:.3f} s "
          f"per update, {floor / current:.2f} of the current update")


if __name__ == "__main__":
    main()
