"""``smac-hard-gym scriptlab``: the SMAC-HARD paper's LLM script loop against any OpenAI-compatible server
(:mod:`smac_hard_gym.scriptlab`; docs/script_lab.md)."""

from __future__ import annotations

import argparse
import os
import sys

HELP = ("write opponent scripts with a language model: planner, coders and critic against any OpenAI-compatible "
        "chat server; generated scripts run only in the process sandbox")

ENDPOINT_ENV = "SMAC_HARD_GYM_LLM_ENDPOINT"
MODEL_ENV = "SMAC_HARD_GYM_LLM_MODEL"
DEFAULT_ENDPOINT = "http://127.0.0.1:8080/v1"  # llama.cpp's llama-server default


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from smac_hard_gym.scriptlab.client import KEY_ENV

    parser.add_argument("--map", required=True, help="map name (see `smac-hard-gym maps`)")
    parser.add_argument("--rounds", type=int, default=5, help="rounds at most (default 5)")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="output folder (default scriptlab_<map>); its files are listed in docs/script_lab.md")
    parser.add_argument("--endpoint", default=None,
                        help=f"the server's OpenAI-compatible base URL, before /chat/completions (default "
                             f"${ENDPOINT_ENV} or {DEFAULT_ENDPOINT})")
    parser.add_argument("--model", default=None, help=f"model name sent to the server (default ${MODEL_ENV} or "
                                                      "'local-model')")
    parser.add_argument("--key-env", default=None, metavar="NAME",
                        help=f"environment variable holding the API key (default {KEY_ENV}; OPENAI_API_KEY is used "
                             "for api.openai.com only). The key is never taken from the command line or written")
    parser.add_argument("--episodes", type=int, default=64, help="seeded episodes per pairing (default 64)")
    parser.add_argument("--tolerance", type=float, default=0.05,
                        help="stop when both sides' win rates move less than this between rounds (default 0.05)")
    parser.add_argument("--seed", type=int, default=0, help="episode e of every pairing is a battle seeded seed + e")
    parser.add_argument("--time-limit", type=float, default=2.0,
                        help="seconds a generated script may take per call in the sandbox (default 2)")
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds to wait for each LLM reply (default "
                                                                     "300)")
    parser.add_argument("--temperature", type=float, default=0.7, help="sampling temperature (default 0.7)")
    parser.add_argument("--quiet", action="store_true", help="print only the summary")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from smac_hard_gym.maps import load_map
    from smac_hard_gym.scriptlab import ChatClient, LabConfig, LLMError, run_lab
    from smac_hard_gym.scriptlab.client import Transcript

    spec = load_map(args.map)  # an unknown map fails here, before any request
    out = Path(args.out or f"scriptlab_{spec.name}")
    endpoint = args.endpoint or os.environ.get(ENDPOINT_ENV) or DEFAULT_ENDPOINT
    model = args.model or os.environ.get(MODEL_ENV) or "local-model"
    config = LabConfig(map_name=spec.name, out=out, rounds=args.rounds, episodes=args.episodes,
                       tolerance=args.tolerance, seed=args.seed, time_limit=args.time_limit,
                       progress=not args.quiet)
    config.check()
    client = ChatClient(endpoint, model, key_env=args.key_env, timeout=args.timeout, temperature=args.temperature,
                        transcript=Transcript(out / "transcript.jsonl"))
    try:
        result = run_lab(config, client)
    except LLMError as err:
        print(f"smac-hard-gym scriptlab: error: {err}", file=sys.stderr)
        return 2
    state = "settled" if result.settled else "did not settle"
    print(f"scriptlab {spec.name}: {len(result.rounds)} round(s), {state}; kept "
          f"{', '.join(f'{s} {p}' for s, p in result.kept.items()) or 'nothing'}; report {out / 'report.md'}")
    return 0
