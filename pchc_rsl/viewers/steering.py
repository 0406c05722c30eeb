"""The walking command as pchc-play steers it (the native and the web viewer): forward, lateral and yaw rate, each
within the range the task trained it in (``cfg.command_ranges``, kept as ``cfg.steering_ranges`` where an evaluation
preset fixed the command); a component trained at (0, 0) is not steered."""

from __future__ import annotations

from pchc_rsl.export.metadata import COMMAND_COMPONENTS

COMMAND_LABELS = {"lin_vel_x": "forward speed (m/s)", "lin_vel_y": "lateral speed (m/s)",
                  "ang_vel_z": "yaw rate (rad/s)"}


def trained_ranges(cfg) -> dict[str, tuple[float, float]]:
    """component -> (low, high) of the components this env's policy takes (none without a command)."""
    if not getattr(cfg, "use_command", False):
        return {}
    ranges = getattr(cfg, "steering_ranges", None) or getattr(cfg, "command_ranges", {}) or {}
    return {k: (float(ranges[k][0]), float(ranges[k][1])) for k in COMMAND_COMPONENTS
            if k in ranges and ranges[k][1] > ranges[k][0]}


def set_command(env, component: int, value: float) -> bool:
    """Set env 0's command component (clipped to its trained range); False for one the policy does not take."""
    ranges = trained_ranges(env.cfg)
    key = COMMAND_COMPONENTS[component]
    if key not in ranges:
        return False
    low, high = ranges[key]
    env.commands[0, component] = min(high, max(low, round(float(value), 3)))
    return True
