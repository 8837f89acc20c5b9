"""What the one-battle envs (``SMACHardEnv``, the PettingZoo env) share: drawing battle 0 and closing."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["RendersOneBattle"]


class RendersOneBattle:
    """``render()`` and ``close()`` for an env over a one-battle core ``self.core`` with ``self.render_mode`` and
    ``self._renderer`` (None until the first frame); ``render_hint`` says where ``render_mode`` is passed."""

    render_hint = "to the constructor"
    core: Any
    render_mode: str | None
    _renderer: Any

    def render(self) -> np.ndarray | None:
        """The battle as an RGB frame ``(H, W, 3)`` uint8 (``"rgb_array"``), or shown in a window (``"human"``)."""
        if self.render_mode is None:
            import gymnasium

            gymnasium.logger.warn(f"render() called with render_mode=None; pass render_mode='rgb_array' or 'human' "
                                  f"{self.render_hint}")
            return None
        if self._renderer is None:
            from smac_hard_gym.render import EnvRenderer

            self._renderer = EnvRenderer(self.core.spec, self.render_mode, step_mul=self.core.backend.step_mul)
        return self._renderer.render(self.core.state, 0, int(self.core.episode_step[0]),
                                     self.core.opponent_names()[0])

    def close(self) -> None:
        """Release the backend and any render window. Idempotent."""
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        self.core.close()
