"""Build the simulated G1 for a task: the menagerie MJCF plus floor, actuators, armature, lean feet and sensors."""

from __future__ import annotations

import os

import mujoco
import numpy as np

from pchc_rsl.robots.g1.constants import DEFAULT_POSE, FOOT_BODIES, FOOT_SITES, holding_gains, joint_gains, joint_motor

ALL_JOINTS_MARKER = "floating_base_joint"
COLLISION_GROUP = 3
"""Geom group of the menagerie G1's collision primitives; group 2 holds the visual meshes (density 0)."""
SOLE_HALF_SIZE = (0.0935, 0.0365, 0.01)
"""Half sizes of the box that replaces the seven sole capsules of each foot (same footprint, 4 contacts not 14)."""
SOLE_CENTER = (0.0395, 0.0, -0.025)


class G1ModelUnavailable(RuntimeError, ValueError):
    """The G1 could not be had (offline without MENAGERIE_ROOT, or a folder without it). A ValueError too, so every
    CLI reports it in one line like other bad input."""


def load_g1_spec() -> mujoco.MjSpec:
    """The 29-DoF G1 MjSpec from mujoco-menagerie; a one-line error when it cannot be had offline."""
    try:
        import mujoco_menagerie

        return mujoco_menagerie.get("unitree_g1").spec("g1_mjlab")
    except Exception as error:  # noqa: BLE001 - any failure here means the model is unavailable
        hint = (
            f"MENAGERIE_ROOT={os.environ['MENAGERIE_ROOT']} holds no unitree_g1/g1_mjlab.xml"
            if "MENAGERIE_ROOT" in os.environ
            else "mujoco-menagerie downloads it on first use, which needs internet; offline, set MENAGERIE_ROOT "
            "to a folder holding unitree_g1/g1_mjlab.xml (a copy of mujoco-menagerie's download)"
        )
        reason = (str(error).strip().splitlines() or [type(error).__name__])[0][:200]
        raise G1ModelUnavailable(f"could not load the Unitree G1 ({reason}): {hint}.") from None


def build_g1_model(joints: list[str], timestep: float = 0.002, lean_feet: bool = True,
                   visual: bool = False, torque_control: bool = False,
                   held_joints: tuple[str, ...] = ()) -> mujoco.MjModel:
    """Compile a G1 that actuates exactly ``joints`` (in that order) with position actuators.

    Joints not in ``joints`` are deleted, which welds their bodies to the parent (mass kept, no cost).
    Only collision geoms (group 3) collide, and only with the floor (no self-collision). ``visual=False`` (the
    physics model) drops the visual meshes altogether: they weigh nothing (density 0) but are 197k vertices, about
    70 MB per model copy; ``visual=True`` keeps them, non-colliding, for rendering the same physics state.
    The floor has geom priority 1, so a contact's friction is the floor's (randomisable), not the larger of the two.
    ``held_joints`` are kept (not welded) but not actuated: a joint spring and damper with the holding gains
    (kp, kd of robots/g1/constants.holding_gains) keeps each at the default pose, as the robot's PD holds the joints a
    policy does not drive. They come after ``joints`` in qpos only where the MJCF orders them so; look joints up by
    name. ``torque_control``: motor actuators (ctrl is the joint torque, clipped to the effort limit) instead of
    position actuators, for a simulator that applies the robot's own PD law (the sim bridge).
    Sensors: per foot a framepos, a framelinvel and a touch sensor (sole contact force); the whole-body centre of
    mass (subtree COM of the pelvis); then one actuatorfrc per actuator.
    """
    spec = load_g1_spec()
    spec.option.timestep = timestep
    known = {j.name for j in spec.joints}
    unknown = [j for j in [*joints, *held_joints] if j not in known]
    if unknown:
        raise ValueError(f"Unknown G1 joints {unknown}; known: {sorted(known - {ALL_JOINTS_MARKER})}.")
    for joint in list(spec.joints):
        if joint.name != ALL_JOINTS_MARKER and joint.name not in joints and joint.name not in held_joints:
            spec.delete(joint)
    for name in held_joints:
        joint = spec.joint(name)
        kp, kd = holding_gains(name)
        joint.armature = joint_motor(name).armature
        if np.ndim(joint.stiffness):  # MuJoCo 4: polynomial coefficients, the linear term first
            joint.stiffness, joint.damping = [kp, 0.0, 0.0], [kd, 0.0, 0.0]
        else:
            joint.stiffness, joint.damping = kp, kd
        joint.springref = DEFAULT_POSE.get(name, 0.0)

    for geom in list(spec.geoms):
        if geom.group == COLLISION_GROUP:
            geom.contype, geom.conaffinity = 1, 0  # robot: collides with the floor only
        elif visual:
            geom.contype, geom.conaffinity = 0, 0
        else:
            spec.delete(geom)
    if not visual:
        for mesh in list(spec.meshes):
            spec.delete(mesh)
    if lean_feet:
        for geom in list(spec.geoms):
            if "_foot" in geom.name and geom.name.endswith("_collision"):
                spec.delete(geom)
        for body_name in FOOT_BODIES:
            spec.body(body_name).add_geom(
                name=body_name.replace("ankle_roll_link", "sole"), type=mujoco.mjtGeom.mjGEOM_BOX,
                size=SOLE_HALF_SIZE, pos=SOLE_CENTER, contype=1, conaffinity=0, group=COLLISION_GROUP,
                rgba=(0.2, 0.2, 0.2, 1),
            )
    floor = spec.worldbody.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=(0, 0, 0.05), contype=0, conaffinity=1,
        friction=(1.0, 0.005, 0.0001), priority=1, rgba=(0.5, 0.55, 0.6, 1),
    )
    if visual:
        add_scenery(spec, floor)

    for name in joints:
        joint = spec.joint(name)
        motor = joint_motor(name)
        kp, kd = joint_gains(name)
        joint.armature = motor.armature
        if torque_control:
            kp, kd = 1.0, 0.0  # ctrl = torque: gain 1, no bias
        spec.add_actuator(
            name=name.replace("_joint", ""), target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT,
            gaintype=mujoco.mjtGain.mjGAIN_FIXED, gainprm=[kp] + [0] * 9,
            biastype=mujoco.mjtBias.mjBIAS_AFFINE if not torque_control else mujoco.mjtBias.mjBIAS_NONE,
            biasprm=([0, -kp, -kd] if not torque_control else [0, 0, 0]) + [0] * 7,
            forcelimited=True, forcerange=[-motor.effort_limit, motor.effort_limit],
            ctrllimited=torque_control, ctrlrange=[-motor.effort_limit, motor.effort_limit],
        )

    for site_name, body_name in zip(FOOT_SITES, FOOT_BODIES):
        spec.add_sensor(name=f"{site_name}_pos", type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
                        objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site_name)
        spec.add_sensor(name=f"{site_name}_linvel", type=mujoco.mjtSensor.mjSENS_FRAMELINVEL,
                        objtype=mujoco.mjtObj.mjOBJ_SITE, objname=site_name)
        sole = spec.body(body_name).add_site(
            name=f"{site_name}_sole", type=mujoco.mjtGeom.mjGEOM_BOX, pos=(SOLE_CENTER[0], 0, -0.035),
            size=(SOLE_HALF_SIZE[0] + 0.01, SOLE_HALF_SIZE[1] + 0.01, 0.015), group=4,
        )
        spec.add_sensor(name=f"{site_name}_touch", type=mujoco.mjtSensor.mjSENS_TOUCH,
                        objtype=mujoco.mjtObj.mjOBJ_SITE, objname=sole.name)
    spec.add_sensor(name="com_pos", type=mujoco.mjtSensor.mjSENS_SUBTREECOM, objtype=mujoco.mjtObj.mjOBJ_BODY,
                    objname="pelvis")
    spec.add_sensor(name="com_vel", type=mujoco.mjtSensor.mjSENS_SUBTREELINVEL, objtype=mujoco.mjtObj.mjOBJ_BODY,
                    objname="pelvis")
    for name in joints:
        spec.add_sensor(name=f"{name}_torque", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=name.replace("_joint", ""))
    return spec.compile()


def add_scenery(spec: mujoco.MjSpec, floor: mujoco.MjsGeom) -> None:
    """A checkered floor (so that a camera following the robot shows it walking) and a sky; rendering only."""
    grid = spec.add_texture(
        name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D, builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=256,
        height=256, rgb1=(0.5, 0.55, 0.6), rgb2=(0.36, 0.4, 0.45), mark=mujoco.mjtMark.mjMARK_EDGE,
        markrgb=(0.75, 0.75, 0.75),
    )
    material = spec.add_material(name="grid", texrepeat=(2, 2), texuniform=True, reflectance=0.1)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = grid.name
    floor.material, floor.rgba = material.name, (1, 1, 1, 1)
    spec.add_texture(
        name="sky", type=mujoco.mjtTexture.mjTEXTURE_SKYBOX, builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, width=256,
        height=256, rgb1=(0.65, 0.78, 0.92), rgb2=(0.3, 0.35, 0.4),
    )


def default_joint_positions(joints: list[str]) -> list[float]:
    return [DEFAULT_POSE.get(j, 0.0) for j in joints]
