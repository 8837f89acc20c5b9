"""See the battle: top-down frames, episode recording and replay files.

Nothing here is imported by the engine or the env step path; envs import it only when ``render_mode`` is set, and
Pillow, imageio-ffmpeg and matplotlib are imported only by the functions that need them (``pip install
smac-hard-gym[render]``).

- :class:`BattleRenderer`: frames (H, W, 3) uint8 of one battle, or a grid of battles (``render_grid``).
- :class:`EnvRenderer`: what an env holds for ``render_mode="rgb_array"`` or ``"human"``.
- :class:`EpisodeRecorder` / :func:`load_episode`: capture an episode step by step into a compressed ``.npz`` file
  and read it back (``smac_hard_gym.envs.duel.record_engine_episode`` plays two scripts against each other on the
  two-player core and records the battle).
- :func:`write_video`: frames to ``.gif`` (Pillow) or ``.mp4`` (imageio-ffmpeg).
"""

from __future__ import annotations

from smac_hard_gym.render.env_hook import RENDER_MODES, EnvRenderer, check_render_mode
from smac_hard_gym.render.recorder import (
    Episode,
    EpisodeError,
    EpisodeRecorder,
    load_episode,
)
from smac_hard_gym.render.renderer import BattleRenderer, tile_frames
from smac_hard_gym.render.video import VIDEO_FORMATS, write_video
from smac_hard_gym.render.viewer import HumanViewer

__all__ = [
    "BattleRenderer", "tile_frames", "EnvRenderer", "RENDER_MODES", "check_render_mode", "HumanViewer",
    "EpisodeRecorder", "Episode", "EpisodeError", "load_episode", "write_video",
    "VIDEO_FORMATS",
]
