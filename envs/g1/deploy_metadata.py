"""What running a G1 policy on a robot needs, read from the env that trained it: the exported ONNX file carries it,
so a deploy reads nothing from the training config."""

from __future__ import annotations

from pchc_rsl.robots.g1.constants import holding_gains


def deploy_metadata(env) -> dict:
    """Joints in the policy's order with their PD gains, effort limits, default pose and action scale, the
    observation layout and the control period, of a G1Env."""
    model, cfg = env.model, env.cfg
    frame = [[name, size] for name, size in env.observations.frame_layout]
    return {
        "format": 1,
        "joint_names": list(cfg.joints),
        "kp": [float(x) for x in model.actuator_gainprm[:, 0]],
        "kd": [float(-x) for x in model.actuator_biasprm[:, 2]],
        "effort_limit": [float(x) for x in model.actuator_forcerange[:, 1]],
        "default_joint_pos": env.default_joint_pos.tolist(),
        "action_scale": (env.action_scale[0] * env.joint_action_weights).tolist(),
        "action_scale_eta": float(env.action_scale[0, 0]),  # the frame's eta entry
        "joint_range": [[float(lo), float(hi)] for lo, hi in
                        (model.jnt_range[model.joint(j).id] for j in cfg.joints)],
        "action_clip": float(cfg.action_clip),
        "target": "q_target = default_joint_pos + action_scale * clip(action, -action_clip, action_clip)",
        "observation": {
            "frame": frame,
            "frames": cfg.history_length + 1,
            "order": "newest frame first; each quantity in SI units, unscaled (scale 1)",
            "frame_dim": sum(size for _, size in frame),
            "base_ang_vel_frame": "pelvis (body) frame",
        },
        "control_period_s": float(env.dt),
        "physics_timestep_s": float(cfg.timestep),
        "decimation": int(cfg.decimation),
        "objective_names": list(cfg.objective_names),
        "preference_size": env.num_objectives,
        "held_joints": {j: list(holding_gains(j)) for j in cfg.held_joints},  # trained held by PD: kp, kd
        # the velocity command's trained ranges (lin_vel_x, lin_vel_y, ang_vel_z: [low, high]); {} without one
        "command_ranges": ({k: [float(lo), float(hi)] for k, (lo, hi) in cfg.command_ranges.items()}
                           if cfg.use_command else {}),
    }
