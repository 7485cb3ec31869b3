"""What every semreloc env shares: layout, world, sensors, seeding, action checks, rendering hook.

Subclasses add their estimator (``_reset_estimator`` / ``_step_estimator``), their
``info`` entries and reward terms. The world is rebuilt on every reset.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from filters.motion.odometry import OdometryMotionConfig
from filters.numbers import is_int

from ..config import CameraParams, LidarParams, PhysicsParams, RobotParams, coerce_config, default_odometry_noise
from ..layouts import PROCEDURAL_LAYOUTS, PROCEDURAL_VERSION, Layout, check_layout_seed, get_layout
from ..sensors import Lidar, Odometry, SemanticCamera
from ..world import World, build_world, check_substep
from .spaces import decode_action, make_action_space, make_observation, make_observation_space


def check_seed_use(layout, layout_seed, scenario: str) -> None:
    """ValueError if a nonzero ``layout_seed`` would be ignored: it seeds only the procedural layouts
    and the ``"changed"`` scenario's obstacles. (A `Layout` object passes with any seed: `RandomLayout`
    hands over the drawn layout with the seed it was drawn from.)"""
    procedural = isinstance(layout, str) and layout in PROCEDURAL_LAYOUTS
    if scenario != "changed" and check_layout_seed(layout_seed) and not (procedural or isinstance(layout, Layout)):
        raise ValueError(
            f"layout_seed={layout_seed} seeds only the procedural layouts {list(PROCEDURAL_LAYOUTS)} (and the "
            f"'changed' scenario's obstacles); layout {str(layout)!r:.80} does not use it"
        )


class SemRelocBase(gym.Env):
    """Base class; see `SemRelocEnv` for the spec."""

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}
    _reset_option_keys: frozenset[str] = frozenset({"pose"})
    observation_layout: ClassVar[str] = "typed"
    """``"typed"`` (semantic ranges and class labels in separate entries, the labels ``MultiDiscrete``) or
    ``"flat"`` (one float32 ``semantic`` Box, kept by the older env ids): `.spaces.make_observation_space`."""
    info_missing: ClassVar[str] = "drop"
    """How ``info`` shows a value not computed in a step: ``"drop"`` leaves its key out (so vector envs batch
    the rest as typed arrays, with ``_key`` masks marking who has it); ``"none"`` (older env ids) puts None."""
    procedural_version: ClassVar[int] = PROCEDURAL_VERSION
    """Which version of the procedural generator a layout *name* and ``layout_seed`` resolve with
    (`semreloc_env.layouts.get_layout`); older env ids keep 1, so that their episodes stay as they were."""
    _world_option_keys: frozenset[str] = frozenset({"pose"})
    """Reset options whose check needs the world (`check_reset` builds one only for them)."""
    odometry_reads_slides: bool = True
    """Whether the simulated odometry reads a slide along a wall (`semreloc_env.sensors.Odometry`)."""
    odometry_exact_small_moves: bool = False
    """Whether the simulated odometry's default noise model (`semreloc_env.config.default_odometry_noise`) moves a step
    under ``min_trans_m`` in its own direction (`filters.motion.odometry.OdometryMotionConfig.exact_small_moves`);
    ``odometry=`` overrides it."""

    def __init__(
        self,
        layout: str | Path | dict | Layout = "lab",
        layout_seed: int = 0,
        action_type: str = "discrete",
        robot: dict | RobotParams | None = None,
        physics: dict | PhysicsParams | None = None,
        lidar: dict | LidarParams | None = None,
        camera: dict | CameraParams | None = None,
        odometry: dict | OdometryMotionConfig | None = None,
        render_mode: str | None = None,
    ):
        if render_mode is not None and not (
            isinstance(render_mode, str) and render_mode in self.metadata["render_modes"]
        ):
            raise ValueError(f"unknown render_mode {render_mode!r}; choose one of {self.metadata['render_modes']}")
        self.layout_seed = check_layout_seed(layout_seed)
        self.layout = get_layout(layout, seed=self.layout_seed, procedural_version=self.procedural_version)
        self.robot_params = coerce_config(RobotParams, robot, "robot")
        self.physics_params = coerce_config(PhysicsParams, physics, "physics")
        check_substep(self.robot_params, self.physics_params)  # now, not at the first reset
        # one frame per control step: videos (RecordVideo) and human mode play in real time
        self.metadata = {**type(self).metadata, "render_fps": self.physics_params.control_hz}
        self.lidar = Lidar(coerce_config(LidarParams, lidar, "lidar"))
        self.camera = SemanticCamera(coerce_config(CameraParams, camera, "camera"))
        self.odometry = Odometry(
            coerce_config(
                OdometryMotionConfig, odometry, "odometry", default_odometry_noise(self.odometry_exact_small_moves)
            ),
            reads_slides=self.odometry_reads_slides,
            substeps=self.physics_params.substeps,
        )
        self.action_space = make_action_space(action_type)
        self.action_type = action_type
        self.observation_space = make_observation_space(self.lidar.params, self.camera.params, self.observation_layout)
        self.render_mode = render_mode
        self.world: World | None = None
        self._renderer = None
        self._last: dict[str, Any] = {}

    # ------------------------------------------------------------------ hooks
    def _extra_obstacles(self) -> list:
        """Polygons added to the world but not to the layout (none by default)."""
        return []

    def _validate_options(self, options: dict, world: World | None) -> None:
        """Raise ValueError for bad reset options, before any state changes (``world`` is None when
        no option in `_world_option_keys` is set and the caller is `check_reset`)."""

    def _reset_estimator(self, options: dict) -> None:  # pragma: no cover - overridden
        pass

    def _step_estimator(self, odom: np.ndarray, lidar_scan, semantic_scan) -> None:  # pragma: no cover
        pass

    def _info(self) -> dict[str, Any]:
        return {"pose": self.world.pose.copy()}

    def _reward_terms(self, collided: bool) -> dict[str, float]:
        return {"collision": -1.0 if collided else 0.0}

    def _terminated(self) -> bool:
        return False

    # ------------------------------------------------------------------ API
    def check_reset(self, *, seed: int | None = None, options: dict | None = None) -> None:
        """Raise ValueError if ``reset(seed=seed, options=options)`` would reject its arguments.

        Changes nothing. The registered envs run it in their outermost wrapper
        (`semreloc_env.wrappers.CheckedReset`) so that a rejected reset never reaches
        Gymnasium's ``TimeLimit``, which zeroes its step counter before passing ``reset`` on.
        """
        self._prepare_reset(seed, options, need_world=False)

    def _prepare_reset(self, seed, options, need_world: bool = True) -> tuple[dict, World | None]:
        """Validated ``(options, fresh world)`` for a reset; ValueError naming the bad argument.

        With ``need_world=False`` (`check_reset`) the pymunk world is only built when an
        option in `_world_option_keys` needs it for its check; otherwise ``world`` is None
        (and `_validate_options` gets None). The checks are the same either way.
        """
        if seed is not None and not (is_int(seed) and seed >= 0):
            raise ValueError(f"reset seed must be None or an integer >= 0, got {type(seed).__name__} {seed!r:.60}")
        if options is None:
            options = {}
        elif not isinstance(options, Mapping):
            raise ValueError(f"reset options must be a dict or None, got {type(options).__name__} {options!r:.60}")
        options = dict(options)
        unknown = set(options) - self._reset_option_keys
        if unknown:
            raise ValueError(
                f"unknown reset options {sorted(unknown, key=repr)}; valid: {sorted(self._reset_option_keys)}"
            )
        world = None
        if need_world or any(options.get(k) is not None for k in self._world_option_keys):
            world = build_world(self.layout, self.robot_params, self.physics_params, self._extra_obstacles())
            if options.get("pose") is not None:
                world.set_pose(options["pose"])  # raises before any state changes
        self._validate_options(options, world)
        return options, world

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        options, world = self._prepare_reset(seed, options)
        seed = None if seed is None else int(seed)
        saved = dict(self.__dict__)  # a reset that fails below must leave the old episode intact
        if seed is None:  # the generator is kept, and spawning child streams advances its seed sequence in place
            saved["_np_random"] = copy.deepcopy(self.__dict__.get("_np_random"))
        try:
            super().reset(seed=seed)
            # independent streams: world/start pose, sensors, odometry, estimator
            self._start_rng, self._sensor_rng, self._odom_rng, self._estimator_rng = self.np_random.spawn(4)
            if options.get("pose") is None:
                world.set_pose(world.sample_free_pose(self._start_rng))
            self.world = world
            self._steps = 0
            odom = np.zeros(3)
            lidar_scan, semantic_scan = self._sense()
            self._reset_estimator(options)
            self._step_estimator(odom, lidar_scan, semantic_scan)
        except BaseException:  # a Ctrl-C too: the wrappers (RandomLayout) put theirs back on any exit
            self.__dict__.clear()
            self.__dict__.update(saved)
            raise
        obs = make_observation(lidar_scan, semantic_scan, odom, self.observation_layout)
        self._last = {"lidar": lidar_scan, "semantic": semantic_scan}
        info = self._info()
        if self.render_mode == "human":
            self.render()
        return obs, info

    def _sense(self):
        pose = self.world.pose
        return self.lidar.read(self.world, pose, self._sensor_rng), self.camera.read(self.world, pose, self._sensor_rng)

    def _move(self, v: float, w: float) -> tuple[bool, np.ndarray]:
        """Drive one control step at ``v`` m/s and ``w`` rad/s (a decoded action); returns (collided, true
        previous pose). Hook for kidnapping."""
        prev = self.world.pose
        return self.world.drive(v, w), prev

    def step(self, action):
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        v, w = decode_action(action, self.action_type, self.action_space, self.robot_params)  # validate first
        collided, prev = self._move(v, w)
        self._steps += 1
        odom = self.odometry.read(prev, self.world.pose, self._odom_rng)
        lidar_scan, semantic_scan = self._sense()
        self._step_estimator(odom, lidar_scan, semantic_scan)
        self._last = {"lidar": lidar_scan, "semantic": semantic_scan}
        terms = self._reward_terms(collided)
        info = self._info()
        info["rewards"] = terms
        info["collided"] = collided
        if self.render_mode == "human":
            self.render()
        return (
            make_observation(lidar_scan, semantic_scan, odom, self.observation_layout),
            float(sum(terms.values())),
            self._terminated(),
            False,
            info,
        )

    # ------------------------------------------------------------------ render
    def _render_state(self) -> dict[str, Any]:
        """What the renderer draws; subclasses add their belief."""
        return {
            "layout": self.world.layout,  # the running episode's (set_layout takes effect at the next reset)
            "robot_radius_m": self.robot_params.radius_m,
            "pose": self.world.pose,
            "lidar": self._last.get("lidar"),
            "semantic": self._last.get("semantic"),
            "extra_obstacles": self._extra_obstacles(),
        }

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.world is None:
            raise RuntimeError("call reset() before render()")
        from ..render import Renderer  # lazy: matplotlib only when drawing

        if self._renderer is not None and self._renderer.layout is not self.world.layout:
            self._renderer.close()  # a new layout since (set_layout, then reset): its own frame size
            self._renderer = None
        if self._renderer is None:
            human = self.render_mode == "human"
            self._renderer = Renderer(
                self.world.layout, human=human, fps=self.metadata["render_fps"] if human else None
            )
        frame = self._renderer.draw(self._render_state())
        return frame if self.render_mode == "rgb_array" else None

    def __getstate__(self) -> dict[str, Any]:
        """Pickle and deep-copy without the renderer (a matplotlib figure, which does not pickle); a
        copy draws its own at its first `render`."""
        state = self.__dict__.copy()
        state["_renderer"] = None
        return state

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
