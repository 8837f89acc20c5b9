"""What an env holds to support ``render_mode``: built on the first ``render()`` call, never on the step path."""

from __future__ import annotations

from typing import Any

import numpy as np

from smac_hard_gym.render.renderer import BattleRenderer
from smac_hard_gym.render.viewer import HumanViewer

RENDER_MODES = ("rgb_array", "human")


def check_render_mode(render_mode: str | None) -> str | None:
    """Validate an env's ``render_mode`` argument (``None`` turns rendering off)."""
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be None or one of {RENDER_MODES}, got {render_mode!r}")
    return render_mode


class EnvRenderer:
    """Renders an env's battles for ``render_mode="rgb_array"`` (returns frames) or ``"human"`` (shows them).

    ``render(state, battle, step, opponent_name)`` draws one battle; pass a list of battles to tile a grid (vector
    envs). In ``"human"`` mode it shows the frame and returns ``None``, as gymnasium expects.
    """

    def __init__(self, spec: Any, render_mode: str, *, scale: int | None = None, step_mul: int = 8,
                 fps: float = 8.0) -> None:
        if check_render_mode(render_mode) is None:
            raise ValueError("EnvRenderer needs a render_mode; an env with render_mode=None renders nothing")
        self.render_mode = render_mode
        self.renderer = BattleRenderer(spec, scale=scale, step_mul=step_mul)
        self.viewer = HumanViewer(f"smac-hard-gym {self.renderer.spec.name}", fps) if render_mode == "human" else None

    def render(self, state: Any, battle: int | list[int] = 0, step: Any = None,
               opponent_name: Any = None, cols: int | None = None) -> np.ndarray | None:
        if isinstance(battle, (list, tuple, np.ndarray)):
            frame = self.renderer.render_grid(state, battle, cols, step, opponent_name)
        else:
            frame = self.renderer.render(state, battle, step, opponent_name)
        if self.viewer is not None:
            self.viewer.show(frame)
            return None
        return frame

    def close(self) -> None:
        if self.viewer is not None:
            self.viewer.close()
