"""Reward terms for the G1 tasks: ``term(env, **params) -> Tensor[N]``, weighted and grouped by the task config.

The env multiplies each term by its weight and the policy step dt and adds it to the term's group. Terms read the
env's parts: ``env.robot`` (state), ``env.feet`` (contacts, strides), ``env.pushes`` (the after-disturb window).
"""

from __future__ import annotations

import weakref

import torch

_JOINT_COLUMNS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def track_lin_vel_xy(env, std: float) -> torch.Tensor:
    """exp(-||v_cmd_xy - v_base_xy||^2 / std^2), base frame."""
    return torch.exp(-((env.commands[:, :2] - env.robot.base_lin_vel[:, :2]) ** 2).sum(-1) / std**2)


def track_ang_vel_z(env, std: float) -> torch.Tensor:
    """exp(-(w_cmd - w_z)^2 / std^2)."""
    return torch.exp(-((env.commands[:, 2] - env.robot.base_ang_vel[:, 2]) ** 2) / std**2)


def track_average_lin_vel_xy(env, std: float) -> torch.Tensor:
    """exp(-||v_cmd_xy - v_avg_xy||^2 / std^2) of the base-frame velocity averaged over the last steps
    (``env.command.velocity_average``): a narrow kernel that pays being right on average, which the sway of every
    step hides from a kernel on the instantaneous velocity."""
    return torch.exp(-((env.commands[:, :2] - env.command.velocity_average[:, :2]) ** 2).sum(-1) / std**2)


def track_average_yaw_rate(env, std: float) -> torch.Tensor:
    """exp(-(w_cmd - w_avg)^2 / std^2) of the yaw rate averaged over the last steps
    (``env.command.velocity_average``)."""
    return torch.exp(-((env.commands[:, 2] - env.command.velocity_average[:, 2]) ** 2) / std**2)


def heading_hold(env, std: float) -> torch.Tensor:
    """exp(-e^2 / std^2) of the heading error e: the base's yaw against the yaw its yaw-rate commands integrate to
    since the command was set. A tracking kernel on the yaw rate itself barely sees a bias of a few degrees per
    second under the gait's own yaw oscillation; the heading error integrates that bias, so walking straight when
    told to (and turning by as much as told) pays."""
    return torch.exp(-(env.command.heading_error**2) / std**2)


def position_hold(env, std: float) -> torch.Tensor:
    """exp(-||e||^2 / std^2) of the position error e: the base against where its commands take a body since the
    command was set or a push's window closed (``env.command.path``). Biases of a few cm/s, which the velocity
    kernels barely see, add up in e; so do the lag after each change of command and a drift while told to stand.
    Inside a push's window it pays in full: the disturbance objective, not the task, prices the drift there."""
    return torch.exp(-(env.command.path.error(env.robot.base_pos[:, :2]) ** 2).sum(-1) / std**2)


def flat_orientation(env) -> torch.Tensor:
    """||g_xy||^2 of gravity in the base frame: 0 when upright."""
    return (env.robot.projected_gravity[:, :2] ** 2).sum(-1)


def base_height(env, target: float) -> torch.Tensor:
    """(z_pelvis - target)^2."""
    return (env.robot.base_pos[:, 2] - target) ** 2


def commanded_to_move(env, min_command: float = 0.1) -> torch.Tensor:
    """[N] bool: a speed of at least ``min_command`` (m/s) or a yaw rate of at least as much (rad/s) is commanded;
    turning on the spot takes steps too."""
    return (env.commands[:, :2].norm(dim=-1) >= min_command) | (env.commands[:, 2].abs() >= min_command)


def feet_air_time(env, threshold: float, max_air: float | None = None) -> torch.Tensor:
    """Sum over touchdowns of (air time - threshold), only while the robot is told to move (legged_gym's term).
    ``max_air`` caps the air time counted, so swings longer than it earn no more (hops and held-up feet)."""
    moving = commanded_to_move(env)
    air = env.feet.last_air_time if max_air is None else env.feet.last_air_time.clamp(max=max_air)
    return ((air - threshold) * env.feet.first_contact).sum(-1) * moving


def single_stance(env, min_command: float = 0.1) -> torch.Tensor:
    """1 while exactly one foot is on the ground and the robot is told to move (``commanded_to_move``; legged_gym's
    biped no-fly term): pays walking, in which the feet take turns, and neither hopping (both feet leave the ground
    together) nor shuffling in double support."""
    moving = commanded_to_move(env, min_command)
    return (env.feet.contact.sum(-1) == 1).float() * moving


def backward_touchdown(env, min_command: float = 0.1) -> torch.Tensor:
    """Touchdowns (count) whose step points backward, along the base heading, while a speed of at least
    ``min_command`` is commanded: short backward shuffles, which r_stride pays nothing but charges nothing either,
    and which the evaluation counts. Not in the walking config: docs/design.md, "Gait terms"."""
    moving = env.commands[:, :2].norm(dim=-1) >= min_command
    backward = env.feet.first_contact & (env.feet.step_vector[..., 0] < 0)
    return backward.float().sum(-1) * moving


def fall(env) -> torch.Tensor:
    """1 / dt where the robot fell at this step, else 0: with weight -c a fall costs c of return, once (a term of the
    task group, so every preference pays it; the objectives' ``fall_cost`` charges it to one objective only)."""
    return charged_fall(env, 1.0)


def joint_deviation(env, joints: list[str]) -> torch.Tensor:
    """sum_j (q_j - q_default_j)^2 over the env's joints whose names contain one of ``joints`` (e.g. "hip_roll"):
    unitree_rl_gym's G1 hip_pos term, which keeps the legs from splaying into a straddle."""
    columns = joint_columns(env, joints)
    error = env.robot.joint_pos[:, columns] - env.default_joint_pos[columns]
    return (error**2).sum(-1)


def joint_columns(env, joints: list[str]) -> torch.Tensor:
    """[k] indices, on the env's device, of its joints whose names contain one of ``joints``; made once per env and
    list (an index made from a Python list at every step is copied to a GPU with a wait)."""
    cache = _JOINT_COLUMNS.setdefault(env, {})
    key = tuple(joints)
    if key not in cache:
        cache[key] = torch.tensor([i for i, name in enumerate(env.cfg.joints) if any(part in name for part in joints)],
                                  dtype=torch.long, device=env.device)
    return cache[key]


def feet_slip(env) -> torch.Tensor:
    """Sum over feet in contact of the squared horizontal foot speed."""
    return (env.feet.contact * (env.robot.foot_vel[..., :2] ** 2).sum(-1)).sum(-1)


def feet_clearance(env, target_height: float) -> torch.Tensor:
    """Swing feet away from target_height, weighted by their horizontal speed."""
    speed = env.robot.foot_vel[..., :2].norm(dim=-1)
    return (~env.feet.contact * (env.robot.foot_pos[..., 2] - target_height) ** 2 * speed).sum(-1)


def joint_limits(env) -> torch.Tensor:
    """How far joints are outside 90% of their range (rad, summed)."""
    low, high = env.soft_joint_limits[:, 0], env.soft_joint_limits[:, 1]
    q = env.robot.joint_pos
    return ((low - q).clamp(min=0) + (q - high).clamp(min=0)).sum(-1)


def torques(env) -> torch.Tensor:
    """sum_j tau_j^2."""
    return (env.robot.torques**2).sum(-1)


def action_rate(env) -> torch.Tensor:
    """sum_j (a_t - a_{t-1})^2."""
    return ((env.actions - env.last_actions) ** 2).sum(-1)


def alive(env) -> torch.Tensor:
    return torch.ones(env.num_envs, device=env.device)


def stride(env, along_heading: bool = True, min_command: float = 0.1, speed_std: float | None = None,
           along_command: bool = False, fall_cost: float = 0.0, at_command_speed: bool = False,
           path_std: float | None = None, average_speed_std: float | None = None,
           commanded_length: bool = False, height_target: float = 0.74,
           height_std: float | None = None) -> torch.Tensor:
    """The paper's r_stride = I_contact ||p_current - p_last_contact||, read per step: every step a foot is in
    contact (I_contact, a state) it pays the length of the step that put it there, from the point where it last
    touched the ground before this stance (p_last_contact) to where it stands now (p_current).

    Why this reading: paid once per touchdown (the earlier reading), the sum over an episode is the feet's total
    horizontal travel, which at a given walking speed is the same for any step length; only extra foot motion
    (sideways and backward taps) raised it. Paid per stance step, a step of length L is paid for as long as its
    stance lasts, which grows with L at a given speed. Worked example, 0.5 m/s for 10 s with each foot on the ground
    60% of the time: strides of 0.4 m (12.5 per foot) pay 0.4 m x 0.48 s each, 2.4 per foot; strides of 0.8 m
    (6.25 per foot) pay 0.8 m x 0.96 s each, 4.8 per foot (times dt, as every term). The per-touchdown reading pays
    5.0 m per foot for both.

    Two documented changes to the paper's norm: ``along_heading`` pays only the forward part of the step (along the
    base heading at the touchdown, never negative), so that straddling or side steps earn nothing; and nothing is
    paid while the commanded speed is below ``min_command`` (m/s), where one step held in a split stance would
    otherwise be paid for as long as the robot stands. ``along_command`` pays the part of the step along the
    commanded walking direction instead (the heading's forward part when walking straight ahead), so that a
    walker steered sideways or backwards is paid for the steps that go where it is told.

    ``speed_std`` (m/s; None: off) pays the step only as far as the base keeps the commanded velocity, times
    exp(-||v_cmd_xy - v_base_xy||^2 / speed_std^2). Without it longer steps at the same cadence pay more by walking
    faster: the walker trained from scratch on this reading reached 1.5 m/s at (0, 1) when told 0.5 (its forward
    step 0.48 m at 2.9 steps/s). With it, at the commanded speed the reading above holds (the gate is 1), and a
    longer step can only be bought with a slower cadence, the paper's "longer strides" at a given speed
    (docs/design.md, "The stride speed gate").

    ``at_command_speed`` pays a step walked faster than commanded as the step that the same cadence would make at
    the commanded speed: length x min(1, |v_cmd| / v), v the base's speed along the commanded direction. At a given
    cadence the step grows with v, so even gated the pay grows with v up to where v (v - |v_cmd|) = speed_std^2 / 2
    (0.56 m/s told 0.5, 0.38 told 0.3, for the gate at 0.25); scaled this way it stops growing at the command, and
    only a slower cadence earns a longer step. Measured, it does not hold the stride end to its command
    (docs/design.md, "Action noise"), so the walking config leaves it off.

    ``path_std`` (m; None: off) multiplies the pay by ``position_hold`` with path_std as its std, so that a step is
    paid only as far as the base stays where its commands take it: a few cm/s too fast barely lower the speed gate,
    but they add up in the distance from the path. Measured, it does not hold the stride end to its command either
    (docs/design.md, "Action noise"), so the walking config leaves it off.

    ``average_speed_std`` (m/s; None: off) gates the step on the averaged velocity (``env.command.velocity_average``, as
    ``track_average_lin_vel_xy`` reads it): exp(-||v_cmd_xy - v_avg_xy||^2 / average_speed_std^2). The base sways
    sideways with every step (the released walker's sideways velocity has a std of 0.05-0.08 m/s, most at the stride
    end; forward 0.02-0.04; `tools/diagnostics/velocity_sway.py`), so a narrow gate on the instantaneous velocity
    charges the gait's sway as much as a bias of the mean speed; on the average (std 0.004-0.017) it charges the bias.
    Measured, it does not hold the stride end to its command either (docs/design.md, "Action noise"), so the walking
    config leaves it off.

    ``commanded_length`` pays every step as the step that its cadence makes at the commanded speed, faster or slower:
    length x |v_cmd| / v, v the averaged velocity (``env.command.velocity_average``) along the commanded direction, at
    least half the command. ``at_command_speed`` scales only the faster steps, so a walker unsure of its speed loses pay
    when slow and keeps it when fast; scaled both ways, the pay depends on the cadence alone and a bias either way
    costs the same. Measured alone over 200 iterations, it does not hold the stride end to its command either
    (docs/design.md, "Action noise"); the walking config pays it, as the released walker trained.

    ``height_std`` (m; None: off) pays a step only as far as the pelvis stays up: times
    exp(-min(0, z - height_target)^2 / height_std^2), 1 at or above ``height_target`` (m). Without it the walker sinks
    into a crouch as the stride's weight grows, whatever the style reward pays (docs/design.md, "A style reward that
    pulls").

    ``fall_cost``: as r_disturb's. A fall ends the episode and with it the stride pay, which at the end that weights
    stride alone is the only price of falling. Not in the paper's equation: docs/design.md, "Fall costs"."""
    step = env.feet.stance_step  # [N, foot, (forward, lateral)], 0 in the air
    commanded_speed = env.commands[:, :2].norm(dim=-1)
    direction = env.commands[:, :2] / commanded_speed.unsqueeze(-1).clamp(min=1e-6)
    if along_command:
        length = (step * direction.unsqueeze(1)).sum(-1).clamp(min=0.0)
    elif along_heading:
        length = step[..., 0].clamp(min=0.0)
    else:
        length = step.norm(dim=-1)
    reward = length.sum(-1) * (commanded_speed >= min_command)
    if at_command_speed:
        speed = (env.robot.base_lin_vel[:, :2] * direction).sum(-1)
        reward = reward * (commanded_speed / speed.clamp(min=1e-6)).clamp(max=1.0)
    if commanded_length:
        speed = (env.command.velocity_average[:, :2] * direction).sum(-1)
        reward = reward * commanded_speed / speed.clamp(min=1e-6).maximum(commanded_speed / 2)
    if speed_std is not None:
        reward = reward * track_lin_vel_xy(env, speed_std)
    if average_speed_std is not None:
        reward = reward * track_average_lin_vel_xy(env, average_speed_std)
    if path_std is not None:
        reward = reward * position_hold(env, path_std)
    if height_std is not None:
        sunk = (env.robot.base_pos[:, 2] - height_target).clamp(max=0.0)
        reward = reward * torch.exp(-(sunk**2) / height_std**2)
    return reward - charged_fall(env, fall_cost)


def disturbance(env, vertical: bool = False, fall_cost: float = 0.0, com: bool = False,
                capture_point: float = 0.0) -> torch.Tensor:
    """The paper's r_disturb = 1_after-disturb (-||x_base - x_ref|| - |(v_base - v_ref) . d|).

    Both terms are relative to the same reference: x_ref = x_last + v_ref t moves at the commanded velocity v_ref
    (turned into the world frame at the push), so walking on as commanded is not penalised and stopping is not
    rewarded; with no command v_ref = 0 and this is the paper's equation. The position term is horizontal unless
    ``vertical``: then the base's height change since the push counts too (the paper's 3-D x_base), so a fall
    costs its drop of about 0.5 m on top of the horizontal drift a recovering step also has.

    ``fall_cost``: a fall (``env.fell_this_step()``) also costs this much return, once. Without it a fall is the
    cheapest answer to a strong push under r_disturb alone: the displacement terms stop when the episode ends.
    Not in the paper's equation; why and what it changed: docs/design.md, "Fall costs".

    ``com``: x_base is the whole-body COM instead of the pelvis, the point whose displacement Table I reports, so
    the reward charges what the table measures (docs/design.md, "The COM option of r_disturb").

    ``capture_point`` (a weight; 0: off): inside the window also charges this times ``capture_point_error``. The terms
    above charge the distance from where the robot was pushed, so the step that would catch it, which carries it
    further, costs under them; this one pays that step as it lands. Not in the paper's equation: docs/design.md,
    "The capture point"."""
    pushes = env.pushes
    position = pushes.com_deviation(env.robot) if com else pushes.deviation(env.robot)
    if vertical:
        position = torch.cat([position, pushes.height_change(env.robot).unsqueeze(-1)], dim=-1)
    charged = position.norm(dim=-1) + pushes.relative_velocity_along_push(env.robot)
    if capture_point:
        charged = charged + capture_point * capture_point_error(env)
    reward = -(pushes.active * charged)
    return reward - charged_fall(env, fall_cost)


def capture_point_error(env, gravity: float = 9.81) -> torch.Tensor:
    """[N] how far the capture point of the whole-body COM lies from the middle of the feet on the ground (of both
    feet when neither is), m. x_cp = x_com + v_com / omega, omega = sqrt(g / z_com) (the linear inverted pendulum):
    where a foot must land for the robot to come to rest over it."""
    robot = env.robot
    omega = (gravity / robot.com_pos[:, 2].clamp(min=0.1)).sqrt()
    point = robot.com_pos[:, :2] + robot.com_vel[:, :2] / omega.unsqueeze(-1)
    on_ground = env.feet.contact.float()  # [N, 2]
    weights = torch.where(on_ground.sum(-1, keepdim=True) > 0, on_ground, torch.ones_like(on_ground))
    support = (robot.foot_pos[..., :2] * weights.unsqueeze(-1)).sum(1) / weights.sum(-1, keepdim=True)
    return (point - support).norm(dim=-1)


def charged_fall(env, fall_cost: float) -> torch.Tensor | float:
    """[N] fall_cost / dt where the robot fell at this step (RewardGroups multiplies by dt: a fall costs fall_cost
    of return, once), else 0; without a cost just 0, so the terms that take none allocate nothing per step."""
    if not fall_cost:
        return 0.0
    return fall_cost / env.dt * env.fell_this_step().float()


def energy(env, k_tau: float, k_p: float, fall_cost: float = 0.0) -> torch.Tensor:
    """The paper's r_energy = -k_tau sum_j tau_j^2 - k_p sum_j |dq_j| |tau_j|, averaged over the physics substeps.

    ``fall_cost``: as r_disturb's. A fall that ends the episode (``terminate_on_fall``) also ends r_energy's cost,
    so without it falling after standing is the cheapest way to save energy at lambda = (1, 0). Not in the paper's
    equation: docs/design.md, "Fall costs"."""
    tau, dq = env.robot.torques_substeps, env.robot.joint_vel_substeps  # [N, K, J]
    per_substep = -k_tau * (tau**2).sum(-1) - k_p * (dq.abs() * tau.abs()).sum(-1)
    return per_substep.mean(dim=1) - charged_fall(env, fall_cost)


def pelvis_height(env, target: float) -> torch.Tensor:
    """min(z_pelvis, target) / target in [0, 1]: progress towards standing (HoST rewards head height likewise)."""
    return env.robot.base_pos[:, 2].clamp(min=0.0, max=target) / target


def upright(env) -> torch.Tensor:
    """How much the pelvis' up axis points up, in [0, 1]."""
    return (-env.robot.projected_gravity[:, 2]).clamp(min=0.0)


def standing_posture(env, min_height: float, std: float) -> torch.Tensor:
    """Once standing (pelvis above min_height), exp(-||q - q_default||^2 / std^2): HoST's post-standing target pose."""
    error = ((env.robot.joint_pos - env.default_joint_pos) ** 2).sum(-1)
    return (env.robot.base_pos[:, 2] > min_height) * torch.exp(-error / std**2)
