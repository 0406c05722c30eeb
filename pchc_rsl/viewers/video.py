"""Videos of policies: one tile per preference side by side, a text label on each, encoded by imageio.

No MuJoCo here: a tile is an RGB array [H, W, 3] from any renderer (the G1's, or a matplotlib plot of the toy).
MP4 goes through imageio's ffmpeg plugin (H.264, the ffmpeg binary comes with imageio-ffmpeg); GIF through Pillow.
"""

from __future__ import annotations

import os

import numpy as np
from PIL import Image, ImageDraw, ImageFont

VIDEO_FORMATS = (".mp4", ".gif")
INSTALL_HINT = "pip install -e \".[render]\" (imageio and imageio-ffmpeg)"


def check_video_path(path: str) -> str:
    """The lower-case suffix of a video file name, or a ValueError that says which ones are allowed."""
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in VIDEO_FORMATS:
        raise ValueError(f"--video {path}: the file must end in {' or '.join(VIDEO_FORMATS)} (got '{suffix}'); "
                         f"e.g. --video walk.mp4, or --video walk.gif for a README.")
    return suffix


def check_frame_size(width: int, height: int) -> None:
    """H.264 in the yuv420p pixel format (what players accept) needs even sizes; tiny tiles are unreadable."""
    for name, value in (("--width", width), ("--height", height)):
        if value < 16 or value % 2:
            raise ValueError(f"{name} {value}: a tile size must be an even number of pixels >= 16, e.g. "
                             f"--width 480 --height 360.")


def tile(frames: list[np.ndarray]) -> np.ndarray:
    """Tiles [H, W, 3] side by side: [H, n W, 3]."""
    return np.concatenate(frames, axis=1)


def label(frame: np.ndarray, lines: list[str]) -> np.ndarray:
    """The frame with ``lines`` written in its top-left corner on a dark box (readable on any background)."""
    image = Image.fromarray(frame)
    draw = ImageDraw.Draw(image, "RGBA")
    size = max(8, frame.shape[0] // 22)
    try:
        font = ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: one fixed-size bitmap font
        font = ImageFont.load_default()
    text = "\n".join(lines)
    box = draw.multiline_textbbox((4, 3), text, font=font, spacing=2)
    draw.rectangle((box[0] - 3, box[1] - 2, box[2] + 3, box[3] + 3), fill=(0, 0, 0, 150))
    draw.multiline_text((4, 3), text, font=font, fill=(255, 255, 255), spacing=2)
    return np.asarray(image)


class VideoWriter:
    """Append frames, then close: MP4 streams frames to ffmpeg; GIF keeps them and writes at close (keep it short).

    The frame rate is the rate at which the frames were taken, so the video plays in real time.
    """

    def __init__(self, path: str, fps: float) -> None:
        self.format = check_video_path(path)
        try:
            import imageio.v2 as imageio
        except ImportError as error:
            raise RuntimeError(f"Writing {path} needs imageio ({error}); {INSTALL_HINT}.") from error
        self.path, self.fps, self.frames, self.count = path, fps, [], 0
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        if self.format == ".mp4":
            try:
                self.writer = imageio.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264",
                                                 pixelformat="yuv420p", macro_block_size=2, quality=7)
            except (ImportError, RuntimeError, ValueError) as error:
                raise RuntimeError(f"Cannot write MP4 ({error}); {INSTALL_HINT}, or pass --video FILE.gif.") from error

    def append(self, frame: np.ndarray) -> None:
        self.count += 1
        if self.format == ".mp4":
            self.writer.append_data(frame)
        else:
            self.frames.append(frame)

    def close(self) -> None:
        if self.format == ".mp4":
            self.writer.close()
        elif self.frames:
            import imageio.v3 as iio

            # GIF delays are whole centiseconds; loop=0 repeats for ever, as a README animation should
            iio.imwrite(self.path, np.stack(self.frames), extension=".gif", duration=1000.0 / self.fps, loop=0)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
