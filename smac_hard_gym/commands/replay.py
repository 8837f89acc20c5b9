"""``smac-hard-gym replay``: render a recorded episode file to a GIF or MP4 video."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "render a recorded episode (.npz) to a .gif or .mp4 video"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", help="episode file written by EpisodeRecorder.save (.npz)")
    parser.add_argument("--out", default=None,
                        help="video to write, battle.gif or battle.mp4 (default: FILE with .gif)")
    parser.add_argument("--fps", type=float, default=8.0,
                        help="frames per second (default 8; a step of 8 game loops is half a Normal-speed second, "
                        "so 2 plays at game speed)")
    parser.add_argument("--scale", type=int, default=None, help="pixels per map cell (default 16)")


def run(args: argparse.Namespace) -> int:
    from smac_hard_gym.files import atomic_path
    from smac_hard_gym.render import VIDEO_FORMATS, BattleRenderer, EpisodeError, load_episode, write_video

    out = Path(args.out) if args.out else Path(args.file).with_suffix(".gif")
    if out.suffix.lower() not in VIDEO_FORMATS:
        print(f"smac-hard-gym replay: error: --out {str(out)!r} must end in one of {', '.join(VIDEO_FORMATS)}",
              file=sys.stderr)
        return 2
    try:
        episode = load_episode(args.file)
        renderer = BattleRenderer(episode.terrain, scale=args.scale, step_mul=episode.step_mul)
        print(f"replay {args.file}: map {episode.map_name}, {len(episode)} frames, "
              f"opponent {', '.join(episode.opponents) or 'unknown'} -> {out} "
              f"({renderer.frame_shape[1]}x{renderer.frame_shape[0]}, {args.fps:g} fps)")
        if not out.parent.is_dir():
            raise FileNotFoundError(f"folder {str(out.parent)!r} for --out does not exist")
        with atomic_path(out) as tmp:  # a video stopped halfway never replaces the target
            write_video(episode.render(renderer), tmp, fps=args.fps)
    except (EpisodeError, FileNotFoundError, ImportError, ValueError, OverflowError) as err:
        print(f"smac-hard-gym replay: error: {err}", file=sys.stderr)
        return 2
    print(f"wrote {out}")
    return 0
