"""A ``smac`` import shim: put ``examples/epymarl/smac_shim`` on ``PYTHONPATH`` and code that does
``from smac.env import StarCraft2Env`` (EPyMARL's ``--env-config=sc2``, pymarl) gets smac-hard-gym's."""
