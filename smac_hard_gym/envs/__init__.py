"""The environment APIs, layered: ``core`` (the two-player core: B battles, a backend, SMAC's features for both
sides, the opponent hook) below ``joint_view`` (the learner's side as one joint agent), and the user-facing envs
over them: ``gym_env`` (``SMACHardEnv``), ``vector`` (``NativeVectorEnv``), ``subproc`` (``SubprocVectorEnv``) and
``starcraft2`` (SMAC's ``StarCraft2Env``)."""
