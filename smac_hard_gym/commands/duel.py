"""``smac-hard-gym duel``: two scripts fight on the two-player core (``smac_hard_gym.envs.duel``); prints win and draw
rates."""

from __future__ import annotations

import argparse

HELP = "pit two opponent scripts against each other on a map and print win/draw rates"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--map", required=True, help="map name (see `smac-hard-gym maps`)")
    parser.add_argument("--red", required=True,
                        help="script for the red (learner's) side: a name, names joined by commas (a mixture), "
                             "default, blackbox, file.py[:Class] or module:Name; red units are SMAC's passive *_RL "
                             "units, so it must give orders")
    parser.add_argument("--blue", required=True, help="script for the blue (opponent's) side, same forms")
    parser.add_argument("--episodes", type=int, default=20, help="episodes to play (default 20)")
    parser.add_argument("--seed", type=int, default=0,
                        help="episode e is a battle seeded seed + e (as SMACHardEnv.reset(seed=seed + e))")
    parser.add_argument("--batch", type=int, default=None,
                        help="battles run at once (default: all episodes, at most 64)")
    parser.add_argument("--red-probs", type=float, nargs="+", default=None, help="mixture weights for --red")
    parser.add_argument("--blue-probs", type=float, nargs="+", default=None, help="mixture weights for --blue")
    parser.add_argument("--json", default=None, metavar="PATH", help="also write the result as JSON")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.add_argument("--record", default=None, metavar="DIR",
                        help="also record episodes to DIR as .npz files (see `smac-hard-gym replay`)")
    parser.add_argument("--record-episodes", type=int, default=4, metavar="N",
                        help="how many episodes --record saves (default 4; episode e is seeded seed + e)")


def run(args: argparse.Namespace) -> int:
    from smac_hard_gym.envs.duel import run_duel
    from smac_hard_gym.files import write_json
    from smac_hard_gym.opponents import opponent_from_text

    batch = args.batch if args.batch is not None else min(args.episodes, 64)
    print(f"duel on {args.map}: red={args.red} blue={args.blue} episodes={args.episodes} seed={args.seed} "
          f"batch={batch}")
    result = run_duel(args.map, opponent_from_text(args.red), opponent_from_text(args.blue), episodes=args.episodes,
                      seed=args.seed, batch_size=args.batch, red_probs=args.red_probs, blue_probs=args.blue_probs,
                      progress=not args.no_progress)
    print(f"red wins   {result.red_win_rate:7.1%}  ({result.red_wins})")
    print(f"blue wins  {result.blue_win_rate:7.1%}  ({result.blue_wins})")
    print(f"draws      {result.draw_rate:7.1%}  ({result.draws}, {result.timeouts} at the episode limit)")
    print(f"mean episode length {result.mean_steps:.1f} steps")
    if len(result.by_script) > 1:
        for pairing, counts in sorted(result.by_script.items()):
            print(f"  {pairing}: {counts['games']} games, red {counts['red_wins']}, blue {counts['blue_wins']}, "
                  f"draws {counts['draws']}")
    if args.json:
        write_json(args.json, result.to_dict(), indent=1)
        print(f"wrote {args.json}")
    if args.record:
        _record(args)
    return 0


def _record(args: argparse.Namespace) -> None:
    """Replay ``--record-episodes`` episodes of the same pairing one by one and save each as a recording."""
    from pathlib import Path

    from smac_hard_gym.envs.duel import record_engine_episode
    from smac_hard_gym.maps import load_map
    from smac_hard_gym.opponents import make_opponent

    if args.record_episodes < 1:
        raise SystemExit(f"--record-episodes must be >= 1, got {args.record_episodes}")
    folder = Path(args.record)
    folder.mkdir(parents=True, exist_ok=True)
    spec = load_map(args.map)
    for e in range(args.record_episodes):
        red = make_opponent(spec, args.red, args.red_probs)
        blue = make_opponent(spec, args.blue, args.blue_probs)
        recording = record_engine_episode(args.map, red, blue, seed=args.seed + e)
        path = folder / f"duel_{args.map}_{recording.metadata['red']}_vs_{recording.metadata['blue']}_{e}.npz"
        recording.save(path)
        print(f"recorded {path} (winner: {recording.metadata.get('winner')})")
