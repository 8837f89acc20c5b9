"""PettingZoo door of smac-hard-gym (``pip install 'smac-hard-gym[pettingzoo]'``).

>>> from smac_hard_gym.pettingzoo import parallel_env
>>> env = parallel_env(map_name="3m")                      # red's units as agents, blue a script
>>> observations, infos = env.reset(seed=0)
>>> sorted(observations["red_0"])
['action_mask', 'observation']
>>> env = parallel_env(map_name="3m", teams="both")        # self-play: red and blue units as agents
>>> env.possible_agents
['red_0', 'red_1', 'red_2', 'blue_0', 'blue_1', 'blue_2']

See :class:`~smac_hard_gym.envs.pettingzoo.SMACHardParallelEnv` for spaces, rewards, state and episode end.
Importing this module imports PettingZoo; ``import smac_hard_gym`` alone does not.
"""

from smac_hard_gym.envs.pettingzoo import TEAMS, SMACHardParallelEnv, env, parallel_env

__all__ = ["parallel_env", "env", "SMACHardParallelEnv", "TEAMS"]
