"""semreloc: Gymnasium environments for semantic, active relocalization of a 2D mobile robot.

Importing the package registers the environments::

    import gymnasium as gym
    import semreloc_env  # noqa: F401

    env = gym.make("SemReloc-v22", layout="twin_rooms")
"""

from gymnasium.envs.registration import WrapperSpec, register, registry

from .layouts import CLASS_NAMES, Layout, LayoutError, get_layout, load_layout
from .world import World, build_world

__all__ = [
    "CLASS_NAMES",
    "ENV_IDS",
    "VECTOR_ENV_IDS",
    "Layout",
    "LayoutError",
    "World",
    "build_world",
    "get_layout",
    "load_layout",
    "default_relocalizer",
    "semreloc_class",
    "semreloc_ids_since",
]

ENV_IDS = (
    "SemReloc-v22",
    "SemReloc-v21",
    "SemReloc-v20",
    "SemReloc-v19",
    "SemReloc-v18",
    "SemReloc-v17",
    "SemReloc-v16",
    "SemReloc-v15",
    "SemReloc-v14",
    "SemReloc-v13",
    "SemReloc-v12",
    "SemReloc-v11",
    "SemReloc-v10",
    "SemReloc-v9",
    "SemReloc-v8",
    "SemReloc-v7",
    "SemReloc-v6",
    "SemReloc-v5",
    "SemReloc-v4",
    "SemReloc-v3",
    "SemReloc-v2",
    "SemReloc-v1",
    "SemReloc-v0",
    "SemSlam-v2",
    "SemSlam-v1",
    "SemSlam-v0",
)
"""Every registered single-robot id, newest first; the older ones are kept for reproducing old results and
running old policies (each env's Version History says what changed): ``SemReloc-v1`` and ``SemSlam-v0`` have
the flat observation, ``SemReloc-v0`` also the first release's relocalizer."""

VECTOR_ENV_IDS = (
    "SemRelocVec-v22",
    "SemRelocVec-v21",
    "SemRelocVec-v20",
    "SemRelocVec-v19",
    "SemRelocVec-v18",
    "SemRelocVec-v17",
    "SemRelocVec-v16",
    "SemRelocVec-v15",
    "SemRelocVec-v14",
    "SemRelocVec-v13",
    "SemRelocVec-v12",
    "SemRelocVec-v11",
    "SemRelocVec-v10",
    "SemRelocVec-v9",
    "SemRelocVec-v8",
    "SemRelocVec-v7",
    "SemRelocVec-v6",
    "SemRelocVec-v5",
    "SemRelocVec-v4",
    "SemRelocVec-v3",
    "SemRelocVec-v2",
    "SemRelocVec-v1",
)
"""Ids for ``gym.make_vec``: R robots of ``SemReloc-v22`` / ``-v21`` / ``-v20`` / ``-v19`` / ``-v18`` / ``-v17``
/ ``-v16`` / ``-v15`` / ``-v14`` / ``-v13`` / ``-v12`` / ``-v11`` / ``-v10`` / ``-v9`` / ``-v8`` / ``-v7`` / ``-v6``
/ ``-v5`` / ``-v4`` / ``-v3`` / ``-v2`` / ``-v1`` in one process."""


def semreloc_class(env_id: str):
    """The env class a registered ``SemReloc-*`` id makes (``SemReloc-v18``: `SemRelocEnvV18`). ValueError for
    another id."""
    from gymnasium.envs.registration import load_env_creator

    if env_id not in semreloc_ids_since(0):
        raise ValueError(f"no SemReloc relocalizer for env id {env_id!r}; ids: {semreloc_ids_since(0)}")
    return load_env_creator(registry[env_id].entry_point)


def default_relocalizer(env_id: str):
    """The `MCLConfig` a ``SemReloc-*`` id's relocalizer has unless ``relocalizer=`` overrides it (what
    command-line overrides are checked against). ValueError for another id."""
    return semreloc_class(env_id).default_relocalizer


def semreloc_ids_since(version: int) -> tuple[str, ...]:
    """The ``SemReloc-vN`` ids of `ENV_IDS` with ``N >= version``, newest first."""
    return tuple(i for i in ENV_IDS if i.startswith("SemReloc-v") and int(i.rsplit("v", 1)[1]) >= version)


# outermost: reset arguments are checked before TimeLimit zeroes its counter (wrappers.CheckedReset)
_CHECKED_RESET = (WrapperSpec("CheckedReset", "semreloc_env.wrappers:CheckedReset", {}),)

_SINGLE = {
    "SemReloc-v22": "semreloc_env.envs.semreloc:SemRelocEnv",
    "SemReloc-v21": "semreloc_env.envs.semreloc:SemRelocEnvV21",
    "SemReloc-v20": "semreloc_env.envs.semreloc:SemRelocEnvV20",
    "SemReloc-v19": "semreloc_env.envs.semreloc:SemRelocEnvV19",
    "SemReloc-v18": "semreloc_env.envs.semreloc:SemRelocEnvV18",
    "SemReloc-v17": "semreloc_env.envs.semreloc:SemRelocEnvV17",
    "SemReloc-v16": "semreloc_env.envs.semreloc:SemRelocEnvV16",
    "SemReloc-v15": "semreloc_env.envs.semreloc:SemRelocEnvV15",
    "SemReloc-v14": "semreloc_env.envs.semreloc:SemRelocEnvV14",
    "SemReloc-v13": "semreloc_env.envs.semreloc:SemRelocEnvV13",
    "SemReloc-v12": "semreloc_env.envs.semreloc:SemRelocEnvV12",
    "SemReloc-v11": "semreloc_env.envs.semreloc:SemRelocEnvV11",
    "SemReloc-v10": "semreloc_env.envs.semreloc:SemRelocEnvV10",
    "SemReloc-v9": "semreloc_env.envs.semreloc:SemRelocEnvV9",
    "SemReloc-v8": "semreloc_env.envs.semreloc:SemRelocEnvV8",
    "SemReloc-v7": "semreloc_env.envs.semreloc:SemRelocEnvV7",
    "SemReloc-v6": "semreloc_env.envs.semreloc:SemRelocEnvV6",
    "SemReloc-v5": "semreloc_env.envs.semreloc:SemRelocEnvV5",
    "SemReloc-v4": "semreloc_env.envs.semreloc:SemRelocEnvV4",
    "SemReloc-v3": "semreloc_env.envs.semreloc:SemRelocEnvV3",
    "SemReloc-v2": "semreloc_env.envs.semreloc:SemRelocEnvV2",
    "SemReloc-v1": "semreloc_env.envs.semreloc:SemRelocEnvV1",
    "SemReloc-v0": "semreloc_env.envs.semreloc:SemRelocEnvV0",
    "SemSlam-v2": "semreloc_env.envs.semslam:SemSlamEnv",
    "SemSlam-v1": "semreloc_env.envs.semslam:SemSlamEnvV1",
    "SemSlam-v0": "semreloc_env.envs.semslam:SemSlamEnvV0",
}
for _id, _entry in _SINGLE.items():
    if _id not in registry:
        register(id=_id, entry_point=_entry, max_episode_steps=400, additional_wrappers=_CHECKED_RESET)

# R robots in one process (a loop over SemReloc envs): gym.make_vec("SemRelocVec-v22", num_envs=R).
# Separate ids because make_vec refuses a vector entry point on a spec with additional wrappers; their
# single-env entry point refuses (a single env from them would lack CheckedReset): use SemReloc-* for that.
_VECTOR = {
    "SemRelocVec-v22": "semreloc_env.envs.vector_ids:semreloc_vec_v22",
    "SemRelocVec-v21": "semreloc_env.envs.vector_ids:semreloc_vec_v21",
    "SemRelocVec-v20": "semreloc_env.envs.vector_ids:semreloc_vec_v20",
    "SemRelocVec-v19": "semreloc_env.envs.vector_ids:semreloc_vec_v19",
    "SemRelocVec-v18": "semreloc_env.envs.vector_ids:semreloc_vec_v18",
    "SemRelocVec-v17": "semreloc_env.envs.vector_ids:semreloc_vec_v17",
    "SemRelocVec-v16": "semreloc_env.envs.vector_ids:semreloc_vec_v16",
    "SemRelocVec-v15": "semreloc_env.envs.vector_ids:semreloc_vec_v15",
    "SemRelocVec-v14": "semreloc_env.envs.vector_ids:semreloc_vec_v14",
    "SemRelocVec-v13": "semreloc_env.envs.vector_ids:semreloc_vec_v13",
    "SemRelocVec-v12": "semreloc_env.envs.vector_ids:semreloc_vec_v12",
    "SemRelocVec-v11": "semreloc_env.envs.vector_ids:semreloc_vec_v11",
    "SemRelocVec-v10": "semreloc_env.envs.vector_ids:semreloc_vec_v10",
    "SemRelocVec-v9": "semreloc_env.envs.vector_ids:semreloc_vec_v9",
    "SemRelocVec-v8": "semreloc_env.envs.vector_ids:semreloc_vec_v8",
    "SemRelocVec-v7": "semreloc_env.envs.vector_ids:semreloc_vec_v7",
    "SemRelocVec-v6": "semreloc_env.envs.vector_ids:semreloc_vec_v6",
    "SemRelocVec-v5": "semreloc_env.envs.vector_ids:semreloc_vec_v5",
    "SemRelocVec-v4": "semreloc_env.envs.vector_ids:semreloc_vec_v4",
    "SemRelocVec-v3": "semreloc_env.envs.vector_ids:semreloc_vec_v3",
    "SemRelocVec-v2": "semreloc_env.envs.vector_ids:semreloc_vec_v2",
    "SemRelocVec-v1": "semreloc_env.envs.vector_ids:semreloc_vec_v1",
}
for _id, _vector_entry in _VECTOR.items():
    if _id not in registry:
        register(
            id=_id,
            entry_point="semreloc_env.envs.vector_ids:single_env_refused",
            vector_entry_point=_vector_entry,
            max_episode_steps=400,
        )
