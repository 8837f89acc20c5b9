"""Write frames to a video file: ``.gif`` through Pillow, ``.mp4`` (H.264) through imageio-ffmpeg."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

VIDEO_FORMATS = (".gif", ".mp4")
INSTALL_HINT = "pip install 'smac-hard-gym[render]'"


def _check_frame(frame: np.ndarray, shape: tuple[int, ...] | None) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3:
        raise ValueError(f"frames must be (H, W, 3) uint8 arrays, got {frame.shape} {frame.dtype}")
    if shape is not None and frame.shape != shape:
        raise ValueError(f"all frames must share one shape: {shape} then {frame.shape}")
    return frame


def _write_gif(frames: Iterable[np.ndarray], path: Path, fps: float) -> int:
    try:
        from PIL import Image
    except ImportError:
        raise ImportError(f"writing .gif needs the 'pillow' package: {INSTALL_HINT} or pip install pillow") from None
    images, shape = [], None
    for frame in frames:
        frame = _check_frame(frame, shape)
        shape = frame.shape
        images.append(Image.fromarray(frame))
    if not images:
        raise ValueError("no frames to write")
    # GIF stores delays in 1/100 s; Pillow takes milliseconds.
    images[0].save(path, save_all=True, append_images=images[1:], duration=max(int(round(1000 / fps)), 20),
                   loop=0, optimize=False)
    return len(images)


def _write_mp4(frames: Iterable[np.ndarray], path: Path, fps: float) -> int:
    try:
        import imageio_ffmpeg
    except ImportError:
        raise ImportError(f"writing .mp4 needs the 'imageio-ffmpeg' package: {INSTALL_HINT} or "
                          f"pip install imageio-ffmpeg (or write a .gif instead)") from None
    writer, shape, count = None, None, 0
    try:
        for frame in frames:
            frame = _check_frame(frame, shape)
            if writer is None:
                shape = frame.shape
                # H.264 in yuv420p wants even sides: pad by at most one pixel instead of rescaling.
                even = (shape[0] + shape[0] % 2, shape[1] + shape[1] % 2)
                writer = imageio_ffmpeg.write_frames(str(path), (even[1], even[0]), fps=fps, codec="libx264",
                                                     pix_fmt_out="yuv420p", macro_block_size=1, quality=7)
                writer.send(None)
            padded = np.zeros((even[0], even[1], 3), dtype=np.uint8)
            padded[: shape[0], : shape[1]] = frame
            writer.send(np.ascontiguousarray(padded))
            count += 1
    finally:
        if writer is not None:
            writer.close()
    if count == 0:
        raise ValueError("no frames to write")
    return count


_WRITERS = {".gif": _write_gif, ".mp4": _write_mp4}


def write_video(frames: Iterable[np.ndarray], path: str | os.PathLike, fps: float = 8.0) -> Path:
    """Write (H, W, 3) uint8 frames to ``path``; the suffix picks the format (``.gif`` or ``.mp4``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in _WRITERS:
        raise ValueError(f"unsupported video file {str(path)!r}: the name must end in one of "
                         f"{', '.join(VIDEO_FORMATS)}")
    if not (isinstance(fps, (int, float)) and not isinstance(fps, bool) and 0 < fps <= 120):
        raise ValueError(f"fps must be a number in (0, 120], got {fps!r}")
    if not path.parent.exists():
        raise FileNotFoundError(f"folder {str(path.parent)!r} for {path.name!r} does not exist")
    _WRITERS[suffix](frames, path, float(fps))
    return path
