"""``smac-hard-gym solutions [--map M]``: play the known-solution scenarios and print their win rates and bounds."""

from __future__ import annotations

import argparse

HELP = ("play scripted strategies whose outcome is known from the game (alternating aggro, kiting, holding a "
        "choke, an arc with focus fire, the medivac as bait) against the opponents they beat or lose to, and check "
        "the win-rate bounds")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--map", default=None, help="only the scenarios on this map")
    parser.add_argument("--episodes", type=int, default=64, help="seeded episodes per pairing (default 64)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the episodes")
    parser.add_argument("--json", default=None, metavar="PATH", help="also write the table as JSON")


def run(args: argparse.Namespace) -> int:
    from smac_hard_gym.envs.solutions import check_claim
    from smac_hard_gym.files import write_json
    from smac_hard_gym.opponents.known_solutions import claims_for_map

    if args.episodes < 1:
        raise ValueError(f"--episodes must be a positive int, got {args.episodes}")
    claims = claims_for_map(args.map)  # an unknown map: ValueError, one line from the CLI
    print(f"{'map':<14}{'red (learner side)':<20}{'vs':<13}{'win rate':>9}  {'bound':<34}result")
    rows, failed = [], 0
    for claim in claims:
        verdict = check_claim(claim, episodes=args.episodes, seed=args.seed)
        bound = claim.bound
        if claim.better_than is not None:  # the comparison's measured rate in place of its name
            bound = bound.replace(f"> {claim.better_than}", f"> {verdict.other_rate:.2f} ({claim.better_than})")
        result = "holds" if verdict.holds else "FAILS"
        failed += not verdict.holds
        print(f"{claim.map_name:<14}{claim.red:<20}{claim.blue:<13}{verdict.rate:>9.2f}  {bound:<34}{result}")
        rows.append({"map": claim.map_name, "red": claim.red, "blue": claim.blue, "why": claim.why,
                     "win_rate": verdict.rate, "bound": claim.bound, "comparison_win_rate": verdict.other_rate,
                     "holds": verdict.holds, "episodes": args.episodes,
                     "seed": args.seed})
    if args.json:
        write_json(args.json, rows, indent=1)
    return 1 if failed else 0
