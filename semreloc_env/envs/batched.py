"""R robots in one process as a Gymnasium ``VectorEnv``: a loop over R ``SemReloc`` envs.

`SemRelocLoopVectorEnv` steps ``num_envs`` independent `SemRelocEnv`
instances (each its own world, sensors and particle filter) one after the other. What it
shares is what the process caches anyway: the map (`semreloc_env.maps.maps_for`), the
likelihood field (`filters.localization.likelihood_field.cached_model`) and the static
geometry of the world. It is *not* a fused kernel over robots: the per-robot cost is that of
one env (see ``docs/performance.md``). What it gives today is the Gymnasium vector API with
next-step autoreset, per-robot results equal bit for bit to R separate envs seeded
``seed + i``, and no subprocesses.

Create it with ``gym.make_vec("SemRelocVec-v22", num_envs=R, vectorization_mode="vector_entry_point")``
(or another ``SemRelocVec-*`` id, each running its ``SemReloc-*``) or directly (``env_id`` defaults to
the newest, ``"SemReloc-v22"``); `agents.vec_env.SB3VecEnvAdapter` turns it into a stable-baselines3
``VecEnv``.

Autoreset follows Gymnasium's ``NEXT_STEP`` mode: a robot whose episode ended
(terminated or truncated) in one ``step`` is reset by the *next* ``step`` call, which
ignores that robot's action and returns its reset observation with reward 0,
``terminated = truncated = False`` and the reset ``info``.
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Callable
from copy import deepcopy
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array

from filters.numbers import is_int

from ..wrappers import check_reset
from .spaces import decode_action

SINGLE_ENV_ID = "SemReloc-v22"


def float_array_hint(actions, space, first: int = 0) -> str:
    """For a float array of discrete actions (NumPy turns ``[0, 1, nan]`` into floats): which robots'
    entries are not finite, since the first robot's error names a float that looked fine."""
    if not (isinstance(actions, np.ndarray) and actions.dtype.kind == "f" and isinstance(space, gym.spaces.Discrete)):
        return ""
    bad = np.flatnonzero(~np.isfinite(actions.reshape(len(actions), -1)).all(axis=1))
    where = f"; robots {(bad + first).tolist()} hold NaN or inf" if bad.size else ""
    return f" (the actions are a {actions.dtype} array: discrete actions must be integers{where})"


def action_list(
    actions, num_envs: int, space: gym.spaces.Space, first: int = 0, hint_applies: Callable[[], bool] = lambda: True
) -> list:
    """``actions`` as a list of ``num_envs`` robots' actions, each robot's single action space ``space``; ValueError if
    ``actions`` is no sequence or holds another count, if it is an array of Box actions of another shape, or if it is
    a float array of discrete actions (`float_array_hint`, robots numbered from ``first``) where ``hint_applies()``
    (the robots' own checks would refuse every such float). Checks of the whole batch, before each robot's own."""
    try:
        scalar = isinstance(actions, (str, bytes)) or np.ndim(actions) == 0
    except (ValueError, RuntimeError):  # ragged, or a torch tensor that requires grad: each robot's own check says
        scalar = False
    if scalar:
        raise ValueError(f"actions must be a sequence of {num_envs} actions, got {actions!r:.80}")
    acts = list(actions)
    if len(acts) != num_envs:
        raise ValueError(f"got {len(acts)} actions for {num_envs} robots")
    hint = float_array_hint(actions, space, first)
    if hint and hint_applies():  # every robot's action is a float: robot 0 is not the one to name
        raise ValueError(f"invalid actions{hint}")
    if isinstance(actions, np.ndarray) and isinstance(space, gym.spaces.Box) and actions.shape[1:] != space.shape:
        raise ValueError(
            f"actions must have shape {(num_envs, *space.shape)} (one {space.shape} action per robot), "
            f"got shape {actions.shape}"
        )
    return acts


def in_wrapped_space(action, space: gym.spaces.Space) -> bool:
    """Whether a wrapper's action space takes ``action``: `gym.spaces.Space.contains`, except that a
    real-number array (or nested list) of a float Box's shape counts by its values cast to the Box's dtype,
    not by its own dtype (``Box.contains`` refuses float64 for a float32 Box, which the wrapped env
    itself takes, as NumPy's default float). Bools are refused."""
    if isinstance(action, (bool, np.bool_)):
        return False
    if isinstance(space, gym.spaces.Box) and space.dtype.kind == "f" and not isinstance(action, (str, bytes)):
        try:
            a = np.asarray(action)
        except (ValueError, TypeError):  # ragged
            return False
        if a.dtype.kind not in "iuf" or a.shape != space.shape:
            return False
        with np.errstate(over="ignore"):
            return bool(space.contains(a.astype(space.dtype)))
    return bool(space.contains(action))


class SemRelocLoopVectorEnv(VectorEnv):
    """``num_envs`` SemReloc envs stepped in a loop in this process (see the module docstring).

    Args:
        num_envs: number of robots R (>= 1).
        env_id: the single-robot env each robot runs (default ``"SemReloc-v22"``, the newest; any
            ``SemReloc-*`` id), made with ``gym.make`` so it carries the same wrappers (``CheckedReset``,
            ``TimeLimit``). (Before this default was the newest it was ``"SemReloc-v1"``.)
        max_episode_steps: time limit per robot (default: the single env's registration).
        wrapper: optional callable applied to each robot's env (e.g.
            `semreloc_env.wrappers.BeliefObservation`); the spaces are the wrapped env's.
        first_robot: the number error messages give robot 0 (default 0; `agents.worker_vec_env` runs blocks of a
            larger set of robots, each named by its number in the set).
        **kwargs: ``gym.make`` keyword arguments of the single env (layout, relocalizer, ...).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int = 1,
        env_id: str = SINGLE_ENV_ID,
        max_episode_steps: int | None = None,
        wrapper=None,
        first_robot: int = 0,
        **kwargs,
    ):
        if not (is_int(first_robot) and first_robot >= 0):
            raise ValueError(f"first_robot must be an int >= 0, got {first_robot!r:.60}")
        self.first_robot = int(first_robot)
        if not (is_int(num_envs) and num_envs >= 1):
            raise ValueError(f"num_envs must be an int >= 1, got {num_envs!r}")
        if kwargs.get("render_mode") is not None:
            raise ValueError("SemRelocLoopVectorEnv does not render; make single envs to render")
        if wrapper is not None and not callable(wrapper):
            raise TypeError(
                f"wrapper must be a callable env -> env (e.g. semreloc_env.observations.ActiveObservation), "
                f"got {type(wrapper).__name__} {wrapper!r:.60}"
            )
        if max_episode_steps is not None and not is_int(max_episode_steps):  # 2.5 or "5" is no step count
            raise TypeError(f"max_episode_steps must be an int >= 1 or None, got {max_episode_steps!r:.60}")
        if max_episode_steps is not None and max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be an int >= 1 or None, got {max_episode_steps!r}")
        extra = {} if max_episode_steps is None else {"max_episode_steps": int(max_episode_steps)}
        self.envs = [gym.make(env_id, **kwargs, **extra) for _ in range(int(num_envs))]
        if wrapper is not None:
            self.envs = [wrapper(env) for env in self.envs]
            if not isinstance(self.envs[0], gym.Env):
                raise TypeError(
                    f"wrapper must return the wrapped env (a gymnasium.Env), returned {type(self.envs[0]).__name__}"
                )
        self.num_envs = int(num_envs)
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._spec = None
        self._obs = create_empty_array(self.single_observation_space, n=self.num_envs, fn=np.zeros)
        self._done = np.zeros(self.num_envs, dtype=np.bool_)
        self._out_of_step: str | None = None  # why `step` must wait for a reset (a robot raised mid-loop)
        self._robot_obs: list | None = None  # each robot's last observation (None: not all reset yet)

    @property
    def spec(self):
        """The spec ``gym.make_vec`` gave (None if built directly), its ``max_episode_steps`` the limit each
        robot runs with: make_vec copies the registration's into the spec, not the one passed to it."""
        return self._spec

    @spec.setter
    def spec(self, value) -> None:
        limit = self.envs[0].spec.max_episode_steps if self.envs[0].spec is not None else None
        if value is not None and limit is not None and value.max_episode_steps != limit:
            value = dataclasses.replace(value, max_episode_steps=limit)
        self._spec = value

    # ------------------------------------------------------------------ checks
    def check_actions(self, actions, skip_done: bool = False) -> list:
        """The per-robot actions of ``actions``; ValueError naming the robot if any is invalid.

        Checks all of them before any robot moves, so a rejected call changes nothing. With
        ``skip_done`` the robots that `step` will reset instead (their action is ignored) are not
        checked."""
        acts = action_list(
            actions,
            self.num_envs,
            self.single_action_space,
            self.first_robot,
            lambda: all(env.action_space is env.unwrapped.action_space for env in self.envs),
        )
        for i, (env, a) in enumerate(zip(self.envs, acts)):
            if skip_done and self._done[i]:
                continue
            base = env.unwrapped
            try:
                if env.action_space is base.action_space:
                    decode_action(a, base.action_type, base.action_space, base.robot_params)
                elif not in_wrapped_space(a, env.action_space):
                    raise ValueError(f"invalid action {a!r:.80} for {env.action_space}")
            except ValueError as e:
                hint = float_array_hint(actions, env.action_space, self.first_robot)
                raise ValueError(f"robot {self.first_robot + i}: {e}{hint}") from None
        return acts

    def _per_robot(self, options) -> list:
        """One options dict (or None) per robot, from one for all or a list of one per robot."""
        if isinstance(options, (list, tuple)):
            if len(options) != self.num_envs:
                raise ValueError(
                    f"got {len(options)} options dicts for {self.num_envs} robots (one dict, or one per robot)"
                )
            return list(options)
        return [options] * self.num_envs

    def check_seeds(self, seed, options=None) -> list[int | None]:
        """Per-robot seeds of ``seed`` (see `reset`), every robot's seed and options checked first.

        ``options`` is one dict for all robots or a list of one per robot."""
        if seed is None or is_int(seed):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        elif isinstance(seed, (str, bytes, dict, set, frozenset, float, bool, np.floating, np.bool_)):
            # a set has no order: which robot would get which seed?
            raise ValueError(f"seed must be None, an int or a list of {self.num_envs} seeds, got {seed!r:.80}")
        else:
            try:
                seeds = list(seed)
            except TypeError:
                raise ValueError(
                    f"seed must be None, an int or a list of {self.num_envs} seeds, got {seed!r:.80}"
                ) from None
            if len(seeds) != self.num_envs:
                raise ValueError(f"got {len(seeds)} seeds for {self.num_envs} robots")
            # NumPy integers (an array of seeds) as Python ints; anything else the robot's own check refuses
            seeds = [int(s) if is_int(s) else s for s in seeds]
        per_robot = self._per_robot(options)
        for i, (env, s, o) in enumerate(zip(self.envs, seeds, per_robot)):
            try:
                check_reset(env, seed=s, options=o)
            except ValueError as e:
                raise ValueError(f"robot {self.first_robot + i}: {e}") from None
        return seeds

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | list[dict | None] | None = None):
        """Reset every robot: ``seed`` int gives robot ``i`` the seed ``seed + i``; a list gives each its own.
        ``options``: one dict for every robot, or a list of one dict (or None) per robot.

        As Gymnasium's sync vector env, a dict ``options`` may carry ``"reset_mask"``: a bool array of shape ``(R,)``
        with at least one True; then only the robots it marks are reset (each with its seed from ``seed`` and the
        other options), the others keep their episodes and observations, and ``infos`` holds the reset robots'
        entries only (their ``_key`` masks). Such a reset needs every robot reset once before, and brings the
        robots back in step (after a robot raised) only if it resets them all.

        Seeds and options are checked for every robot before any is reset (ValueError)."""
        mask, options = self._reset_mask(options)
        seeds = self.check_seeds(seed, options)
        per_robot = self._per_robot(options)
        if mask is not None:
            if self._robot_obs is None:
                raise RuntimeError(
                    "reset_mask resets some robots only: reset every robot once first with this env's reset() (not "
                    "through an SB3 adapter, which keeps the observations itself)"
                )
            if self._out_of_step is not None:
                raise RuntimeError(f"{self._out_of_step} (a reset_mask that leaves robots out does not)")
        super().reset(seed=seeds[0])
        obs_list = [None] * self.num_envs if mask is None else list(self._robot_obs)
        info_list: list[dict | None] = [None] * self.num_envs
        for i, (env, s, o) in enumerate(zip(self.envs, seeds, per_robot)):
            if mask is not None and not mask[i]:
                continue
            with self.naming_who_raised(i, "reset"):
                obs_list[i], info_list[i] = env.reset(seed=s, options=o)
        if mask is None:
            self.all_reset()
        else:
            self._done[mask] = False
        self._robot_obs = obs_list
        return deepcopy(concatenate(self.single_observation_space, obs_list, self._obs)), batch_infos(info_list)

    def _reset_mask(self, options) -> tuple[np.ndarray | None, Any]:
        """``(reset_mask, options without it)`` of `reset`'s ``options`` (the caller's dict left as it is), the mask
        None where there is none or it marks every robot (a full reset); ValueError for a mask that is not a bool
        array of shape ``(R,)`` with a True."""
        if not (isinstance(options, dict) and "reset_mask" in options):
            return None, options
        mask = options["reset_mask"]
        if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (self.num_envs,)):
            raise ValueError(
                f"options['reset_mask'] must be a numpy bool array of shape ({self.num_envs},), got {mask!r:.80}"
            )
        if not mask.any():
            raise ValueError("options['reset_mask'] must mark at least one robot to reset (it is all False)")
        return None if mask.all() else mask.copy(), {k: v for k, v in options.items() if k != "reset_mask"}

    def step(self, actions):
        """Step every robot with its action (a robot that ended last step is reset instead).

        Every action is checked before any robot moves (ValueError naming the robot). A robot that raises
        while stepping (say, a look-alike kidnapping with no place to go) leaves the robots before it stepped
        and those after it not: the error passes on, and `step` refuses to run (RuntimeError) until `reset`."""
        self.check_in_step()
        acts = self.check_actions(actions, skip_done=True)
        rewards = np.zeros(self.num_envs, dtype=np.float64)
        terms = np.zeros(self.num_envs, dtype=np.bool_)
        truncs = np.zeros(self.num_envs, dtype=np.bool_)
        obs_list, info_list = [], []
        for i, env in enumerate(self.envs):
            with self.naming_who_raised(i, "step"):
                if self._done[i]:
                    obs, info = env.reset()
                else:
                    obs, rewards[i], terms[i], truncs[i], info = env.step(acts[i])
            obs_list.append(obs)
            info_list.append(info)
        self._done = terms | truncs
        self._robot_obs = obs_list
        obs = deepcopy(concatenate(self.single_observation_space, obs_list, self._obs))
        return obs, rewards, terms, truncs, batch_infos(info_list)

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """As Gymnasium's sync vector env: each robot's env's ``name`` (found through its wrappers) called with
        ``args`` and ``kwargs``, or its value if not callable, robot by robot."""
        out = []
        for env in self.envs:
            got = env.get_wrapper_attr(name)
            if callable(got):
                self._robot_obs = None  # the call may move the robots (``call("reset")``): see `all_reset`
                out.append(got(*args, **kwargs))
            else:
                out.append(got)
        return tuple(out)

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """Each robot's env's attribute ``name`` (through its wrappers; a method is called, as `call`)."""
        return self.call(name)

    def set_attr(self, name: str, values: Any) -> None:
        """Set each robot's env's attribute ``name`` (``set_wrapper_attr``): to ``values[i]`` for robot ``i`` if
        ``values`` is a list or tuple (ValueError unless one per robot), else to ``values`` for every robot."""
        if not isinstance(values, (list, tuple)):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr: got {len(values)} values for {self.num_envs} robots (one, or one per robot)")
        for env, value in zip(self.envs, values):
            env.set_wrapper_attr(name, value)

    def close_extras(self, **kwargs) -> None:
        for env in self.envs:
            env.close()

    # ------------------------------------------------------------------ helpers
    @property
    def out_of_step(self) -> str | None:
        """Why `step` refuses to run until a reset (a robot raised in the last ``step()`` or ``reset()``), or None."""
        return self._out_of_step

    def check_in_step(self) -> None:
        """RuntimeError if a robot raised in the last ``step()`` or ``reset()``: the robots are out of step until
        a reset of all of them (`reset`, or the SB3 adapter's)."""
        if self._out_of_step is not None:
            raise RuntimeError(self._out_of_step)

    def all_reset(self) -> None:
        """Every robot has just been reset: `step` may run again. The robots' last observations are forgotten until
        `reset` or `step` returns them (the SB3 adapter resets and steps the robots itself), so that a reset with a
        ``reset_mask`` never returns another driver's stale ones."""
        self._done[:] = False
        self._out_of_step = None
        self._robot_obs = None

    @contextlib.contextmanager
    def naming_who_raised(self, i: int, call: str, detail: str = ""):
        """Let an exception of robot ``i``'s ``call`` (``"step"`` or ``"reset"``) pass, and remember that the robots
        are out of step (`check_in_step` then refuses); ``detail`` says more of what the robot was doing. For loops
        over the robots outside this class too (the SB3 adapter's). A Ctrl-C in the loop counts too."""
        try:
            yield
        except BaseException as e:
            f, last = self.first_robot, self.first_robot + self.num_envs - 1
            ran = ("no other robot had run it", f"robot {f} had run it", f"robots {f} to {f + i - 1} had run it")
            ran = ran[min(i, 2)]
            left = ("it was the last", f"robot {f + i + 1} had not", f"robots {f + i + 1} to {last} had not")
            left = left[min(self.num_envs - 1 - i, 2)]
            self._out_of_step = (
                f"robot {f + i} raised {type(e).__name__} in the last {call}(){detail} ({shortened_message(e)}); {ran} and "
                f"{left}: the robots are out of step, call reset()"
            )
            if hasattr(e, "add_note") and not isinstance(e, KeyboardInterrupt):  # Python 3.11+: the error itself says
                e.add_note(
                    f"(robot {f + i} raised this in {call}(){detail}; of robots {f} to {last}, {ran} and {left})"
                )
            raise

    def _add_info(self, vector_infos: dict[str, Any], env_info: dict[str, Any], env_num: int) -> dict[str, Any]:
        """Gymnasium's info batching (arrays per key plus ``_key`` masks), but lossless: an array whose
        dtype cannot hold a later robot's value exactly (None in a float array, a float in an int
        array, another shape) becomes an object array, so `robot_info` returns every value as given (a NumPy
        scalar or 0-d array as the Python number of the same value).

        One robot at a time, as Gymnasium's own: the specification of `batch_infos`, which batches all the robots'
        infos at once with the same result and which `reset` and `step` use."""
        n = self.num_envs
        for key, value in env_info.items():
            if isinstance(value, dict):
                vector_infos[key] = self._add_info(vector_infos.get(key, {}), value, env_num)
            else:
                arr = vector_infos.get(key)
                if arr is None:
                    arr = _new_info_array(value, n)
                elif arr.dtype != object and not _fits(arr, value):
                    arr = _as_object(arr)
                arr[env_num] = value
                vector_infos[key] = arr
            mask = vector_infos.get(f"_{key}")
            if mask is None:
                mask = np.zeros(n, dtype=np.bool_)
            mask[env_num] = True
            vector_infos[f"_{key}"] = mask
        return vector_infos

    @staticmethod
    def robot_info(infos: dict[str, Any], i: int) -> dict[str, Any]:
        """Robot ``i``'s ``info`` dict back from the batched ``infos`` (keys its ``_key`` masks mark present): the
        values its own env gave, except that NumPy scalars and 0-d arrays come back as Python numbers (``.item()``:
        the same value; the batched arrays do not keep whether a number was a NumPy scalar)."""
        out = {}
        for key, value in infos.items():
            if key.startswith("_"):
                continue
            if isinstance(value, dict):
                if infos.get(f"_{key}", np.ones(i + 1, bool))[i]:
                    out[key] = SemRelocLoopVectorEnv.robot_info(value, i)
            elif infos[f"_{key}"][i]:
                v = value[i]
                out[key] = v.item() if isinstance(v, np.generic) else v
        return out


def shortened_message(e: BaseException, limit: int = 300) -> str:
    """``str(e)``, cut at a word boundary after at most ``limit`` characters (with "...")."""
    text = str(e)
    if len(text) <= limit:
        return text
    return text[:limit].rsplit(" ", 1)[0] + " ..."


def batch_infos(infos: list[dict[str, Any] | None]) -> dict[str, Any]:
    """The robots' ``infos`` (robot ``i``'s dict at ``i``, None for a robot without one) batched as `SemRelocLoopVectorEnv._add_info` batches them
    one robot after the other, the same keys in the same order, arrays and masks: key by key, each array built once
    from all the robots' values. TypeError if a key holds a dict for one robot and something else for another."""
    return _batched(list(infos), len(infos))


def _batched(dicts: list[dict[str, Any] | None], n: int) -> dict[str, Any]:
    present = [d for d in dicts if d is not None]
    uniform = len(present) == n and all(d.keys() == present[0].keys() for d in present)
    if uniform:  # every robot has every key (the usual case): the first robot's order is the order
        order = list(present[0])
    else:
        union: dict[str, None] = {}
        for d in present:
            union.update(dict.fromkeys(d))
        order = list(union)
    everyone = list(range(n))
    out: dict[str, Any] = {}
    for key in order:
        where = everyone if uniform else [i for i, d in enumerate(dicts) if d is not None and key in d]
        values = [dicts[i][key] for i in where]
        kinds = set(map(type, values))
        nested = [k for k in kinds if issubclass(k, dict)]
        if nested and len(nested) == len(kinds):
            out[key] = _batched([d.get(key) if d is not None else None for d in dicts], n)
        elif nested:
            raise TypeError(f"info key {key!r} holds a dict for some robots and not for others: it cannot be batched")
        else:
            out[key] = _info_array(values, where, n, kinds)
        mask = np.zeros(n, dtype=np.bool_)
        mask[where] = True
        out[f"_{key}"] = mask
    return out


def _info_array(values: list, rows: list[int], n: int, kinds: set[type]) -> np.ndarray:
    """The array `SemRelocLoopVectorEnv._add_info` ends with after storing ``values`` at ``rows``: one call of the
    typed shortcuts where every value has the same type (``kinds``, the set of them) and, for arrays, the same shape
    and dtype."""
    first = values[0]
    if len(kinds) == 1:
        kind = type(first)
        if kind in (int, float, bool) or issubclass(kind, np.number):
            arr = np.zeros(n, dtype=kind)
            arr[rows] = np.array(values, dtype=arr.dtype)
            return arr
        if kind is np.ndarray and all(v.shape == first.shape and v.dtype == first.dtype for v in values):
            arr = np.zeros((n, *first.shape), dtype=first.dtype)
            arr[rows] = np.stack(values)
            return arr
    arr = _new_info_array(first, n)
    for i, value in zip(rows, values):
        if arr.dtype != object and not _fits(arr, value):
            arr = _as_object(arr)
        arr[i] = value
    return arr


def _new_info_array(value, n: int) -> np.ndarray:
    if type(value) in (int, float, bool) or isinstance(value, np.number):
        return np.zeros(n, dtype=type(value))
    if isinstance(value, np.ndarray):
        return np.zeros((n, *value.shape), dtype=value.dtype)
    return np.full(n, None, dtype=object)


def _fits(arr: np.ndarray, value) -> bool:
    """``value`` can be stored in a row of ``arr`` without changing it."""
    if isinstance(value, np.ndarray):
        return value.shape == arr.shape[1:] and value.dtype == arr.dtype
    if arr.ndim != 1:
        return False
    return (type(value) in (int, float, bool) or isinstance(value, np.number)) and np.dtype(type(value)) == arr.dtype


def _as_object(arr: np.ndarray) -> np.ndarray:
    out = np.full(arr.shape[0], None, dtype=object)
    for i in range(arr.shape[0]):
        out[i] = arr[i].item() if arr.ndim == 1 else arr[i].copy()
    return out
