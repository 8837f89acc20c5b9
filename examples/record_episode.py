"""Record one battle between two scripts, save it as an episode file and render it to a GIF.

    python examples/record_episode.py --map 3m --out-dir episodes
    smac-hard-gym replay episodes/3m.npz --out episodes/3m.mp4   # the same episode again, as MP4

The learner's side is played by a tiny script written here (every unit attacks the nearest living enemy), the
opponent by any built-in script (``base`` by default). Writing the GIF needs Pillow (``pip install
smac-hard-gym[render]``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from smac_hard_gym.engine.state import CMD_ATTACK
from smac_hard_gym.envs.duel import record_engine_episode
from smac_hard_gym.opponents import Script, SideView
from smac_hard_gym.render import BattleRenderer, write_video


class NearestTarget(Script):
    """Every living unit attacks the nearest living enemy, re-chosen each step."""

    name = "nearest"

    def act(self, view: SideView, commands, active: np.ndarray) -> None:
        dx = view.own_x[:, :, None] - view.enemy_x[:, None, :]
        dy = view.own_y[:, :, None] - view.enemy_y[:, None, :]
        dist = np.where(view.enemy_alive[:, None, :], dx * dx + dy * dy, np.inf)
        go = active[:, None] & view.own_alive & view.enemy_alive.any(axis=1)[:, None]
        commands.kind[:, view.own][go] = CMD_ATTACK
        commands.target[:, view.own][go] = view.enemy_slot(dist.argmin(axis=2))[go]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--map", default="3m")
    parser.add_argument("--opponent", default="base", help="built-in opponent script")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out-dir", default="episodes")
    parser.add_argument("--fps", type=float, default=8.0)
    parser.add_argument("--scale", type=int, default=16, help="pixels per map cell")
    args = parser.parse_args()
    print(f"recording {args.map}: nearest vs {args.opponent}, seed {args.seed}")

    out_dir = Path(args.out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    recorder = record_engine_episode(args.map, NearestTarget(), args.opponent, seed=args.seed)
    episode_path = recorder.save(out_dir / f"{args.map}.npz")
    episode = recorder.to_episode()
    print(f"{len(episode)} frames, winner {recorder.metadata['winner']}, saved {episode_path}")

    renderer = BattleRenderer(episode.terrain, scale=args.scale, step_mul=episode.step_mul)
    video = write_video(episode.render(renderer), out_dir / f"{args.map}.gif", fps=args.fps)
    print(f"wrote {video}")


if __name__ == "__main__":
    main()
