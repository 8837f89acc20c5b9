"""Empty stand-in for ``smaclite``: EPyMARL's ``envs/__init__.py`` imports its smaclite wrapper, which imports
``smaclite`` at module level, so EPyMARL fails to start without it. Nothing here is used by ``--env-config=sc2``;
run_reference.py puts this folder on PYTHONPATH only when no real smaclite is installed."""
