"""Policies, feature extractors and training helpers for the semreloc envs (stable-baselines3 + torch).

Heavy imports (torch, SB3) happen in the submodules that need them, so
``agents.baselines`` stays cheap for scripts that only drive a robot.
"""


def __getattr__(name: str):
    # `agents.load_policy` without importing the learned-policy module (and gymnasium) up front
    if name in ("load_policy", "SHIPPED_POLICY"):
        from . import learned

        return getattr(learned, name)
    raise AttributeError(f"module 'agents' has no attribute {name!r}")
