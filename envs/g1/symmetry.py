"""Left-right mirror of a G1Env's observations and actions: rsl-rl's symmetry extension calls ``augment_with_mirror``
(``symmetry_cfg.data_augmentation_func = "pchc_rsl.envs.g1.symmetry:augment_with_mirror"``).

Every group is a signed permutation of its columns (robots/g1/symmetry.py for the rules): joints swap sides, roll
and yaw joints change sign, polar vectors negate y, the angular velocity negates x and z, the command (v_x, v_y,
w_z) becomes (v_x, -v_y, -w_z), the feet swap; lambda and every scalar (height, eta, push timing) are unchanged, and
so is every reward group (each objective is symmetric: stride length, displacement after a push).
"""

from __future__ import annotations

import weakref

import torch
from tensordict import TensorDict

from pchc_rsl.robots.g1.symmetry import joint_mirror

_AXIAL, _POLAR, _COMMAND = [-1.0, 1.0, -1.0], [1.0, -1.0, 1.0], [1.0, -1.0, -1.0]

QUANTITY_MIRROR = {
    # policy frame (envs/g1/observations.py: frame_layout)
    "base_ang_vel": _AXIAL,
    "projected_gravity": _POLAR,
    "joint_pos_minus_default": "joints",
    "joint_vel": "joints",
    "last_action": "joints",
    "action_scale_eta": None,
    "joint_pos": "joints",  # the AMP window
    "amp_root_velocity": _COMMAND,  # (forward, sideways, yaw rate) as the command
    "velocity_command": _COMMAND,
    # privileged state (G1Env.privileged_parts)
    "base_lin_vel": _POLAR,
    "base_height": None,
    "foot_contact": "feet",
    "push_active": None,
    "push_direction_xy": [1.0, -1.0],
    "push_deviation_xy": [1.0, -1.0],
    "push_timing": None,
    "push_size": None,
    "path_error_xy": [1.0, -1.0],  # base heading frame
    "heading_error": [-1.0],
    "velocity_average": _COMMAND,  # (forward, sideways, yaw rate) as the command
}
"""How the mirror acts on each quantity: None (unchanged), a sign per component, "joints" or "feet" (swap)."""


def _signed_permutation(layout: list[tuple[str, int]], joint_index: list[int], joint_sign: list[float]):
    """[D] index and sign over a vector laid out as ``layout`` ((name, size) pairs)."""
    index, sign, start = [], [], 0
    for name, size in layout:
        if name not in QUANTITY_MIRROR:
            raise KeyError(f"No mirror rule for the observed quantity '{name}': add it to QUANTITY_MIRROR.")
        rule = QUANTITY_MIRROR[name]
        if rule == "joints":
            part_index, part_sign = joint_index, joint_sign
        elif rule == "feet":
            part_index, part_sign = [1, 0], [1.0, 1.0]
        else:
            part_index, part_sign = list(range(size)), ([1.0] * size if rule is None else rule)
        if len(part_index) != size or len(part_sign) != size:
            raise ValueError(f"'{name}' has {size} columns; its mirror rule covers {len(part_index)}.")
        index += [start + i for i in part_index]
        sign += part_sign
        start += size
    return index, sign


class G1Mirror:
    """The signed permutations of one env's observation groups and actions, built once from its layouts."""

    def __init__(self, env) -> None:
        joint_index, joint_sign = joint_mirror(list(env.cfg.joints))
        frame = env.observations.frame_layout
        frames = env.cfg.history_length + 1
        privileged = [(name, value.shape[-1]) for name, value in env.privileged_parts()]
        layouts = {
            "policy": frame * frames,
            "critic": frame * frames + privileged,
            "amp": env.observations.amp_frame_layout * env.cfg.amp_window,
        }
        device = env.device
        self.groups = {}
        for group, layout in layouts.items():
            index, sign = _signed_permutation(layout, joint_index, joint_sign)
            self.groups[group] = (torch.tensor(index, device=device), torch.tensor(sign, device=device))
        self.actions = (torch.tensor(joint_index, device=device), torch.tensor(joint_sign, device=device))

    @staticmethod
    def apply(values: torch.Tensor, permutation: tuple[torch.Tensor, torch.Tensor]) -> torch.Tensor:
        """``index_select`` rather than advanced indexing: the same columns, faster on a CPU
        (tools/benchmarks/bench_update.py)."""
        index, sign = permutation
        return values.index_select(-1, index.to(values.device)) * sign.to(values.device, values.dtype)

    def observations(self, obs: TensorDict) -> TensorDict:
        """The mirror of every group this env makes (other groups, lambda among them, unchanged and not copied)."""
        mirrored = {group: self.apply(values, self.groups[group]) if group in self.groups else values
                    for group, values in obs.items()}
        return TensorDict(mirrored, batch_size=obs.batch_size, device=obs.device)

    def action(self, actions: torch.Tensor) -> torch.Tensor:
        return self.apply(actions, self.actions)


_MIRRORS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def mirror_of(env) -> G1Mirror:
    """The env's G1Mirror, built on first use."""
    if env not in _MIRRORS:
        _MIRRORS[env] = G1Mirror(env)
    return _MIRRORS[env]


def augment_with_mirror(env, obs: TensorDict | None = None, actions: torch.Tensor | None = None):
    """rsl-rl's data augmentation function: the batch followed by its mirror ([2B, ...]); None stays None."""
    mirror = mirror_of(env)
    obs_out = None if obs is None else torch.cat([obs, mirror.observations(obs)], dim=0)
    actions_out = None if actions is None else torch.cat([actions, mirror.action(actions)], dim=0)
    return obs_out, actions_out
