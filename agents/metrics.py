"""Relocalization metrics of episodes, from the env's ``info`` alone (no torch, no SB3).

Shared by `agents.callbacks` (training logs) and `agents.train.evaluate`, so
both count the same way. Definitions, per episode, from the ``info`` of its last step:

* **success**: the belief is converged (``info["belief"]["converged"]``) and its mean is
  within ``SUCCESS_POSITION_M`` (0.5 m) and ``SUCCESS_HEADING_RAD`` (15 deg) of the truth
  (``info["pose_error"]``) -- exactly the termination condition of ``SemReloc-v22`` (and v21 ... v0).
* **wrong convergence**: the episode ended with a converged belief that is *not* within
  those bounds: the filter is confidently wrong.
* **unconverged**: neither (the belief is still spread out at the end).
  The three outcomes partition the episodes, so their rates sum to 1.
* **steps to converge**: the episode length of a successful episode (env steps, 0.1 s each
  at the default physics), undefined otherwise.
* **first convergence wrong**: the first step whose belief was converged had the wrong pose
  (recorded whether or not the episode later succeeded).
* **final position error** (m) / **final heading error** (rad) of the belief mean.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from semreloc_env.envs.semreloc import SUCCESS_HEADING_RAD, SUCCESS_POSITION_M

OUTCOMES = ("success", "wrong", "unconverged")


def belief_correct(info: dict) -> bool:
    """Whether the belief of one step's ``info`` is converged at the true pose (the success test)."""
    err = info["pose_error"]
    return bool(
        info["belief"]["converged"] and err["position"] < SUCCESS_POSITION_M and err["heading"] < SUCCESS_HEADING_RAD
    )


@dataclass(frozen=True)
class EpisodeResult:
    """One finished episode (see the module docstring). Units: steps, metres, radians."""

    outcome: str
    length: int
    steps_to_converge: int | None
    first_convergence_wrong: bool
    final_position_error_m: float
    final_heading_error_rad: float
    episode_return: float

    def as_dict(self) -> dict:
        return asdict(self)


class EpisodeTracker:
    """Accumulates one episode's steps; `finish` returns its `EpisodeResult`.

    Call `observe` with the ``info`` and reward of every step (the reset ``info`` may be
    observed too, with ``reward=0`` and ``is_step=False``: it counts for first convergence but
    not for the length).
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.length = 0
        self.ret = 0.0
        self.first_convergence_wrong: bool | None = None
        self.last_info: dict | None = None

    def observe(self, info: dict, reward: float = 0.0, is_step: bool = True) -> None:
        if is_step:
            self.length += 1
            self.ret += float(reward)
        if self.first_convergence_wrong is None and info["belief"]["converged"]:
            self.first_convergence_wrong = not belief_correct(info)
        self.last_info = info

    def finish(self) -> EpisodeResult:
        if self.last_info is None:
            raise RuntimeError("no step observed in this episode")
        info = self.last_info
        if belief_correct(info):
            outcome = "success"
        elif info["belief"]["converged"]:
            outcome = "wrong"
        else:
            outcome = "unconverged"
        result = EpisodeResult(
            outcome=outcome,
            length=self.length,
            steps_to_converge=self.length if outcome == "success" else None,
            first_convergence_wrong=bool(self.first_convergence_wrong),
            final_position_error_m=float(info["pose_error"]["position"]),
            final_heading_error_rad=float(info["pose_error"]["heading"]),
            episode_return=self.ret,
        )
        self.reset()
        return result


def summarize_episodes(results: list[EpisodeResult]) -> dict[str, float]:
    """Rates and medians over episodes (None where undefined: the median steps when nothing succeeded).

    Keys: ``episodes``, ``success_rate``, ``wrong_convergence_rate``, ``unconverged_rate``,
    ``first_convergence_wrong_rate`` (all in [0, 1]), ``median_steps_to_converge`` (over successful
    episodes), ``mean_episode_length`` (steps), ``median_final_position_error_m``,
    ``median_final_heading_error_rad``, ``mean_return``.
    """
    n = len(results)
    if n == 0:
        raise ValueError("no episodes to summarise")
    steps = [r.steps_to_converge for r in results if r.steps_to_converge is not None]
    return {
        "episodes": n,
        "success_rate": sum(r.outcome == "success" for r in results) / n,
        "wrong_convergence_rate": sum(r.outcome == "wrong" for r in results) / n,
        "unconverged_rate": sum(r.outcome == "unconverged" for r in results) / n,
        "first_convergence_wrong_rate": sum(r.first_convergence_wrong for r in results) / n,
        "median_steps_to_converge": float(np.median(steps)) if steps else None,
        "mean_episode_length": float(np.mean([r.length for r in results])),
        "median_final_position_error_m": float(np.median([r.final_position_error_m for r in results])),
        "median_final_heading_error_rad": float(np.median([r.final_heading_error_rad for r in results])),
        "mean_return": float(np.mean([r.episode_return for r in results])),
    }
