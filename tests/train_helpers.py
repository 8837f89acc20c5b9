"""Helpers shared by the training tests."""

from sb3_contrib import MaskablePPO


def interrupt_learn_at(monkeypatch, steps):
    """MaskablePPO.learn raising KeyboardInterrupt (Ctrl-C) once ``steps`` env steps have been trained."""
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList

    learn = MaskablePPO.learn

    class CtrlC(BaseCallback):
        def _on_step(self):
            if self.num_timesteps >= steps:
                raise KeyboardInterrupt
            return True

    def interrupted_learn(self, total_timesteps, callback=None, **kwargs):
        return learn(self, total_timesteps, callback=CallbackList([callback, CtrlC()]), **kwargs)

    monkeypatch.setattr(MaskablePPO, "learn", interrupted_learn)
