"""Vector entry points of the registered ``SemRelocVec-*`` ids (one per single-robot id they follow)."""

from __future__ import annotations

from .batched import SemRelocLoopVectorEnv


def semreloc_vec_v2(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v2``: ``num_envs`` ``SemReloc-v2`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v2"``).
    ``SemRelocVec-v1`` is the class itself, whose ``env_id`` defaults to ``"SemReloc-v1"``."""
    if "env_id" in kwargs:
        raise TypeError("SemRelocVec-v2 runs SemReloc-v2; for another single env use SemRelocLoopVectorEnv(env_id=...)")
    return SemRelocLoopVectorEnv(num_envs, env_id="SemReloc-v2", **kwargs)
