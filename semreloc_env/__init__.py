"""semreloc: Gymnasium environments for semantic, active relocalization of a 2D mobile robot.

Importing the package registers the environments::

    import gymnasium as gym
    import semreloc_env  # noqa: F401

    env = gym.make("SemReloc-v1", layout="twin_rooms")
"""

from gymnasium.envs.registration import WrapperSpec, register, registry

from .layouts import CLASS_NAMES, Layout, LayoutError, get_layout, load_layout
from .world import World, build_world

__all__ = ["CLASS_NAMES", "ENV_IDS", "Layout", "LayoutError", "World", "build_world", "get_layout", "load_layout"]

ENV_IDS = ("SemReloc-v1", "SemReloc-v0", "SemSlam-v0")
"""Every registered id; ``SemReloc-v0`` is the first release's relocalizer, kept for reproducing old results."""

# outermost: reset arguments are checked before TimeLimit zeroes its counter (wrappers.CheckedReset)
_CHECKED_RESET = (WrapperSpec("CheckedReset", "semreloc_env.wrappers:CheckedReset", {}),)

if "SemReloc-v1" not in registry:
    register(
        id="SemReloc-v1",
        entry_point="semreloc_env.envs.semreloc:SemRelocEnv",
        max_episode_steps=400,
        additional_wrappers=_CHECKED_RESET,
    )
if "SemReloc-v0" not in registry:
    register(
        id="SemReloc-v0",
        entry_point="semreloc_env.envs.semreloc:SemRelocEnvV0",
        max_episode_steps=400,
        additional_wrappers=_CHECKED_RESET,
    )
if "SemRelocVec-v1" not in registry:
    # R robots in one process (a loop over SemReloc-v1 envs): gym.make_vec("SemRelocVec-v1", num_envs=R).
    # A separate id because make_vec refuses a vector entry point on a spec with additional wrappers.
    register(
        id="SemRelocVec-v1",
        entry_point="semreloc_env.envs.semreloc:SemRelocEnv",
        vector_entry_point="semreloc_env.envs.batched:SemRelocLoopVectorEnv",
        max_episode_steps=400,
    )
if "SemSlam-v0" not in registry:
    register(
        id="SemSlam-v0",
        entry_point="semreloc_env.envs.semslam:SemSlamEnv",
        max_episode_steps=400,
        additional_wrappers=_CHECKED_RESET,
    )
