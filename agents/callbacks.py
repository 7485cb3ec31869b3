"""stable-baselines3 callback: relocalization metrics in the training log (progress: SB3's ``progress_bar``).

`RelocalizationMetricsCallback` reads ``info["belief"]`` and ``info["pose_error"]`` of
every env step (works with any VecEnv: the ``info`` of a step that ends an episode is that
episode's last step), scores finished episodes with `agents.metrics` and, at the end of
every rollout, records over the last ``window`` episodes:

| logger key | meaning |
|---|---|
| ``reloc/success_rate`` | fraction of episodes ending converged at the true pose |
| ``reloc/wrong_convergence_rate`` | fraction ending converged at a wrong pose |
| ``reloc/steps_to_converge`` | median length (steps) of the successful episodes (NaN if none) |
| ``reloc/final_position_error_m`` | median final position error of the belief mean (m) |
| ``reloc/episodes`` | episodes finished since training started |
"""

from __future__ import annotations

import math
from collections import deque

from stable_baselines3.common.callbacks import BaseCallback

from .metrics import EpisodeResult, EpisodeTracker, summarize_episodes

METRIC_KEYS = (
    "reloc/success_rate",
    "reloc/wrong_convergence_rate",
    "reloc/steps_to_converge",
    "reloc/final_position_error_m",
    "reloc/episodes",
)


class RelocalizationMetricsCallback(BaseCallback):
    """Log relocalization metrics of finished training episodes (keys: `METRIC_KEYS`).

    Args:
        window: number of most recent episodes the rates and medians are taken over.
        verbose: SB3 verbosity.

    Attributes:
        results: every finished `EpisodeResult`, in order of finishing.
    """

    def __init__(self, window: int = 100, verbose: int = 0):
        super().__init__(verbose)
        if window < 1:
            raise ValueError(f"window must be >= 1, got {window}")
        self.window = int(window)
        self.results: list[EpisodeResult] = []
        self._recent: deque[EpisodeResult] = deque(maxlen=self.window)
        self._trackers: list[EpisodeTracker] = []

    def _on_training_start(self) -> None:
        self._trackers = [EpisodeTracker() for _ in range(self.training_env.num_envs)]

    def _on_step(self) -> bool:
        infos = self.locals["infos"]
        dones = self.locals["dones"]
        rewards = self.locals["rewards"]
        for i, info in enumerate(infos):
            if "belief" not in info:
                continue
            self._trackers[i].observe(info, float(rewards[i]))
            if dones[i]:
                result = self._trackers[i].finish()
                self.results.append(result)
                self._recent.append(result)
        return True

    def _on_rollout_end(self) -> None:
        if not self._recent:
            return
        s = summarize_episodes(list(self._recent))
        self.logger.record("reloc/success_rate", s["success_rate"])
        self.logger.record("reloc/wrong_convergence_rate", s["wrong_convergence_rate"])
        steps = s["median_steps_to_converge"]
        self.logger.record("reloc/steps_to_converge", math.nan if steps is None else steps)
        self.logger.record("reloc/final_position_error_m", s["median_final_position_error_m"])
        self.logger.record("reloc/episodes", len(self.results))
