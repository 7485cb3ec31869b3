"""Imitation of the viewpoint planner (DAgger): a network that acts on its own observations.

`agents.train_active` trains PPO; with the planner among its actions (options) PPO learns to call
the planner at every decision, and with the four primitive actions alone it learns to turn on the
spot. Imitation asks another question: can a network *act like* the planner from the policy's
observation (`semreloc_env.observations.ActiveObservation`: belief crops, hypotheses, scans, last
action), without the planner's search, its path or its memory?

`imitate` runs DAgger (Ross, Gordon and Bagnell, AISTATS 2011) on the training envs of
`agents.train_active.make_active_env` (four primitive actions, one env step per decision, a new
procedural layout every episode, never a held-out seed):

1. every round collects ``episodes_per_round`` episodes. Each step, the teacher
   (`agents.viewpoint.ViewpointPlanner`, run beside the env by `agents.options.TeacherLabels` and fed every
   observation) says what it would do (``info["teacher_action"]``); the robot takes the teacher's
   action with probability ``beta`` (1 in the first round, times ``beta_decay`` each round after)
   and the network's otherwise, so later rounds visit the states the network drives into;
2. every (observation, teacher action) pair joins the data set;
3. the network (SB3 PPO's policy, `agents.active_features.ActiveExtractor`, the same architecture
   `train_active` builds) is fitted to all pairs so far by cross-entropy for ``epochs`` passes.

The result is saved like a PPO run (`agents.learned.save_policy`): `agents.load_policy` loads it,
`scripts/evaluate_active.py` evaluates it, and `train_active --resume` can continue it with PPO.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from filters.experiments.cli import JsonDict
from filters.numbers import is_int, is_real

from .learned import save_policy
from .options import TeacherLabels  # noqa: F401  (documented here: agents.imitation.TeacherLabels)
from .train_active import ActiveTrainConfig, build_model, check_fresh_out, make_active_venv
from .vec_env import closing_venv


def _default_train() -> ActiveTrainConfig:
    return ActiveTrainConfig(options=(), repeat=1, belief_mass_weight=0.0, n_envs=2, progress_bar=False)


@dataclass(frozen=True)
class ImitationConfig:
    """One DAgger run (each field documented below)."""

    train: ActiveTrainConfig = field(default_factory=_default_train)
    """envs and network: layout kinds and seeds, particles, episode length, observation, n_envs,
    vec_env, seed, network sizes, torch threads, device (`agents.train_active.ActiveTrainConfig`;
    its options must be empty and its repeat 1; its PPO settings matter only to a later PPO run)"""
    rounds: int = 6
    """DAgger rounds (collect, then fit)"""
    episodes_per_round: int = 60
    """episodes collected per round, over all envs"""
    beta: float = 1.0
    """probability that the teacher's action is taken in the first round"""
    beta_decay: float = 0.5
    """factor on beta after each round (0: the network drives from the second round on)"""
    epochs: int = 3
    """passes over all data collected so far, after each round"""
    batch_size: int = 256
    """minibatch size of the fit"""
    learning_rate: float = 1e-3
    """Adam step size of the fit"""
    max_samples: int = 60_000
    """cap on the data set (the oldest pairs are dropped beyond it; ~41 KB each)"""
    planner: JsonDict = field(default_factory=dict)
    """keyword arguments of the teacher `agents.viewpoint.ViewpointPlanner` (empty: its defaults); on the
    command line one JSON object, e.g. '{"replan_every": 5}'"""

    def __post_init__(self) -> None:
        if self.train.options or self.train.repeat != 1:
            raise ValueError(
                "imitation trains the four primitive actions one step at a time: train.options must be empty "
                f"and train.repeat 1, got options={self.train.options!r}, repeat={self.train.repeat!r}"
            )
        if self.train.time_budget_s is not None:  # an audit: it was taken and ignored
            raise ValueError(
                "imitation runs its rounds to the end: train.time_budget_s applies to train_active only, got "
                f"{self.train.time_budget_s!r}; choose fewer rounds or episodes_per_round instead"
            )
        for name in ("rounds", "episodes_per_round", "epochs", "batch_size", "max_samples"):
            v = getattr(self, name)
            if not (is_int(v) and v >= 1):
                raise ValueError(f"{name} must be an integer >= 1, got {v!r:.60}")
        for name, lo, hi in (("beta", 0.0, 1.0), ("beta_decay", 0.0, 1.0)):
            v = getattr(self, name)
            if not (is_real(v) and lo <= v <= hi):
                raise ValueError(f"{name} must be a number in [{lo}, {hi}], got {v!r:.60}")
        if not (is_real(self.learning_rate) and 0 < self.learning_rate < 1):
            raise ValueError(f"learning_rate must be a number in (0, 1), got {self.learning_rate!r:.60}")
        if not isinstance(self.planner, dict):
            raise ValueError(f"planner must be a dict of ViewpointPlanner arguments, got {self.planner!r:.60}")
        from .viewpoint import ViewpointPlanner

        try:  # unknown or bad planner arguments fail here, not in the workers
            ViewpointPlanner(**self.planner)
        except TypeError as e:
            raise ValueError(f"planner: {e}") from None

    def as_dict(self) -> dict[str, Any]:
        """The fields, ``train`` as `ActiveTrainConfig.as_dict` records it (``kind_weights`` resolved)."""
        return {**dataclasses.asdict(self), "train": self.train.as_dict()}


class _Dataset:
    """(observation, teacher action) pairs, stored compactly (float16 images, int8 labels), capped."""

    def __init__(self, cap: int):
        self.cap = cap
        self.obs: dict[str, list[np.ndarray]] = {}
        self.labels: list[np.ndarray] = []

    def add(self, obs: dict[str, np.ndarray], labels: np.ndarray) -> None:
        for k, v in obs.items():
            v = np.asarray(v)
            small = v.astype(np.float16) if v.dtype.kind == "f" else v.astype(np.int8)
            self.obs.setdefault(k, []).append(small)
        self.labels.append(np.array(labels, dtype=np.int64))  # a copy: the caller's array is reused

    def arrays(self) -> tuple[dict[str, np.ndarray], np.ndarray]:
        obs = {k: np.concatenate(v)[-self.cap :] for k, v in self.obs.items()}
        labels = np.concatenate(self.labels)[-self.cap :]
        self.obs = {k: [v] for k, v in obs.items()}
        self.labels = [labels]
        return obs, labels


class _Rollouts:
    """The training envs and where their episodes stand (observations and teacher actions)."""

    def __init__(self, venv):
        self.venv = venv
        self.obs = venv.reset()
        self.labels = np.array([info["teacher_action"] for info in venv.reset_infos])

    def collect(self, model, episodes: int, beta: float, rng: np.random.Generator, data: _Dataset | None):
        """Run until ``episodes`` episodes end (the teacher's action with probability ``beta``, else
        the network's); add every step's pair to ``data`` (None: keep none). Returns ``(successes,
        episodes, steps, agreement)``: agreement is the share of steps at which the network's
        deterministic action equals the teacher's. Episodes still running when it returns go on in
        the next call (under its beta and network), so a round's figures include up to ``n_envs``
        episodes begun in the round before."""
        venv, n = self.venv, self.venv.num_envs
        done_eps = successes = steps = agree = 0
        while done_eps < episodes:
            mine, _ = model.predict(self.obs, deterministic=True)
            mine = np.asarray(mine, dtype=np.int64).reshape(n)
            agree += int(np.sum(mine == self.labels))
            if data is not None:
                data.add(self.obs, self.labels)
            self.obs, _, dones, infos = venv.step(np.where(rng.random(n) < beta, self.labels, mine))
            steps += n
            labels = []
            for i, info in enumerate(infos):
                if dones[i]:  # the env was reset: its next label is in the reset's info
                    done_eps += 1
                    successes += bool(info.get("is_success", False))
                    info = venv.reset_infos[i]
                labels.append(info["teacher_action"])
            self.labels = np.array(labels, dtype=np.int64)
        return successes, done_eps, steps, agree / max(steps, 1)


def _fit(model, obs: dict[str, np.ndarray], labels: np.ndarray, config: ImitationConfig, optimizer, rng) -> float:
    """``config.epochs`` passes of cross-entropy on ``(obs, labels)``; returns the last pass's mean loss."""
    policy = model.policy
    policy.set_training_mode(True)
    n = labels.shape[0]
    mean_loss = float("nan")
    for _ in range(config.epochs):
        order = rng.permutation(n)
        total = 0.0
        for start in range(0, n, config.batch_size):
            idx = order[start : start + config.batch_size]
            batch = {
                k: v[idx].astype(np.float32) if v.dtype == np.float16 else v[idx].astype(np.int64)
                for k, v in obs.items()
            }
            obs_t, _ = policy.obs_to_tensor(batch)
            dist = policy.get_distribution(obs_t)
            loss = -dist.log_prob(torch.as_tensor(labels[idx], device=policy.device)).mean()
            optimizer.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), 1.0)
            optimizer.step()
            total += float(loss.detach()) * idx.size
        mean_loss = total / n
    policy.set_training_mode(False)
    return mean_loss


def plot_imitation_curve(rows: list[dict[str, Any]], path: str | Path) -> Path:
    """Rollout success and agreement with the teacher per DAgger round (from `imitate`'s rows)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    r = [row["round"] for row in rows]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    ax.plot(r, [row["success"] for row in rows], "o-", label="rollout success (teacher share: beta)")
    ax.plot(r, [row["agreement"] for row in rows], "s-", label="network action = teacher's (visited states)")
    ax.plot(r, [row["beta"] for row in rows], ":", color="grey", label="beta")
    ax.set_xlabel("DAgger round (the network as fitted after the round before)")
    ax.set_ylim(0, 1)
    ax.legend(loc="lower left", fontsize=8)
    fitted = [row for row in rows if row["loss"] == row["loss"]]  # the last round fits nothing (NaN)
    ax2 = ax.twinx()
    ax2.plot([row["round"] for row in fitted], [row["loss"] for row in fitted], "^--", color="tab:red")
    ax2.set_ylabel("fit's cross-entropy on all pairs so far (nats)", color="tab:red")
    ax2.set_ylim(bottom=0)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def imitate(config: ImitationConfig, out: str | Path) -> Path:
    """Run DAgger as ``config`` says; write everything under ``out``; return the saved policy's path.

    ``out`` receives ``config.json``, ``imitation.csv`` (per round: beta, episodes, success rate,
    steps, the network's agreement with the teacher on the visited states, the data set size, the
    fit's loss, seconds; a last row, ``rounds``, runs the final network alone and fits nothing),
    ``learning_curve.png``, ``timing.json`` and ``policy.zip``.
    Seeded: the same config gives the same policy (on the same machine and library versions).
    """
    out = Path(out)
    check_fresh_out(out, resumable=False)
    out.mkdir(parents=True, exist_ok=True)
    t = config.train
    torch.set_num_threads(int(t.torch_threads))
    torch.manual_seed(t.seed)
    rng = np.random.default_rng(t.seed)
    venv = make_active_venv(t, teacher=config.planner)
    t0, c0 = time.time(), time.process_time()
    rows: list[dict[str, Any]] = []
    with closing_venv(venv):
        # after the envs are built: a run that fails to build them leaves no config.json to block its folder
        (out / "config.json").write_text(json.dumps(config.as_dict(), indent=1))
        model = build_model(t, venv)
        optimizer = torch.optim.Adam(model.policy.parameters(), lr=config.learning_rate)
        data = _Dataset(config.max_samples)
        rollouts = _Rollouts(venv)
        beta = config.beta
        for r in range(config.rounds + 1):  # the last round only measures the final network, alone
            final = r == config.rounds
            beta = 0.0 if final else beta
            tr = time.time()
            succ, eps, steps, agreement = rollouts.collect(
                model, config.episodes_per_round, beta, rng, None if final else data
            )
            obs, labels = data.arrays()
            loss = float("nan") if final else _fit(model, obs, labels, config, optimizer, rng)
            rows.append(
                {
                    "round": r,
                    "beta": beta,
                    "episodes": eps,
                    "success": succ / eps,
                    "steps": steps,
                    "agreement": agreement,
                    "samples": int(labels.shape[0]),
                    "loss": loss,
                    "seconds": time.time() - tr,
                }
            )
            with open(out / "imitation.csv", "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=list(rows[0]))
                w.writeheader()
                w.writerows(rows)
            beta *= config.beta_decay
    # the final round fits nothing: its loss is null in the JSON (NaN is not JSON; "nan" in the CSV)
    json_rows = [{**row, "loss": None if row["loss"] != row["loss"] else row["loss"]} for row in rows]
    timing = {"wall_s": time.time() - t0, "learner_cpu_s": time.process_time() - c0, "rounds": json_rows}
    (out / "timing.json").write_text(json.dumps(timing, indent=1, allow_nan=False))
    plot_imitation_curve(rows, out / "learning_curve.png")
    return save_policy(
        model,
        out / "policy.zip",
        observation=t.observation,
        repeat=1,
        options=(),
        extra={"env_id": t.env_id, "imitation": config.as_dict(), "timing": timing},
    )
