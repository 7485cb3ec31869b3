"""PPO for active relocalization: a new procedural layout every episode, spatial belief observations.

`make_active_env` builds one training env:
``SemReloc-v22`` (``relocalizer={"n_particles": particles}``, ``max_episode_steps``) ->
`RandomLayout` (a new layout per reset, never a held-out
seed) -> `BeliefMassReward` (``mode="gain"``) -> `MotionOptions` (if ``options``) ->
`ActionRepeat` -> `ActiveObservation`
-> SB3's ``Monitor``. `train_active` trains SB3 PPO with `ActiveExtractor`
on ``n_envs`` of them, logs csv + TensorBoard, shows SB3's progress bar, writes checkpoints,
resumes from one, and saves the final policy with `agents.learned.save_policy` (load it back
with `agents.learned.load_policy`). Everything a run writes goes under ``out``.
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import json
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import gymnasium as gym
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import configure
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

from filters.experiments.cli import JsonDict
from filters.numbers import is_int, is_real
from semreloc_env import semreloc_ids_since  # (importing semreloc_env registers the env ids)
from semreloc_env.layout_sampling import LayoutSampler, RandomLayout
from semreloc_env.observations import ActiveObservation
from semreloc_env.observations.active import check_arguments as check_active_arguments
from semreloc_env.rewards import BeliefMassReward
from semreloc_env.wrappers import ActionRepeat, ResetOptions

from .active_features import MIN_IMAGE_CELLS, ActiveExtractor
from .callbacks import RelocalizationMetricsCallback
from .features import SemRelocPolicy
from .learned import load_model, option_names, read_metadata, run_folder_of, save_policy, saved_run_config
from .options import MotionOptions, TeacherLabels, check_options
from .train import check_ppo_settings, log_formats, ppo_hyperparameters, progress_bar_wanted
from .vec_env import close_after_interrupt, closing_venv

ENV_ID = "SemReloc-v22"
TRAINABLE_ENV_IDS = semreloc_ids_since(2)
"""The envs `ActiveTrainConfig.env_id` may name: ``SemReloc-v2`` and newer (the typed observation
`ActiveObservation` reads), newest first."""
TrainableEnvId = Literal[TRAINABLE_ENV_IDS]
TRAIN_KINDS = ("procedural", "procedural_sym", "procedural_lookalike")
"""Layout kinds drawn for training: procedural only, so ``lab``, ``twin_rooms`` and the changed
lab of the evaluation are layouts the policy has never seen (as are the held-out seeds)."""

DEFAULT_KIND_WEIGHTS = (1.0, 1.0, 2.0)
"""How often each of ``TRAIN_KINDS`` is drawn, relative to the others: look-alike layouts twice as often."""


def observation_defaults() -> dict[str, Any]:
    """`ActiveObservation`'s keyword arguments with their defaults (what ``observation`` may set)."""
    params = inspect.signature(ActiveObservation.__init__).parameters
    return {k: p.default for k, p in params.items() if k not in ("self", "env")}


@dataclass(frozen=True)
class ActiveTrainConfig:
    """One PPO training run for active relocalization (each field documented below)."""

    kinds: tuple[str, ...] = TRAIN_KINDS
    """layout kinds drawn for training (`semreloc_env.layout_sampling.LayoutSampler`)"""
    files: tuple[str, ...] = ()
    """layout files (.json / .yaml) drawn as well, each one more entry after the kinds"""
    kind_weights: tuple[float, ...] | None | Literal["auto"] = "auto"
    """one weight per entry, kinds then files, or one per kind only (files then weigh 1 each);
    None: equal; "auto": ``DEFAULT_KIND_WEIGHTS`` (1, 1, 2) if ``kinds`` are the default kinds (files
    then weigh 1 each), equal weights for any other kinds (`weights`; a saved config.json holds what
    "auto" gave)"""
    layout_seeds: tuple[int, int] = (0, 100)
    """(start, stop) of the procedural seeds drawn (held-out seeds never are); a small range lets the
    mapping-run cache serve repeats"""
    env_id: TrainableEnvId = ENV_ID
    """the registered env the robot trains in (``SemReloc-v2`` or newer: the typed observation); default the
    newest. A run resumed in another env is told so"""
    particles: int = 1000
    """the relocalizer's particle count while training (the observation does not depend on it)"""
    max_episode_steps: int = 200
    """env steps per episode (the evaluation's success limit is 200)"""
    reset_options: JsonDict = field(default_factory=dict)
    """options of every episode's reset (`semreloc_env.wrappers.ResetOptions`), e.g. '{"tracking": true,
    "kidnap_at_step": 30, "kidnap_pose": "lookalike"}' for look-alike kidnappings (success then counts from the
    kidnapping on; give max_episode_steps room after it); default: global starts"""
    repeat: int = 4
    """env steps per decision (`semreloc_env.wrappers.ActionRepeat`)"""
    options: tuple[str, ...] = ("explore",)
    """motions added to the env's four actions as actions 4, 5, ... (`agents.options.MotionOptions`):
    explore (one step of the reactive explorer), viewpoint (one step of the viewpoint planner);
    empty: the four primitive actions only"""
    belief_mass_weight: float = 0.5
    """weight of the belief_mass reward term (gain mode: change of the belief mass within 0.5 m of the
    truth, a shaping term, potential-based only approximately under PPO's discount: docs/active.md,
    "Rewards"); 0 turns it off"""
    reward_weights: JsonDict = field(default_factory=lambda: {"collision": -0.1})
    """overrides of the env's `RewardWeights` (default: collisions cost -0.1 a step instead of -0.5, so
    that driving is not learned away before localizing is); on the command line the whole dict as one
    JSON object, e.g. '{"collision": -0.1, "success": 5}'"""
    observation: JsonDict = field(default_factory=dict)
    """`ActiveObservation` keyword arguments; on the command line one JSON object, e.g. '{"ego_size": 48}'"""
    n_envs: int = 4
    """parallel envs"""
    vec_env: str = "subproc"
    """subproc (one process per env), dummy (all in this process) or workers (the envs split over `workers`
    processes, several each: `agents.worker_vec_env.WorkersVecEnv`, the same episodes as dummy)"""
    workers: int = 2
    """processes of vec_env workers (at most n_envs; the other vec envs ignore it)"""
    total_timesteps: int = 60_000
    """decisions to train for, summed over envs (env steps: up to `repeat` times more)"""
    seed: int = 0
    """seeds PPO and the envs (env k: seed + k)"""
    n_steps: int = 128
    """PPO: decisions per env per rollout"""
    batch_size: int = 256
    """PPO: minibatch size"""
    n_epochs: int = 4
    """PPO: passes over each rollout"""
    learning_rate: float = 3e-4
    """PPO: Adam step size"""
    gamma: float = 0.98
    """PPO: discount per decision"""
    gae_lambda: float = 0.95
    """PPO: GAE lambda"""
    ent_coef: float = 0.02
    """PPO: entropy bonus"""
    clip_range: float = 0.2
    """PPO: ratio clip"""
    vf_coef: float = 0.5
    """PPO: value-loss weight"""
    features_dim: int = 256
    """output size of `ActiveExtractor`"""
    net_arch: tuple[int, ...] = (128,)
    """hidden sizes of the policy and value heads"""
    cnn_channels: tuple[int, int, int] = (16, 32, 32)
    """channels of the image CNNs' three convolutions"""
    torch_threads: int = 1
    """torch.set_num_threads of the learner"""
    device: str = "cpu"
    """torch device"""
    checkpoint_every: int | None = 10_000
    """decisions (summed over envs) between checkpoints (None: none)"""
    time_budget_s: float | None = None
    """stop learning after this many wall seconds (None: run total_timesteps); the policy is saved either way"""
    progress_bar: bool = True
    """SB3's progress bar"""
    verbose: int = 0
    """SB3 verbosity"""

    def __post_init__(self) -> None:
        if self.vec_env not in ("subproc", "dummy", "workers"):
            raise ValueError(f"vec_env must be 'subproc', 'dummy' or 'workers', got {self.vec_env!r}")
        if self.env_id not in TRAINABLE_ENV_IDS:
            raise ValueError(f"env_id must be one of {TRAINABLE_ENV_IDS}, got {self.env_id!r}")
        ints = ("particles", "max_episode_steps", "repeat", "n_envs", "total_timesteps", "n_steps", "batch_size")
        for name in ints + ("n_epochs", "torch_threads", "workers"):
            v = getattr(self, name)
            if not is_int(v) or v < 1:
                raise ValueError(f"{name} must be an int >= 1, got {v!r}")
            object.__setattr__(self, name, int(v))
        if self.vec_env == "workers" and self.workers > self.n_envs:
            raise ValueError(f"workers must be at most n_envs ({self.n_envs}), got {self.workers}")
        lo, hi = self.layout_seeds
        if not (0 <= lo < hi):
            raise ValueError(f"layout_seeds must be (start, stop) with 0 <= start < stop, got {self.layout_seeds!r}")
        if isinstance(self.kind_weights, str) and self.kind_weights != "auto":
            raise ValueError(f'kind_weights must be weights, None or "auto", got {self.kind_weights!r}')
        entries = len(self.kinds) + len(self.files)
        weights = self.weights
        if weights is not None and len(weights) not in (entries, len(self.kinds)):
            raise ValueError(
                f"kind_weights needs one weight per kind and file ({entries}) or per kind ({len(self.kinds)}), "
                f"got {weights!r}; give as many (--config.kind-weights 1 1 ...; imitate_active: "
                "--config.train.kind-weights) or None for equal weights (--config.kind-weights None)"
            )
        if self.time_budget_s is not None and not self.time_budget_s > 0:
            raise ValueError(f"time_budget_s must be None or > 0, got {self.time_budget_s!r}")
        if self.checkpoint_every is not None and self.checkpoint_every < 1:
            raise ValueError("checkpoint_every must be None or >= 1")
        w = self.belief_mass_weight
        if not (is_real(w) and math.isfinite(w)):  # else every worker fails at its env's construction
            raise ValueError(f"belief_mass_weight must be a finite number, got {w!r:.60}")
        check_options(self.options)
        check_ppo_settings(self)
        self._check_reset_options()
        self.layout_sampler()  # the layout stream's arguments, checked here rather than in the env workers
        allowed = set(observation_defaults())
        unknown = sorted(set(self.observation) - allowed)
        if unknown:
            raise ValueError(f"observation: unknown ActiveObservation arguments {unknown}; known {sorted(allowed)}")
        try:  # bad values fail here, not in every worker process
            keys = check_active_arguments(**self.observation)
        except (ValueError, TypeError) as e:
            raise ValueError(f"observation: {e}") from None
        obs = {**observation_defaults(), **self.observation}
        for key, size in (("ego", obs["ego_size"]), ("global", obs["global_size"])):
            if key in keys and size < MIN_IMAGE_CELLS:  # ActiveExtractor's convolutions would refuse it
                raise ValueError(f"observation: {key}_size must be at least {MIN_IMAGE_CELLS} cells, got {size!r}")
        from semreloc_env.config import coerce_config
        from semreloc_env.envs.semreloc import RewardWeights

        try:  # unknown terms or bad values fail here, not in the workers
            coerce_config(RewardWeights, dict(self.reward_weights), "reward_weights")
        except TypeError as e:
            raise ValueError(str(e)) from None

    def _check_reset_options(self) -> None:
        """What every episode of a run can take (checked here: a bad value would fail only at the first reset, in the
        workers, after the run folder was made): ``tracking`` (bool; then a kidnap, or no episode could succeed),
        ``kidnap_at_step`` within the episode, ``kidnap_pose`` "lookalike" only (the layout changes every episode,
        so a fixed pose fits none of them; nor does ``pose``)."""
        from semreloc_env.envs.semreloc import KIDNAP_TO_LOOKALIKE

        opts = self.reset_options
        keys = ("tracking", "kidnap_at_step", "kidnap_pose")
        unknown = sorted(set(opts) - set(keys))
        if unknown:
            raise ValueError(
                f"reset_options: {unknown} cannot be given to every episode (known: {list(keys)}; a pose fits one "
                "layout, and the layout changes every episode)"
            )
        tracking, k, kp = (opts.get(key) for key in keys)
        if tracking is not None and not isinstance(tracking, bool):
            raise ValueError(f"reset_options: tracking must be true or false, got {tracking!r}")
        if k is not None and not (is_int(k) and 1 <= k <= self.max_episode_steps):
            raise ValueError(f"reset_options: kidnap_at_step must be an int in [1, max_episode_steps], got {k!r}")
        if kp is not None and (kp != KIDNAP_TO_LOOKALIKE or k is None):
            raise ValueError(
                f"reset_options: kidnap_pose can only be {KIDNAP_TO_LOOKALIKE!r}, with a kidnap_at_step, got {kp!r}"
            )
        if tracking and k is None:
            raise ValueError("reset_options: a tracking start needs a kidnap_at_step (else no episode can succeed)")

    @property
    def weights(self) -> tuple[float, ...] | None:
        """``kind_weights`` with "auto" resolved (None: equal)."""
        if self.kind_weights == "auto":
            return DEFAULT_KIND_WEIGHTS if tuple(self.kinds) == TRAIN_KINDS else None
        return self.kind_weights

    def as_dict(self) -> dict[str, Any]:
        """The fields, ``kind_weights`` resolved (what config.json records)."""
        return {**dataclasses.asdict(self), "kind_weights": self.weights}

    def layout_sampler(self) -> LayoutSampler:
        """The training layouts' sampler: ``kinds`` then ``files``, ``layout_seeds``, ``kind_weights``."""
        return LayoutSampler(
            kinds=self.kinds,
            files=self.files,
            seeds=range(*self.layout_seeds),
            weights=None if self.weights is None else self._entry_weights(),
        )

    def _entry_weights(self) -> list[float]:
        weights = list(self.weights)
        return weights + [1.0] * (len(self.kinds) + len(self.files) - len(weights))


class WallClockBudget(BaseCallback):
    """Stop learning once ``budget_s`` wall seconds have passed since training started."""

    def __init__(self, budget_s: float):
        super().__init__()
        self.budget_s = float(budget_s)
        self._t0 = 0.0

    def _on_training_start(self) -> None:
        self._t0 = time.time()

    def _on_step(self) -> bool:
        return time.time() - self._t0 < self.budget_s


def make_active_env(config: ActiveTrainConfig, seed: int = 0, teacher: dict[str, Any] | None = None) -> gym.Env:
    """One training env of ``config`` (see the module docstring); its layout stream starts at ``seed``.

    ``teacher``: if not None, `agents.options.TeacherLabels` (the viewpoint planner with these
    arguments) goes in before `ActionRepeat`, and every info carries ``teacher_action``."""
    env = gym.make(
        config.env_id,
        relocalizer={"n_particles": config.particles},
        reward_weights=dict(config.reward_weights),
        max_episode_steps=config.max_episode_steps,
    )
    sampler = config.layout_sampler()
    env = RandomLayout(env, sampler, seed=seed)
    if config.reset_options:
        env = ResetOptions(env, dict(config.reset_options))
    if config.belief_mass_weight:
        env = BeliefMassReward(env, weight=config.belief_mass_weight, mode="gain")
    if config.options:
        env = MotionOptions(env, config.options)
    if teacher is not None:
        env = TeacherLabels(env, teacher)
    env = ActionRepeat(env, config.repeat)
    env = ActiveObservation(env, **config.observation)
    return Monitor(env, info_keywords=("is_success",))


def make_active_venv(config: ActiveTrainConfig, teacher: dict[str, Any] | None = None):
    """``n_envs`` training envs, env ``k`` seeded ``seed + k`` (``teacher``: as `make_active_env`)."""
    if config.vec_env == "workers":
        from .worker_vec_env import WorkersVecEnv

        venv = WorkersVecEnv(functools.partial(_active_block, config, teacher), config.n_envs, config.workers)
        venv.seed(config.seed)
        return venv
    vec_env_cls = SubprocVecEnv if config.vec_env == "subproc" else DummyVecEnv
    return _active_block(config, teacher, config.n_envs, 0, vec_env_cls)


def _active_block(
    config: ActiveTrainConfig, teacher: dict[str, Any] | None, n: int, first: int, vec_env_cls=DummyVecEnv
):
    """Envs ``first .. first + n - 1`` of `make_active_venv` in a ``vec_env_cls`` (a worker's block: a
    ``DummyVecEnv``), made by ``make_vec_env`` (its Monitor, each action space seeded ``seed + k``)."""
    return make_vec_env(
        functools.partial(make_active_env, config, config.seed, teacher=teacher),
        n_envs=n,
        seed=config.seed,
        start_index=first,
        vec_env_cls=vec_env_cls,
    )


def build_model(config: ActiveTrainConfig, venv) -> PPO:
    """A fresh PPO model for ``config`` on ``venv``."""
    return PPO(
        SemRelocPolicy,
        venv,
        **ppo_hyperparameters(config),
        vf_coef=config.vf_coef,
        policy_kwargs={
            "features_extractor_class": ActiveExtractor,
            "features_extractor_kwargs": {
                "features_dim": config.features_dim,
                "cnn_channels": tuple(config.cnn_channels),
            },
            "net_arch": list(config.net_arch),
        },
        seed=config.seed,
        device=config.device,
        verbose=config.verbose,
    )


def plot_learning_curve(progress_csv: str | Path, path: str | Path, repeat: int = 1) -> Path:
    """Plot a run's ``rollout/success_rate`` and ``rollout/ep_rew_mean`` (over the last 100 episodes)
    against env steps (decisions x ``repeat``) from its ``progress.csv``; write a PNG to ``path``.

    Raises:
        ValueError: the csv has no rows with those columns.
    """
    import csv

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with open(progress_csv, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r.get("rollout/success_rate") and r.get("time/total_timesteps")]
    if not rows:
        raise ValueError(f"{progress_csv}: no rows with rollout/success_rate")
    steps = [int(r["time/total_timesteps"]) * repeat for r in rows]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(steps, [float(r["rollout/success_rate"]) for r in rows], color="tab:blue", label="success rate")
    ax.set_xlabel("env steps (decisions x repeat)")
    ax.set_ylabel("training success rate (last 100 episodes)", color="tab:blue")
    ax.set_ylim(0, 1)
    ax2 = ax.twinx()
    ax2.plot(steps, [float(r["rollout/ep_rew_mean"]) for r in rows], color="tab:orange", label="episode return")
    ax2.set_ylabel("episode return", color="tab:orange")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


SPACE_FIELDS = ("options", "repeat", "observation")
"""Fields of `ActiveTrainConfig` that shape the policy's spaces: a resumed run must keep them."""
DISTRIBUTION_FIELDS = ("env_id", "kinds", "files", "kind_weights", "layout_seeds", "particles", "max_episode_steps",
                       "reset_options", "belief_mass_weight", "reward_weights")  # fmt: skip
"""Fields that shape what a run trains on: a resumed run that changes them is told so."""


MODEL_FIELDS = ("n_steps", "batch_size", "n_epochs", "learning_rate", "gamma", "gae_lambda", "ent_coef",
                "clip_range", "vf_coef", "features_dim", "net_arch", "cnn_channels")  # fmt: skip
"""Fields a checkpoint carries (PPO's settings and the network): a resumed run keeps the checkpoint's."""


class RunFolderError(ValueError):
    """``--out`` or ``--resume`` does not fit: a run in the way, a missing checkpoint, other spaces."""


def check_fresh_out(out: Path, resumable: bool = True) -> None:
    """RunFolderError if ``out`` holds a training run already (a new run would overwrite its policy and
    config and leave its checkpoints and TensorBoard events beside the new ones). ``resumable``: the
    message says how to continue that run with ``--resume`` (train_active's runs; an imitation run has none)."""
    held = [n for n in ("config.json", "policy.zip", "checkpoints") if (out / n).exists()]
    if held:
        hint = f", or continue that run with --resume {out}/checkpoints/<checkpoint>.zip" if resumable else ""
        raise RunFolderError(f"{out} holds a training run already ({', '.join(held)}): choose a new --out{hint}")


def run_config_of(checkpoint: Path) -> dict[str, Any] | None:
    """The `ActiveTrainConfig` fields a checkpoint or saved policy was trained with: its run's
    ``config.json`` (`agents.learned.saved_run_config`), else the training config in a saved
    policy's metadata (`agents.learned.save_policy`), else what that metadata holds of the spaces
    (``observation``, ``repeat``, ``options``); None if nothing is known."""
    saved = saved_run_config(checkpoint)
    if saved is not None:
        return saved
    try:
        meta = read_metadata(checkpoint)
    except ValueError:  # a bare SB3 checkpoint
        return None
    extra = meta.get("extra") or {}
    config = extra.get("config", extra.get("imitation"))
    if isinstance(config, dict):
        return config.get("train", config)
    known = {"observation": meta["observation"], "repeat": meta["repeat"]}
    if meta.get("options") is not None or "explorer_option" in meta:
        known["options"] = list(option_names(meta.get("options"), meta.get("explorer_option", False)))
    return known


def _comparable(config: dict[str, Any]) -> dict[str, Any]:
    """``config`` with ``observation`` completed by `ActiveObservation`'s defaults (so ``{}`` equals the
    defaults given explicitly), an older run's ``explorer_option`` as ``options``, layout ``files`` as
    absolute paths (so ``./a.json`` equals ``a.json``; relative ones are taken from the current
    directory), ``kind_weights`` "auto" resolved, and tuples as lists, as ``config.json`` holds them."""
    out = json.loads(json.dumps(config))
    if out.get("kind_weights") == "auto":  # resolved as ActiveTrainConfig.weights does (older DAgger runs kept it)
        auto = tuple(out.get("kinds") or ()) == tuple(TRAIN_KINDS)
        out["kind_weights"] = list(DEFAULT_KIND_WEIGHTS) if auto else None
    if isinstance(out.get("files"), list):
        out["files"] = [os.path.abspath(f) if isinstance(f, str) else f for f in out["files"]]
    if "options" not in out and "explorer_option" in out:  # runs saved before options existed
        out["options"] = list(option_names(None, out.pop("explorer_option")))
    if isinstance(out.get("observation"), dict):
        out["observation"] = json.loads(json.dumps({**observation_defaults(), **out["observation"]}))
    return out


def check_resume(resume: str | Path, config: ActiveTrainConfig, out: str | Path | None = None) -> Path:
    """The checkpoint's path; RunFolderError if it is missing or not a PPO model, if ``out`` holds another run than the
    checkpoint's (`check_fresh_out`), or if ``config`` changes a field that shapes the policy's spaces
    (`SPACE_FIELDS`) from what the checkpoint was trained with (`run_config_of`); a changed field of
    `DISTRIBUTION_FIELDS` is printed (continuing on other layouts can be meant); for a bare checkpoint without its
    run's config, if its action or observation space differs from ``config``'s (one env is built to compare).
    Checked before the run's folder is made."""
    path = Path(resume)
    if not path.is_file() and path.with_suffix(".zip").is_file():
        path = path.with_suffix(".zip")
    if not path.is_file():
        raise RunFolderError(f"--resume {resume}: no such checkpoint")
    try:  # a file of something else fails here, before a run folder or an env is made
        model = load_model(path, "PPO")
    except ValueError as e:
        raise RunFolderError(f"--resume {resume}: not a checkpoint of a training run: {e}") from None
    if out is not None and Path(out).resolve() != run_folder_of(path).resolve():
        check_fresh_out(Path(out))
    saved = run_config_of(path)
    if saved is None:  # a checkpoint kept outside its run: its spaces are all there is to compare
        env = make_active_env(config)
        try:
            spaces = {"observation": env.observation_space, "action": env.action_space}
        finally:
            env.close()
        differ = [k for k, space in spaces.items() if getattr(model, f"{k}_space") != space]
        if differ:
            raise RunFolderError(
                f"--resume {resume}: its {' and '.join(differ)} space{'s differ' if len(differ) > 1 else ' differs'} "
                "from this run's (action space: "
                f"checkpoint {model.action_space}, run {spaces['action']}; the options and observation settings "
                "shape them): pass the --config.options and --config.observation it was trained with"
            )
        return path
    if "env_id" not in saved:  # runs made before env_id was a field: their saved policy names the env
        try:
            saved["env_id"] = read_metadata(run_folder_of(path) / "policy.zip")["extra"]["env_id"]
        except (FileNotFoundError, ValueError, KeyError, TypeError):
            print(
                f"note: {path}'s run does not record its env (runs saved before ActiveTrainConfig.env_id and "
                f"without a policy.zip; they trained in the newest env of their code); this run trains in "
                f"{config.env_id}",
                flush=True,
            )
    saved, now = _comparable(saved), _comparable(config.as_dict())
    differ = [f for f in SPACE_FIELDS if f in saved and saved[f] != now[f]]
    if differ:
        raise RunFolderError(
            f"--resume {resume}: it was trained with "
            + ", ".join(f"{f}={saved[f]!r}" for f in differ)
            + ", this run has "
            + ", ".join(f"{f}={now[f]!r}" for f in differ)
            + ": pass the same --config.<field> values (see its run's config.json)"
        )
    changed = [f for f in DISTRIBUTION_FIELDS if f in saved and saved[f] != now[f]]
    if changed:
        print(
            f"note: continuing {path} with other training settings than its run: "
            + "; ".join(f"{f} {saved[f]!r} -> {now[f]!r}" for f in changed),
            flush=True,
        )
    kept = [f for f in MODEL_FIELDS if f in saved and saved[f] != now[f]]
    if kept:
        print(
            f"note: {path} keeps its own PPO and network settings (a checkpoint carries them), not this "
            "command's: " + "; ".join(f"{f} {saved[f]!r} (given {now[f]!r})" for f in kept),
            flush=True,
        )
    return path


def resumed_config(model: PPO, config: ActiveTrainConfig) -> ActiveTrainConfig:
    """``config`` with the `MODEL_FIELDS` a loaded checkpoint ``model`` carries, which are what a resumed
    run trains with (and what its ``config.json`` records), also for a bare checkpoint without a run
    config."""
    kw = model.policy_kwargs or {}
    extractor = kw.get("features_extractor_kwargs") or {}
    clip = model.clip_range(1.0) if callable(model.clip_range) else model.clip_range
    lr = model.learning_rate(1.0) if callable(model.learning_rate) else model.learning_rate
    kept = {
        "n_steps": int(model.n_steps),
        "batch_size": int(model.batch_size),
        "n_epochs": int(model.n_epochs),
        "learning_rate": float(lr),
        "gamma": float(model.gamma),
        "gae_lambda": float(model.gae_lambda),
        "ent_coef": float(model.ent_coef),
        "clip_range": float(clip),
        "vf_coef": float(model.vf_coef),
    }
    if "features_dim" in extractor:
        kept["features_dim"] = int(extractor["features_dim"])
    if "cnn_channels" in extractor:
        kept["cnn_channels"] = tuple(int(c) for c in extractor["cnn_channels"])
    if isinstance(kw.get("net_arch"), (list, tuple)) and all(isinstance(v, int) for v in kw["net_arch"]):
        kept["net_arch"] = tuple(kw["net_arch"])
    return dataclasses.replace(config, **kept)


def _checkpoints_overwritten(out: Path, decisions: int, config: ActiveTrainConfig) -> list[str]:
    """The checkpoints in ``out/checkpoints`` that a run resumed at ``decisions`` would write again
    (`CheckpointCallback` names them by the decision count, which carries on)."""
    if config.checkpoint_every is None:
        return []
    step = max(1, config.checkpoint_every // config.n_envs) * config.n_envs
    last = decisions + config.total_timesteps + config.n_steps * config.n_envs  # learn() ends on a rollout
    names = {f"ppo_{n}_steps.zip" for n in range(decisions + step, last + 1, step)}
    return sorted(f.name for f in (out / "checkpoints").glob("ppo_*_steps.zip") if f.name in names)


def train_active(
    config: ActiveTrainConfig,
    out: str | Path,
    resume: str | Path | None = None,
    callbacks: list[BaseCallback] | None = None,
) -> Path:
    """Train as ``config`` says; write everything under ``out``; return the saved policy's path.

    ``out`` receives ``config.json``, ``progress.csv`` and TensorBoard events, ``checkpoints/``
    (``ppo_<decisions>_steps.zip``), ``policy.zip`` (`agents.learned.save_policy`) and
    ``timing.json`` (wall and CPU seconds of this run, its decisions and the total since the first
    run, env steps) and ``learning_curve.png``.
    ``resume``: a checkpoint to continue from; ``total_timesteps`` more decisions are trained (the
    step count carries on), and the earlier run's ``progress.csv``, ``timing.json``, ``config.json``,
    ``policy.zip`` and ``learning_curve.png`` in ``out`` are kept as ``*_before_<decisions>.*``;
    RunFolderError instead of overwriting such files or the checkpoints of a later point of the run
    (resume into a new ``out`` then). The checkpoint's PPO and network settings (`MODEL_FIELDS`) are
    kept, whatever ``config`` says (a note names the differences), and ``config.json`` records them.
    """
    out = Path(out)
    if resume is None:
        check_fresh_out(out)
    else:
        resume = check_resume(resume, config, out)
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(int(config.torch_threads))
    venv = make_active_venv(config)
    try:  # the envs (subprocesses, workers) are closed if the model cannot be set up
        if resume is not None:
            # seed: SB3's load reseeds everything with the checkpoint's own seed unless given one (an audit: a
            # resumed run ignored --config.seed, and config.json recorded a seed that never ran)
            model = PPO.load(resume, env=venv, device=config.device, seed=config.seed)
            # the checkpoint's episode statistics would fill the resumed run's rollout/* rows and its curve
            model.ep_info_buffer = model.ep_success_buffer = None
            config = resumed_config(model, config)  # its n_steps also bounds the checkpoints it will write
            n = int(model.num_timesteps)
            names = ("progress.csv", "timing.json", "config.json", "policy.zip", "learning_curve.png")
            taken = [f"{Path(m).stem}_before_{n}{Path(m).suffix}" for m in names]
            taken = [t for t in taken if (out / t).exists()] + _checkpoints_overwritten(out, n, config)
            if taken:  # resuming would overwrite an earlier run's files
                raise RunFolderError(
                    f"--resume {resume} into {out} would overwrite {', '.join(taken)} (this folder continued from "
                    f"{n} decisions before, or holds later checkpoints): give a new --out"
                )
            for name in names:
                if (out / name).exists():
                    (out / name).rename(out / f"{Path(name).stem}_before_{n}{Path(name).suffix}")
        else:
            model = build_model(config, venv)
        (out / "config.json").write_text(json.dumps(config.as_dict(), indent=1))
        logger = configure(str(out), log_formats(config.verbose))
        model.set_logger(logger)
        cbs: list[BaseCallback] = [RelocalizationMetricsCallback(window=100)]
        if config.checkpoint_every is not None:
            cbs.append(
                CheckpointCallback(
                    save_freq=max(1, config.checkpoint_every // config.n_envs),
                    save_path=str(out / "checkpoints"),
                    name_prefix="ppo",
                )
            )
        if config.time_budget_s is not None:
            cbs.append(WallClockBudget(config.time_budget_s))
        cbs += list(callbacks or [])
    except BaseException:
        close_after_interrupt(venv)
        raise
    t0, c0 = time.time(), time.process_time()
    start_decisions = int(model.num_timesteps)  # > 0 when resumed
    with closing_venv(venv):
        try:
            model.learn(
                total_timesteps=config.total_timesteps,
                callback=cbs,
                progress_bar=progress_bar_wanted(config.progress_bar),
                reset_num_timesteps=resume is None,
            )
        finally:
            logger.close()
    timing = {
        "wall_s": time.time() - t0,
        "learner_cpu_s": time.process_time() - c0,
        "decisions": int(model.num_timesteps),  # in all, the resumed runs' included
        "decisions_this_run": int(model.num_timesteps) - start_decisions,  # those wall_s and learner_cpu_s paid
        "env_steps_max": int(model.num_timesteps) * config.repeat,
        "resumed_from": None if resume is None else str(resume),
    }
    (out / "timing.json").write_text(json.dumps(timing, indent=1))
    try:
        plot_learning_curve(out / "progress.csv", out / "learning_curve.png", config.repeat)
    except ValueError:  # too short a run for one logged rollout
        pass
    return save_policy(
        model,
        out / "policy.zip",
        observation=config.observation,
        repeat=config.repeat,
        options=config.options,
        extra={"env_id": config.env_id, "config": config.as_dict(), "timing": timing},
    )
