"""SMAC's interface over the engine's state: features (observations, global state, rewards, outcomes), the action
set (availability, checking, decoding into engine commands) and the compiled kernels both run on."""
