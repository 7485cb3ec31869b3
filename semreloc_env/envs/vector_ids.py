"""Vector entry points of the registered ``SemRelocVec-*`` ids (one per single-robot id they follow)."""

from __future__ import annotations

from .batched import SemRelocLoopVectorEnv


def single_env_refused(**kwargs):
    """The ``entry_point`` of every ``SemRelocVec-*`` id: those ids make R robots in one process, with
    ``gym.make_vec(id, num_envs=R)``; a single env, or Gymnasium's own vector envs, come from the
    ``SemReloc-*`` id, whose spec adds the reset check (`semreloc_env.wrappers.CheckedReset`) that a
    vector id's spec cannot carry (``make_vec`` refuses a vector entry point on a spec with wrappers).

    Raises:
        gymnasium.error.Error: always, naming the ids to use instead.
    """
    from gymnasium.error import Error

    raise Error(
        "SemRelocVec-* ids make R robots in one process: gym.make_vec('SemRelocVec-vN', num_envs=R) "
        "(vectorization_mode 'vector_entry_point', their default). For one env use gym.make('SemReloc-vN'); "
        "for Gymnasium's sync or async vector envs gym.make_vec('SemReloc-vN', num_envs=R, "
        "vectorization_mode='sync')"
    )


def _loop(env_id: str, num_envs: int, kwargs: dict) -> SemRelocLoopVectorEnv:
    if "env_id" in kwargs:
        raise TypeError(
            f"{env_id.replace('-', 'Vec-')} runs {env_id}; for another single env use SemRelocLoopVectorEnv(env_id=...)"
        )
    return SemRelocLoopVectorEnv(num_envs, env_id=env_id, **kwargs)


def semreloc_vec_v22(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v22``: ``num_envs`` ``SemReloc-v22`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v22"``)."""
    return _loop("SemReloc-v22", num_envs, kwargs)


def semreloc_vec_v21(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v21``: ``num_envs`` ``SemReloc-v21`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v21"``)."""
    return _loop("SemReloc-v21", num_envs, kwargs)


def semreloc_vec_v20(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v20``: ``num_envs`` ``SemReloc-v20`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v20"``)."""
    return _loop("SemReloc-v20", num_envs, kwargs)


def semreloc_vec_v19(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v19``: ``num_envs`` ``SemReloc-v19`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v19"``)."""
    return _loop("SemReloc-v19", num_envs, kwargs)


def semreloc_vec_v18(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v18``: ``num_envs`` ``SemReloc-v18`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v18"``)."""
    return _loop("SemReloc-v18", num_envs, kwargs)


def semreloc_vec_v17(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v17``: ``num_envs`` ``SemReloc-v17`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v17"``)."""
    return _loop("SemReloc-v17", num_envs, kwargs)


def semreloc_vec_v16(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v16``: ``num_envs`` ``SemReloc-v16`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v16"``)."""
    return _loop("SemReloc-v16", num_envs, kwargs)


def semreloc_vec_v15(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v15``: ``num_envs`` ``SemReloc-v15`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v15"``)."""
    return _loop("SemReloc-v15", num_envs, kwargs)


def semreloc_vec_v14(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v14``: ``num_envs`` ``SemReloc-v14`` robots in one process."""
    return _loop("SemReloc-v14", num_envs, kwargs)


def semreloc_vec_v13(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v13``: ``num_envs`` ``SemReloc-v13`` robots in one process."""
    return _loop("SemReloc-v13", num_envs, kwargs)


def semreloc_vec_v12(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v12``: ``num_envs`` ``SemReloc-v12`` robots in one process."""
    return _loop("SemReloc-v12", num_envs, kwargs)


def semreloc_vec_v11(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v11``: ``num_envs`` ``SemReloc-v11`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v11"``)."""
    return _loop("SemReloc-v11", num_envs, kwargs)


def semreloc_vec_v10(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v10``: ``num_envs`` ``SemReloc-v10`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v10"``)."""
    return _loop("SemReloc-v10", num_envs, kwargs)


def semreloc_vec_v9(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v9``: ``num_envs`` ``SemReloc-v9`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v9"``)."""
    return _loop("SemReloc-v9", num_envs, kwargs)


def semreloc_vec_v8(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v8``: ``num_envs`` ``SemReloc-v8`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v8"``)."""
    return _loop("SemReloc-v8", num_envs, kwargs)


def semreloc_vec_v7(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v7``: ``num_envs`` ``SemReloc-v7`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v7"``)."""
    return _loop("SemReloc-v7", num_envs, kwargs)


def semreloc_vec_v6(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v6``: ``num_envs`` ``SemReloc-v6`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v6"``)."""
    return _loop("SemReloc-v6", num_envs, kwargs)


def semreloc_vec_v5(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v5``: ``num_envs`` ``SemReloc-v5`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v5"``)."""
    return _loop("SemReloc-v5", num_envs, kwargs)


def semreloc_vec_v4(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v4``: ``num_envs`` ``SemReloc-v4`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v4"``)."""
    return _loop("SemReloc-v4", num_envs, kwargs)


def semreloc_vec_v3(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v3``: ``num_envs`` ``SemReloc-v3`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v3"``)."""
    return _loop("SemReloc-v3", num_envs, kwargs)


def semreloc_vec_v2(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v2``: ``num_envs`` ``SemReloc-v2`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v2"``)."""
    return _loop("SemReloc-v2", num_envs, kwargs)


def semreloc_vec_v1(num_envs: int = 1, **kwargs) -> SemRelocLoopVectorEnv:
    """``SemRelocVec-v1``: ``num_envs`` ``SemReloc-v1`` robots in one process
    (`SemRelocLoopVectorEnv` with ``env_id="SemReloc-v1"``)."""
    return _loop("SemReloc-v1", num_envs, kwargs)
