"""Import ``pysc2_evolved`` (the ``[sc2]`` extra) once, quietly, with an error that says how to install it."""

from __future__ import annotations

import logging

_HINT = "the sc2 backend needs the [sc2] extra: pip install 'smac-hard-gym[sc2]' (pysc2_evolved and websockets)"


def _import():
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)  # pysc2_evolved logs a warning about its timeout setting at import
    try:
        from pysc2_evolved import run_configs
        from pysc2_evolved.lib import portspicker, protocol, remote_controller
    except ImportError as err:
        raise ImportError(f"{_HINT} ({err})") from err
    finally:
        logging.disable(previous)
    return run_configs, portspicker, protocol, remote_controller


run_configs, portspicker, protocol, remote_controller = _import()

# What a lost or broken game raises while a game is being played.
GAME_ERRORS: tuple[type[BaseException], ...] = (
    protocol.ProtocolError, protocol.ConnectionError, remote_controller.RequestError, ConnectionError, OSError,
    TimeoutError,
)
