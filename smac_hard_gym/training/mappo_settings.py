"""MAPPO's PPO settings for each SMAC map: the shared policy's per-map defaults (``train --policy shared``).

MAPPO's authors tuned a few PPO settings per map and published them as one launch script per map
(marlbenchmark/on-policy, commit de66d7a, ``onpolicy/scripts/train_smac_scripts/train_smac_<map>.sh``; the
SMAC-HARD repository's on-policy copy has the same). Every script runs 8 threads x 400 steps (3,200 samples an
update, as our 64 battles x 50 steps), learning rate 5e-4, entropy 0.01, gamma 0.99; they differ in:

- ``epochs`` (``--ppo_epoch``): 15 by default, 10 or 5 on the larger maps;
- ``minibatches`` (``--num_mini_batch``): 1, except 2 on MMM2;
- ``memory``: "gru" where the script runs ``rmappo`` (a recurrent actor and critic), "frames" where it runs
  ``mappo`` with ``--use_stacked_frames --stacked_frames 4`` (3s_vs_4z, 3s_vs_5z), "none" where it runs ``mappo``
  without stacking (corridor, 6h_vs_8z);
- ``clip`` (``--clip_param``): each agent's probability ratio is clipped at 0.2, at 0.05 on 3s_vs_5z, 5m_vs_6m and
  8m_vs_9m.

The shared policy has no recurrent core; its memory is stacked frames, so "gru" and "frames" both give 4 frames
(the number MAPPO stacks) and "none" gives 1. MAPPO's clip carries over where the ratio is MAPPO's, per unit
(``train --ratio unit``, :mod:`~smac_hard_gym.wrappers.sb3_unit_ppo`). SB3's MaskablePPO (``--ratio joint``) clips
the joint ratio, the product over the units, so there MAPPO's clip does not carry over and the shared policy's clip
on the joint ratio is measured instead (docs/training_results.md): 0.05 where MAPPO runs 15
epochs (2s_vs_1sc: 1.00 on three seeds, where 0.2 lost two of them; 3s_vs_5z), 0.2 where it runs 10 or 5, its
larger maps (25m and 27m_vs_30m learn nothing in 200k steps at 0.05 with those epochs; they win at 0.2): fewer
gradient passes an update take a looser trust region. Not carried over either: MMM2's ``--gain 1`` (the initial
scale of the action layer; ours keeps SB3's 0.01, as MAPPO's other maps) and ``--use_value_active_masks`` (the
value loss of dead agents; our critic gives one value per battle). 2s3z has no script: it gets MAPPO's defaults,
as any map not listed.

Where a measurement shows MAPPO's memory buys nothing, the shared policy leaves it out (``MEASURED``): on
27m_vs_30m one frame and four win the same (1.00 on three seeds each at 400k steps) and one frame trains 2.35x
faster; on 25m one frame wins 1.00 from 200k steps on two seeds, four frames 0.75, 1.00 and 0.09 at 200k. A
marine's cooldown, 13.8 game loops, is under two env steps, so there is little to remember. On 3s_vs_5z a joint
clip of 0.15, near MAPPO's per-unit 0.05 over three units (1.05^3 = 1.16), won 0.69, 1.00 and 1.00 at 2M steps
(seeds 0-2) where 0.05 won 0.00, 0.09 and 1.00 (the engine with C14); on 3s_vs_4z 0.15 won 1.00 on seeds 0-2 at 1M
steps where 0.05 won 0.16 (seed 0); on 8m_vs_9m, MAPPO's 15-epoch map with eight units, 0.2 won 1.00, 1.00 and
0.94 on seeds 0-2 at 1M steps where 0.05 won 0.78 (seed 0). On 3m, the README's quick start, MAPPO's 15 epochs of
one minibatch at 0.05 learn too slowly for a short run (measured on the engine before the weapons' wind-up, when the
quick start was 50k steps): 50k steps against the ``default`` pool win 0.44 and the sampled training battles none
by 100k, where 10 epochs of 4 minibatches at 0.2 win 0.63 and 0.47 of them (the joint MLP: 0.66 and 0.69), and
against SMAC's opponent 1.00 at 1M steps on seeds 0 and 1 (docs/training_results.md, "Which policy ``train`` uses
by default"). With the actor reading its unit's state row (``actor_state``, the shared policy's default), which holds
the weapon's cooldown, 3s_vs_5z takes one frame: at 2M steps one frame won 0.56, 0.97, 1.00, 1.00 and 0.41 (seeds
0-4) where four won 1.00, 0.00, 0.94, 0.00 and 0.00 on the engine with the wind-up and its range slop. On 6h_vs_8z
MAPPO's settings (5 epochs of one 3,200-sample minibatch) win nothing in 1M steps on the engine now, where EPyMARL's
QMIX learns the map (0.38 at 0.5M steps, its checkpoint 0.93 in replays): the joint MLP's PPO settings (64 battles x
32 steps in 10 epochs of 4 minibatches, clip 0.2) won 0.91 and 1.00 at 1M steps (seeds 0, 1), so 6h_vs_8z takes
them.
"""

from __future__ import annotations

from typing import Any

__all__ = ["MAPPO_SMAC", "MAPPO_DEFAULT", "MEASURED", "FRAMES_FOR_MEMORY", "CLIP_FOR_EPOCHS", "RATIOS",
           "shared_map_defaults"]

# MAPPO's config.py defaults (a map without a script); n_steps: 64 battles x 50 steps per rollout stand for its 8
# threads x 400
MAPPO_DEFAULT: dict[str, Any] = {"epochs": 15, "minibatches": 1, "memory": "gru", "clip": 0.2, "n_steps": 50}

# what differs from MAPPO_DEFAULT in each map's script
MAPPO_SMAC: dict[str, dict[str, Any]] = {
    "3m": {}, "8m": {}, "MMM": {}, "1c3s5z": {}, "2m_vs_1z": {}, "2s_vs_1sc": {}, "3s_vs_3z": {},
    "bane_vs_bane": {}, "so_many_baneling": {},
    "25m": {"epochs": 10}, "10m_vs_11m": {"epochs": 10},
    "5m_vs_6m": {"epochs": 10, "clip": 0.05}, "8m_vs_9m": {"clip": 0.05},
    "27m_vs_30m": {"epochs": 5}, "3s5z": {"epochs": 5}, "3s5z_vs_3s6z": {"epochs": 5}, "2c_vs_64zg": {"epochs": 5},
    "MMM2": {"epochs": 5, "minibatches": 2},
    "3s_vs_4z": {"memory": "frames"},
    "3s_vs_5z": {"memory": "frames", "clip": 0.05},
    "corridor": {"epochs": 5, "memory": "none"}, "6h_vs_8z": {"epochs": 5, "memory": "none"},
}

# where our measurements differ from MAPPO's choice (docs/training_results.md, "MAPPO's settings for each map");
# "joint_clip" overrides CLIP_FOR_EPOCHS: on 3s_vs_5z MAPPO's per-unit 0.05 over three units (1.05 ** 3 = 1.16),
# and the same on 3s_vs_4z, its three stalkers against four zealots; on 8m_vs_9m 0.2, the clip of the 10- and
# 5-epoch maps (0.05 learned it late); on 3m, the quick start's map, 10 epochs of 4 minibatches at 0.2: MAPPO's 15
# small passes learn it too slowly for a short run
# "memory_with_state": the memory when the actor reads its unit's state row, which holds the weapon's cooldown: on
# 3s_vs_5z one frame then won on each of five seeds (0.41-1.00 at 2M) where four frames won on two of five;
# 6h_vs_8z takes the joint MLP's PPO settings (32-step rollouts, 10 epochs of 4 minibatches of 512, clip 0.2), which
# learn the map as EPyMARL's QMIX does on this engine, where MAPPO's win nothing in 1M steps
MEASURED: dict[str, dict[str, Any]] = {"27m_vs_30m": {"memory": "none"}, "25m": {"memory": "none"},
                                       "3s_vs_5z": {"joint_clip": 0.15, "memory_with_state": "none"},
                                       "3s_vs_4z": {"joint_clip": 0.15},
                                       "8m_vs_9m": {"joint_clip": 0.2},
                                       "3m": {"epochs": 10, "minibatches": 4, "joint_clip": 0.2},
                                       "6h_vs_8z": {"n_steps": 32, "epochs": 10, "minibatches": 4, "joint_clip": 0.2}}

FRAMES_FOR_MEMORY = {"gru": 4, "frames": 4, "none": 1}
CLIP_FOR_EPOCHS = {15: 0.05, 10: 0.2, 5: 0.2}  # the joint ratio's clip by MAPPO's epochs for the map (measured)


RATIOS = ("joint", "unit")  # what PPO clips: SB3's joint ratio, or each unit's (MAPPO's)


def shared_map_defaults(map_name: str, ratio: str = "joint", actor_state: bool = False) -> dict[str, Any]:
    """The shared policy's TrainConfig defaults for ``map_name``: ``n_steps`` (per battle and rollout, for 64
    battles), ``n_epochs``, ``frame_stack`` (with ``actor_state``, for an actor that reads its unit's state row),
    ``clip_range`` (for the ``ratio`` PPO clips) and ``minibatches`` (the rollout is split into that many
    minibatches)."""
    if ratio not in RATIOS:
        raise ValueError(f"ratio must be one of {RATIOS}, got {ratio!r}")
    settings = {**MAPPO_DEFAULT, **MAPPO_SMAC.get(map_name, {}), **MEASURED.get(map_name, {})}
    clip = settings["clip"] if ratio == "unit" else settings.get("joint_clip", CLIP_FOR_EPOCHS[settings["epochs"]])
    memory = settings.get("memory_with_state", settings["memory"]) if actor_state else settings["memory"]
    return {"n_steps": settings["n_steps"], "n_epochs": settings["epochs"], "frame_stack": FRAMES_FOR_MEMORY[memory],
            "clip_range": clip, "minibatches": settings["minibatches"]}
