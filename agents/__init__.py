"""Policies, feature extractors and training helpers for the semreloc envs (stable-baselines3 + torch).

Heavy imports (torch, SB3) happen in the submodules that need them, so
``agents.baselines`` stays cheap for scripts that only drive a robot.
"""
