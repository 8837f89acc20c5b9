"""A StarCraft II stand-in for tests: exercises the real backend's launch and protocol paths without the game.

Kept apart from the production backend (:mod:`smac_hard_gym.sc2`): nothing there imports it except the lazy
``smac_hard_gym.sc2.make_sc2path`` export.

- :mod:`.server`: a protocol test server speaking s2clientprotocol over a loopback websocket
  (``python -m smac_hard_gym.sc2.testing.server``);
- :mod:`.game`: the game behind it, one battle of the native engine dressed as a two-player SC2 game;
- :mod:`.standin`: :func:`~smac_hard_gym.sc2.testing.standin.make_sc2path`, a throwaway SC2PATH whose
  ``SC2_x64`` is the test server.

Needs the ``[sc2]`` extra (s2clientprotocol, websockets).
"""
