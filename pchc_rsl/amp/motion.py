"""Reference motions for AMP: joint-position clips loaded by joint name and resampled to the control rate.

The discriminator compares windows of the robot's joint positions with windows of these clips, so a clip only has
to provide joint angles with their names and frame rate; ``with_root_velocity`` each frame also carries the root's
velocity in its heading frame (forward, sideways, yaw rate), read from the clip's root pose. Two formats are read,
with numpy only (never mujoco):

- the LAFAN1 G1 retargeting CSV: no header, 30 fps, 36 columns: root position xyz, root quaternion xyzw, then the
  29 joint angles in the order ``G1_CSV_JOINTS``;
- npz clips with keys ``fps`` (scalar), ``dof_names`` [D] (strings) and ``dof_positions`` [T, D], and for the root
  velocity ``root_positions`` [T, 3] and ``root_quaternions`` [T, 4] (xyzw); other keys are ignored.
"""

from __future__ import annotations

import math
import os
import zipfile
import zlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

G1_CSV_JOINTS: tuple[str, ...] = tuple(
    f"{name}_joint"
    for name in (
        "left_hip_pitch", "left_hip_roll", "left_hip_yaw", "left_knee", "left_ankle_pitch", "left_ankle_roll",
        "right_hip_pitch", "right_hip_roll", "right_hip_yaw", "right_knee", "right_ankle_pitch", "right_ankle_roll",
        "waist_yaw", "waist_roll", "waist_pitch",
        "left_shoulder_pitch", "left_shoulder_roll", "left_shoulder_yaw", "left_elbow",
        "left_wrist_roll", "left_wrist_pitch", "left_wrist_yaw",
        "right_shoulder_pitch", "right_shoulder_roll", "right_shoulder_yaw", "right_elbow",
        "right_wrist_roll", "right_wrist_pitch", "right_wrist_yaw",
    )
)
"""The 29 G1 joints of the LAFAN1 retargeting CSV, in column order (after the 7 root columns)."""

CSV_FPS = 30.0
CSV_ROOT_COLUMNS = 7  # root position xyz, root quaternion xyzw
CSV_NUM_COLUMNS = CSV_ROOT_COLUMNS + len(G1_CSV_JOINTS)
NPZ_KEYS = ("fps", "dof_names", "dof_positions")
NPZ_ROOT_KEYS = ("root_positions", "root_quaternions")
ROOT_VELOCITY_SIZE = 3
"""Root velocity columns of a frame: forward and sideways velocity in the heading frame (m/s), yaw rate (rad/s)."""
MOTION_EXTENSIONS = (".csv", ".npz")


def _read_csv(path: Path) -> tuple[float, list[str], np.ndarray, np.ndarray]:
    """(fps, joint names, joint positions [T, 29], root pose [T, 7]: xyz, quaternion xyzw) of a LAFAN1 G1 retargeting
    CSV."""
    try:
        data = np.loadtxt(path, delimiter=",", dtype=np.float64, ndmin=2)
    except ValueError as error:  # numpy's text ends with advice about its own arguments (usecols): keep the fact
        fact = str(error).strip().splitlines()[0].split(";")[0] if str(error).strip() else type(error).__name__
        raise ValueError(
            f"{path}: cannot parse as a LAFAN1 G1 CSV (comma-separated numbers, no header, {CSV_NUM_COLUMNS} "
            f"columns on every row; a truncated file?): {fact}."
        ) from None
    if data.shape[0] == 0:
        raise ValueError(f"{path}: the CSV holds no frames.")
    if data.shape[1] != CSV_NUM_COLUMNS:
        raise ValueError(
            f"{path} has {data.shape[1]} columns; a LAFAN1 G1 CSV needs {CSV_NUM_COLUMNS}: root position xyz (3), "
            f"root quaternion xyzw (4) and {len(G1_CSV_JOINTS)} joint angles."
        )
    return CSV_FPS, list(G1_CSV_JOINTS), data[:, CSV_ROOT_COLUMNS:], data[:, :CSV_ROOT_COLUMNS]


def _read_npz(path: Path) -> tuple[float, list[str], np.ndarray, np.ndarray | None]:
    """(fps, joint names, joint positions [T, D], root pose [T, 7] or None) of an npz clip."""
    try:
        return _read_npz_archive(path)
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError) as error:  # truncated, empty, not a zip archive
        reason = (str(error).strip().splitlines() or [""])[0]
        raise ValueError(
            f"{path} ({path.stat().st_size} bytes) is not a readable .npz archive (truncated or corrupt?): "
            f"{type(error).__name__}: {reason}"
        ) from None


def _read_npz_archive(path: Path) -> tuple[float, list[str], np.ndarray, np.ndarray | None]:
    if path.stat().st_size == 0:
        raise EOFError("the file is empty")
    try:
        archive = np.load(path, allow_pickle=False)
    except ValueError:  # numpy's guess for a file that is neither .npy nor .npz: pickled data
        raise zipfile.BadZipFile("neither a zip archive nor a numpy array") from None
    if isinstance(archive, np.ndarray):
        raise ValueError(f"{path} holds a single .npy array, not an .npz archive with keys {list(NPZ_KEYS)}.")
    with archive as data:
        missing = [key for key in NPZ_KEYS if key not in data.files]
        if missing:
            raise ValueError(
                f"{path} lacks the key(s) {missing}; an npz motion clip needs {list(NPZ_KEYS)}, it has {data.files}."
            )
        try:
            fps_array, names_array, positions = (data[key] for key in NPZ_KEYS)
        except ValueError as error:  # object arrays need pickle, which we refuse for safety
            raise ValueError(
                f"{path}: cannot read {list(NPZ_KEYS)} without pickle ({error}); store dof_names as a string array."
            ) from error
        root = None
        if all(key in data.files for key in NPZ_ROOT_KEYS):
            root = np.concatenate([np.asarray(data[key], dtype=np.float64).reshape(len(positions), -1)
                                   for key in NPZ_ROOT_KEYS], axis=1)
    if fps_array.size != 1:
        raise ValueError(f"{path}: 'fps' must be a scalar, got shape {list(fps_array.shape)}.")
    fps = float(fps_array.reshape(()))
    names = [str(n) for n in names_array.reshape(-1)]
    positions = np.asarray(positions, dtype=np.float64)
    if positions.ndim != 2 or positions.shape[1] != len(names):
        raise ValueError(
            f"{path}: 'dof_positions' must be [T, {len(names)}] (one column per dof_names entry), "
            f"got shape {list(positions.shape)}."
        )
    if root is not None and root.shape[1] != 7:
        raise ValueError(f"{path}: 'root_positions' must be [T, 3] and 'root_quaternions' [T, 4] (xyzw).")
    return fps, names, positions, root


def resample(positions: np.ndarray, fps_in: float, fps_out: float) -> np.ndarray:
    """Linearly interpolate [T, J] frames at fps_in onto the times k / fps_out inside the clip. Returns [T', J].

    T' = floor((T - 1) fps_out / fps_in) + 1: the first frame is kept and no frame is extrapolated past the last.
    """
    num_in = positions.shape[0]
    # The small slack keeps exact multiples (e.g. 30 frames at 30 fps -> 50 at 50 fps) from losing their last frame.
    num_out = math.floor((num_in - 1) * fps_out / fps_in + 1e-9) + 1
    source = np.arange(num_out) * (fps_in / fps_out)  # fractional input frame of each output frame
    lower = np.minimum(np.floor(source).astype(np.int64), num_in - 1)
    upper = np.minimum(lower + 1, num_in - 1)
    frac = (source - lower)[:, None]
    return (1.0 - frac) * positions[lower] + frac * positions[upper]


def root_velocity(root: np.ndarray, fps_in: float, fps_out: float) -> np.ndarray:
    """[T', 3] the root's velocity in its heading frame at ``fps_out`` (forward, sideways m/s, yaw rate rad/s), from
    its pose [T, 7] (position xyz, quaternion xyzw) at ``fps_in``: position and unwrapped yaw resampled as the joints
    are, then differenced over each frame and turned into the heading at its end, as the env reads its own base
    (envs/g1/observations.py). The first frame repeats the second's."""
    x, y, z, w = root[:, 3], root[:, 4], root[:, 5], root[:, 6]
    yaw = np.unwrap(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
    planar = resample(np.column_stack([root[:, :2], yaw]), fps_in, fps_out)
    change = np.diff(planar, axis=0) * fps_out  # [T' - 1, 3]: world-frame velocity xy, yaw rate
    heading = planar[1:, 2]
    cos, sin = np.cos(heading), np.sin(heading)
    local = np.column_stack([cos * change[:, 0] + sin * change[:, 1], -sin * change[:, 0] + cos * change[:, 1],
                             change[:, 2]])
    return np.concatenate([local[:1], local], axis=0)


def load_motion(
    path: str | os.PathLike, joint_names: Sequence[str], fps_out: float, min_frames: int = 5,
    joint_ranges: Sequence[tuple[float, float]] | None = None, range_tolerance: float = 0.05,
    with_root_velocity: bool = False,
) -> torch.Tensor:
    """Joint positions of ``joint_names`` (in that order) resampled to ``fps_out``. Returns float32 [T, J].

    ``min_frames`` is the shortest clip accepted after resampling (at least one discriminator window).
    ``joint_ranges`` ([J] (low, high), rad, the robot's): a frame more than ``range_tolerance`` outside its joint's
    range is refused, naming the file and the joint: the robot cannot take that pose, so the discriminator would
    learn a style no policy can reach. ``with_root_velocity``: each frame also holds the root's velocity
    (``root_velocity``; [T, J + 3]), for a discriminator that tells walking from stepping in place.
    """
    path = Path(path)
    if not math.isfinite(fps_out) or fps_out <= 0:
        raise ValueError(f"fps_out must be a positive number of frames per second, got {fps_out}.")
    suffix = path.suffix.lower()
    if suffix == ".csv":
        fps_in, names, positions, root = _read_csv(path)
    elif suffix == ".npz":
        fps_in, names, positions, root = _read_npz(path)
    else:
        raise ValueError(
            f"Unsupported motion file extension '{path.suffix}' ({path}); allowed: .csv (LAFAN1 G1 retargeting, "
            f"{CSV_NUM_COLUMNS} columns at {CSV_FPS:g} fps) and .npz (keys {', '.join(NPZ_KEYS)})."
        )
    if not math.isfinite(fps_in) or fps_in <= 0:
        raise ValueError(f"{path}: the clip's fps must be a positive number, got {fps_in}.")

    if len(joint_names) == 0:
        raise ValueError(f"joint_names is empty; choose some of the clip's joints {names}.")
    unknown = [name for name in joint_names if name not in names]
    if unknown:
        raise ValueError(f"{path}: the task needs joint(s) {unknown}, which the clip does not have; the clip's "
                         f"joints are {names}.")
    columns = [names.index(name) for name in joint_names]
    selected = positions[:, columns]

    bad = ~np.isfinite(selected)
    if bad.any():
        frames, joints = np.nonzero(bad)
        raise ValueError(
            f"{path}: {int(bad.sum())} non-finite value(s) (NaN or inf), first at frame {int(frames[0])} of joint "
            f"'{joint_names[int(joints[0])]}'; motion clips must be finite."
        )

    if joint_ranges is not None:
        low, high = (np.asarray([r[k] for r in joint_ranges], dtype=np.float64) for k in (0, 1))
        outside = (selected < low - range_tolerance) | (selected > high + range_tolerance)
        if outside.any():
            frames, joints = np.nonzero(outside)
            j = int(joints[0])
            raise ValueError(
                f"{path}: column '{joint_names[j]}' leaves the robot's range [{low[j]:.3f}, {high[j]:.3f}] rad "
                f"(by more than {range_tolerance:g}) in {int(outside[:, j].sum())} frame(s), first frame "
                f"{int(frames[0])} at {selected[frames[0], j]:.3f} rad; retarget the clip to this robot."
            )

    resampled = resample(selected, fps_in, fps_out)
    if with_root_velocity:
        if root is None or not np.isfinite(root).all():
            raise ValueError(f"{path}: the root velocity needs the clip's finite root pose (an npz clip: keys "
                             f"{list(NPZ_ROOT_KEYS)}); this clip has none, or non-finite values.")
        resampled = np.concatenate([resampled, root_velocity(root, fps_in, fps_out)], axis=1)
    if resampled.shape[0] < min_frames:
        raise ValueError(
            f"{path}: {positions.shape[0]} frames at {fps_in:g} fps give {resampled.shape[0]} frames at "
            f"{fps_out:g} fps, fewer than min_frames={min_frames} (one discriminator window)."
        )
    return torch.as_tensor(resampled, dtype=torch.float32)


def find_motion_files(paths: str | os.PathLike | Sequence[str | os.PathLike]) -> list[Path]:
    """Expand files and folders into motion files: a folder stands for its .csv and .npz files, sorted by name."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    files: list[Path] = []
    for entry in map(Path, paths):
        if entry.is_dir():
            files += sorted(p for p in entry.iterdir() if p.is_file() and p.suffix.lower() in MOTION_EXTENSIONS)
        elif entry.is_file():
            files.append(entry)
        else:
            raise FileNotFoundError(f"Motion path {entry} is neither a file nor a folder.")
    if not files:
        raise ValueError(
            f"No motion clips found in {[str(p) for p in paths]}; a folder must hold {' or '.join(MOTION_EXTENSIONS)} "
            "files."
        )
    return files


def load_motions(
    paths: str | os.PathLike | Sequence[str | os.PathLike],
    joint_names: Sequence[str],
    fps_out: float,
    min_frames: int = 5,
    joint_ranges: Sequence[tuple[float, float]] | None = None,
    with_root_velocity: bool = False,
) -> list[torch.Tensor]:
    """Load every clip named by ``paths`` (files and/or folders) with load_motion. Returns a list of [T_i, J]
    ([T_i, J + 3] ``with_root_velocity``)."""
    return [load_motion(f, joint_names, fps_out, min_frames, joint_ranges, with_root_velocity=with_root_velocity)
            for f in find_motion_files(paths)]


def kept_frames(clip: torch.Tensor, joint_names: Sequence[str], exclude_beyond: dict[str, float]) -> torch.Tensor:
    """[T] bool: the frames of a clip [T, J] in which no joint named in ``exclude_beyond`` is further from zero than
    its bound (rad), e.g. {"left_shoulder_roll_joint": 1.2}: poses the clip holds that a task's gait should not
    learn (the arms raised into a T-pose)."""
    unknown = [name for name in exclude_beyond if name not in joint_names]
    if unknown:
        raise ValueError(f"exclude_reference_beyond names {unknown}, which are not AMP joints; they are "
                         f"{list(joint_names)}.")
    keep = torch.ones(clip.shape[0], dtype=torch.bool)
    for name, bound in exclude_beyond.items():
        keep &= clip[:, list(joint_names).index(name)].abs() <= bound
    return keep


class MotionWindows:
    """Uniform sampler of ``window`` consecutive frames over all valid window starts of all clips.

    Long clips contribute proportionally more windows, so every reference transition is equally likely. The clips
    are concatenated once; ``starts`` holds each valid start row of that concatenation.
    """

    def __init__(self, clips: Sequence[torch.Tensor], window: int = 5, device: str | torch.device = "cpu",
                 keep: Sequence[torch.Tensor] | None = None) -> None:
        """``keep``: per clip, [T_i] bool of the frames a window may hold (None: all); windows over a left-out frame
        are not sampled."""
        if window < 1:
            raise ValueError(f"window must be >= 1 frame, got {window}.")
        if len(clips) == 0:
            raise ValueError("MotionWindows needs at least one clip, got none.")
        shapes = [tuple(c.shape) for c in clips]
        if any(len(s) != 2 for s in shapes) or len({s[1] for s in shapes}) != 1:
            raise ValueError(f"Clips must all be [T_i, J] with the same J, got shapes {shapes}.")
        short = [i for i, s in enumerate(shapes) if s[0] < window]
        if short:
            raise ValueError(
                f"Clip(s) {short} have fewer frames than window={window} (shapes {[shapes[i] for i in short]})."
            )
        self.window = window
        self.num_joints = shapes[0][1]
        self.dim = window * self.num_joints
        self.device = torch.device(device)
        self.frames = torch.cat([c.to(self.device, torch.float32) for c in clips])  # [sum T_i, J]
        starts, offset = [], 0
        for i, (length, _) in enumerate(shapes):
            first = torch.arange(length - window + 1)
            if keep is not None:  # a start is valid when its whole window is kept
                clear = keep[i].to(torch.int64).unfold(0, window, 1).sum(-1) == window
                first = first[clear]
            starts.append(offset + first)
            offset += length
        self.starts = torch.cat(starts).to(self.device)  # [num_windows]
        if self.starts.numel() == 0:
            raise ValueError("No reference window is left: every window of the clips holds a left-out frame.")
        self.offsets = torch.arange(window, device=self.device)

    @property
    def num_windows(self) -> int:
        return int(self.starts.numel())

    def sample(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """n random windows [n, window * J], frames concatenated oldest first."""
        draw_device = generator.device if generator is not None else self.device
        pick = torch.randint(0, self.num_windows, (n,), generator=generator, device=draw_device).to(self.device)
        rows = self.starts[pick, None] + self.offsets  # [n, window]
        return self.frames[rows].reshape(n, self.dim)
