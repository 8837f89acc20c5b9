"""A window that shows frames as they come (``render_mode="human"``), through matplotlib."""

from __future__ import annotations

import numpy as np

# Backends that draw to files or memory only: showing a window there would warn, so frames are just drawn.
_NON_INTERACTIVE = {"agg", "pdf", "ps", "svg", "cairo", "pgf", "template"}


class HumanViewer:
    """Shows each frame in one matplotlib figure, pausing ``1/fps`` seconds so the battle plays at that rate.

    matplotlib is imported on first use; without it the first :meth:`show` raises an ImportError naming the package.
    """

    def __init__(self, title: str = "smac-hard-gym", fps: float = 8.0) -> None:
        if not (isinstance(fps, (int, float)) and fps > 0):
            raise ValueError(f"fps must be a positive number, got {fps!r}")
        self.title = title
        self.fps = float(fps)
        self._plt = None
        self._figure = None
        self._image = None

    def _open(self, frame: np.ndarray) -> None:
        try:
            import matplotlib.pyplot as plt
        except ImportError:
            raise ImportError("render_mode='human' needs matplotlib: pip install 'smac-hard-gym[render]' or "
                              "pip install matplotlib (or use render_mode='rgb_array')") from None
        self._plt = plt
        height, width = frame.shape[:2]
        self._figure = plt.figure(self.title, figsize=(width / 100, height / 100), dpi=100)
        axes = self._figure.add_axes((0, 0, 1, 1))
        axes.set_axis_off()
        self._image = axes.imshow(frame, interpolation="nearest")
        if self.interactive:
            plt.show(block=False)

    @property
    def interactive(self) -> bool:
        import matplotlib

        return matplotlib.get_backend().lower() not in _NON_INTERACTIVE

    @property
    def is_open(self) -> bool:
        return self._figure is not None

    def show(self, frame: np.ndarray) -> None:
        """Display ``frame`` (H, W, 3) uint8 and wait one frame period."""
        if self._figure is not None and not self._plt.fignum_exists(self._figure.number):
            self._figure = self._image = None  # the user closed the window: open a new one
        if self._figure is None:
            self._open(frame)
        else:
            self._image.set_data(frame)
        self._figure.canvas.draw_idle()
        if self.interactive:
            self._figure.canvas.start_event_loop(1.0 / self.fps)

    def close(self) -> None:
        """Close the window. Idempotent."""
        if self._figure is not None:
            self._plt.close(self._figure)
        self._figure = self._image = None
