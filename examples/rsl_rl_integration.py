"""The PCI actor and MultiCriticPPO in your own rsl-rl project: an environment written from scratch, rsl-rl's own
OnPolicyRunner, and the two class names changed in the config.

    pip install -e .        # or: pip install pchc-rsl
    python examples/rsl_rl_integration.py [--onnx policy.onnx]

The environment is a point mass between two goals; its two objectives are the negative squared distances to goal A
and to goal B. What PCHC asks of an environment is all here:
  - an observation group "preference": lambda [N, m], raw, on the simplex, drawn at every reset;
  - extras["reward_groups"]: [N, 1 + m], the preference-invariant task reward, then each objective's raw reward.
After training, one policy goes to goal A at lambda = (1, 0) and to goal B at lambda = (0, 1).
"""

from __future__ import annotations

import argparse

import torch
from tensordict import TensorDict

from rsl_rl.env import VecEnv
from rsl_rl.runners import OnPolicyRunner

GOALS = torch.tensor([[1.0, 0.0], [0.0, 1.0]])

TRAIN_CFG = {
    "num_steps_per_env": 16,
    "save_interval": 1000,
    # the actor and the critics read lambda: add the "preference" group to both
    "obs_groups": {"actor": ["policy", "preference"], "critic": ["critic", "preference"]},
    # the two class names that make an rsl-rl config a PCHC one
    "algorithm": {"class_name": "pchc_rsl.algorithms:MultiCriticPPO", "learning_rate": 3e-3, "gamma": 0.95},
    "actor": {"class_name": "pchc_rsl.modules:PCIActor", "hidden_dims": [64, 64], "history_length": 0,
              "distribution_cfg": {"class_name": "rsl_rl.modules:GaussianDistribution", "init_std": 0.3}},
    "critic": {"class_name": "pchc_rsl.modules:PreferenceMLPModel", "hidden_dims": [64, 64]},
    "logger": "tensorboard",
}


class TwoGoalEnv(VecEnv):
    """N point masses in the plane; actions move them; an episode lasts ``episode_length`` steps."""

    def __init__(self, num_envs: int, episode_length: int = 16) -> None:
        self.num_envs, self.num_actions, self.max_episode_length = num_envs, 2, episode_length
        self.device, self.cfg = "cpu", {}
        self.pos = torch.zeros(num_envs, 2)
        self.preference = torch.zeros(num_envs, 2)
        self.episode_length_buf = torch.zeros(num_envs, dtype=torch.long)
        self.fixed_preference = None  # set to evaluate at one lambda
        self.reset(torch.arange(num_envs))

    def reset(self, ids: torch.Tensor) -> None:
        self.pos[ids] = 0.0
        self.episode_length_buf[ids] = 0
        if self.fixed_preference is not None:
            self.preference[ids] = self.fixed_preference
        else:  # a fresh lambda per episode, uniform on the simplex
            self.preference[ids] = torch.distributions.Dirichlet(torch.ones(2)).sample((len(ids),))

    def get_observations(self) -> TensorDict:
        t = self.episode_length_buf.float().unsqueeze(1) / self.max_episode_length
        state = torch.cat([self.pos, t], dim=-1)
        return TensorDict({"policy": state.clone(), "critic": state.clone(), "preference": self.preference.clone()},
                          batch_size=[self.num_envs])

    def step(self, actions: torch.Tensor):
        self.pos += 0.15 * actions.clamp(-1.0, 1.0)
        self.episode_length_buf += 1
        objectives = -((self.pos.unsqueeze(1) - GOALS) ** 2).sum(-1)  # [N, 2]: goal A, goal B
        task = torch.zeros(self.num_envs, 1)  # nothing preference-invariant in this task
        time_outs = self.episode_length_buf >= self.max_episode_length
        extras = {"reward_groups": torch.cat([task, objectives], dim=-1), "time_outs": time_outs.clone(), "log": {}}
        rewards = task[:, 0] + (self.preference * objectives).sum(-1)  # what rsl-rl logs; PCHC reads the groups
        self.reset(time_outs.nonzero().squeeze(-1))
        return self.get_observations(), rewards, time_outs.clone(), extras


def final_position(runner: OnPolicyRunner, env: TwoGoalEnv, preference) -> torch.Tensor:
    """Mean position of the envs at the end of an episode run at one lambda."""
    env.fixed_preference = torch.tensor(preference)
    env.reset(torch.arange(env.num_envs))
    policy = runner.get_inference_policy()
    obs = env.get_observations()
    with torch.inference_mode():
        for _ in range(env.max_episode_length - 1):
            obs, *_ = env.step(policy(obs))
    return env.pos.mean(0)


def main(argv: list[str] | None = None) -> dict[str, list[float]]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--iterations", type=int, default=80)
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--onnx", metavar="FILE", help="also export the policy to this ONNX file")
    args = parser.parse_args(argv)
    torch.manual_seed(args.seed)
    env = TwoGoalEnv(args.num_envs)
    runner = OnPolicyRunner(env, {k: (dict(v) if isinstance(v, dict) else v) for k, v in TRAIN_CFG.items()},
                            log_dir=None, device="cpu")
    runner.learn(args.iterations)
    ends = {}
    for name, preference in (("(1, 0)", [1.0, 0.0]), ("(0.5, 0.5)", [0.5, 0.5]), ("(0, 1)", [0.0, 1.0])):
        ends[name] = final_position(runner, env, preference).tolist()
        print(f"lambda = {name}: ends at ({ends[name][0]:.2f}, {ends[name][1]:.2f})")
    if args.onnx:
        from pchc_rsl.export.onnx_export import export_onnx

        export_onnx(runner.alg.actor, args.onnx)  # inputs "obs" and "preference"; checked against onnxruntime
        print(f"exported {args.onnx}")
    return ends


if __name__ == "__main__":
    main()
