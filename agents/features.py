"""A stable-baselines3 features extractor for the semreloc Dict observation.

`SemRelocExtractor` turns ``{"lidar", "semantic", "odometry", "belief", ...}`` into one
feature vector:

* every Box entry is first scaled to ``[0, 1]`` by its own space bounds (``(x - low) / (high - low)``),
  so metres, radians and counts reach the network on one scale without ``VecNormalize``;
* ``lidar``: a 1D convolution with *circular* padding over the beams (a 360 deg scan has no
  edges), then a linear layer;
* the semantic camera, in either observation layout: ``semantic_range`` (Box) with ``semantic_class``
  (``MultiDiscrete``, which SB3 hands over one-hot; ``SemReloc-v22``, ``ActiveObservation``), or the flat
  ``semantic`` Box of ``SemReloc-v1``/``-v0`` (ranges, then labels as floats, one-hot encoded here): per
  beam, the scaled range and the one-hot class stacked as channels, through a 1D convolution (zero
  padding: the camera's field of view has edges), then a linear layer;
* any other key (``odometry``, ``belief``, ...): a small MLP.

The per-key outputs are concatenated and passed through a final linear layer + ReLU to
``features_dim`` features. Use it with ``policy_kwargs={"features_extractor_class":
SemRelocExtractor, "features_extractor_kwargs": {...}}`` and ``"MultiInputPolicy"`` or, a little faster,
`SemRelocPolicy`.

`SemRelocPolicy` is SB3's ``MultiInputPolicy`` (``MultiInputActorCriticPolicy``), with two costs cut
(``agents.train`` and ``agents.train_active`` build their models with it):

* its observation preprocessing (`preprocess_observation`) one-hot encodes a ``MultiDiscrete`` entry in one
  torch call instead of one per beam, the same tensors: for the 32 camera beams of ``semantic_class`` a
  batch-16 policy forward took about 1.0 instead of 1.2 ms of CPU here;
* its optimizer is torch's fused Adam (`FUSED_ADAM`), one kernel per parameter instead of a dozen tensor
  operations: a 256-sample PPO minibatch took 7.5-7.8 instead of 8.9-10.1 ms. The same algorithm rounded in
  another order, so a training run differs from one with ``"MultiInputPolicy"`` in the last bits (and then,
  as training does, in more); ``optimizer_kwargs={"eps": 1e-5}`` gives SB3's optimizer back.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.policies import BaseModel, MultiInputActorCriticPolicy
from stable_baselines3.common.preprocessing import preprocess_obs
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from semreloc_env.layouts import CLASS_NAMES


class _Scale(nn.Module):
    """``(x - low) / (high - low)`` for a Box with finite bounds (identity where unbounded)."""

    def __init__(self, box: gym.spaces.Box):
        super().__init__()
        low = np.asarray(box.low, dtype=np.float64).ravel()
        high = np.asarray(box.high, dtype=np.float64).ravel()
        finite = np.isfinite(low) & np.isfinite(high) & (high > low)
        offset = np.where(finite, low, 0.0)
        scale = np.where(finite, 1.0 / np.where(finite, high - low, 1.0), 1.0)
        self.register_buffer("offset", torch.as_tensor(offset, dtype=torch.float32))
        self.register_buffer("scale", torch.as_tensor(scale, dtype=torch.float32))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return (x.flatten(1) - self.offset) * self.scale


class SemRelocExtractor(BaseFeaturesExtractor):
    """Per-key encoders for the semreloc Dict observation, concatenated (see the module docstring).

    Args:
        observation_space: a ``Dict`` of ``Box`` entries, plus ``semantic_class`` (``MultiDiscrete``,
            one entry per beam, all with the same number of classes) next to ``semantic_range``;
            ``lidar`` and the semantic camera get convolutions when present, every other key an MLP.
        features_dim: size of the output feature vector.
        conv_channels: channels of each 1D convolution layer (two layers, kernel 5, stride 2).
        key_dim: output size of each per-key encoder.
        n_classes: number of semantic labels including 0 = none in the flat ``semantic`` layout
            (default ``len(CLASS_NAMES) + 1``); the typed layout reads it from ``semantic_class``.
    """

    def __init__(
        self,
        observation_space: gym.spaces.Dict,
        features_dim: int = 128,
        conv_channels: int = 16,
        key_dim: int = 64,
        n_classes: int = len(CLASS_NAMES) + 1,
    ):
        super().__init__(observation_space, features_dim)
        if not isinstance(observation_space, gym.spaces.Dict):
            raise TypeError(f"SemRelocExtractor needs a Dict observation space, got {observation_space}")
        self.n_classes = int(n_classes)
        entries = observation_space.spaces
        classes = entries.get("semantic_class")
        if classes is not None:
            nvec = np.asarray(getattr(classes, "nvec", []))
            ranges = entries.get("semantic_range")
            if not isinstance(classes, gym.spaces.MultiDiscrete) or nvec.ndim != 1 or np.any(nvec != nvec[0]):
                raise TypeError(f"'semantic_class' must be a 1-D MultiDiscrete with one class count, got {classes}")
            if not isinstance(ranges, gym.spaces.Box) or int(np.prod(ranges.shape)) != nvec.size:
                raise ValueError(f"'semantic_class' needs a 'semantic_range' Box of {nvec.size} beams, got {ranges}")
            self.n_sem_classes = int(nvec[0])
        self.keys = tuple(k for k in entries if k != "semantic_class")  # encoded with semantic_range
        self.scalers = nn.ModuleDict()
        self.encoders = nn.ModuleDict()
        total = 0
        for key in self.keys:
            box = entries[key]
            if not isinstance(box, gym.spaces.Box):
                raise TypeError(f"observation entry {key!r} is {box}, not a Box")
            n = int(np.prod(box.shape))
            self.scalers[key] = _Scale(box)
            if key == "lidar":
                enc = self._conv(1, n, conv_channels, key_dim, padding_mode="circular")
            elif key == "semantic_range" and classes is not None:
                enc = self._conv(1 + self.n_sem_classes, n, conv_channels, key_dim, padding_mode="zeros")
            elif key == "semantic":
                if n % 2:
                    raise ValueError(f"'semantic' must hold ranges then labels (even length), got {n}")
                enc = self._conv(1 + self.n_classes, n // 2, conv_channels, key_dim, padding_mode="zeros")
            else:
                enc = nn.Sequential(nn.Linear(n, key_dim), nn.ReLU(), nn.Linear(key_dim, key_dim), nn.ReLU())
            self.encoders[key] = enc
            total += key_dim
        self.head = nn.Sequential(nn.Linear(total, features_dim), nn.ReLU())

    @staticmethod
    def _conv(in_ch: int, length: int, ch: int, out_dim: int, padding_mode: str) -> nn.Sequential:
        conv = nn.Sequential(
            nn.Conv1d(in_ch, ch, kernel_size=5, stride=2, padding=2, padding_mode=padding_mode),
            nn.ReLU(),
            nn.Conv1d(ch, ch, kernel_size=5, stride=2, padding=2, padding_mode=padding_mode),
            nn.ReLU(),
            nn.Flatten(),
        )
        with torch.no_grad():
            n_flat = conv(torch.zeros(1, in_ch, length)).shape[1]
        return nn.Sequential(conv, nn.Linear(n_flat, out_dim), nn.ReLU())

    def _channels(self, key: str, obs: torch.Tensor, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        if key == "lidar":
            return self.scalers[key](obs).unsqueeze(1)
        if key == "semantic_range" and "semantic_class" in observations:
            ranges = self.scalers[key](obs)
            # SB3's preprocess_obs one-hot encodes a MultiDiscrete: (B, beams * classes), beam-major
            classes = observations["semantic_class"].flatten(1)
            if classes.shape[1] != ranges.shape[1] * self.n_sem_classes:
                raise ValueError(
                    f"'semantic_class' must arrive one-hot, {ranges.shape[1]} x {self.n_sem_classes} values per "
                    f"sample (stable_baselines3.common.preprocessing.preprocess_obs), got {classes.shape[1]}"
                )
            onehot = classes.reshape(ranges.shape[0], ranges.shape[1], self.n_sem_classes)
            return torch.cat([ranges.unsqueeze(1), onehot.float().transpose(1, 2)], dim=1)
        if key == "semantic":
            flat = obs.flatten(1)
            half = flat.shape[1] // 2
            ranges = self.scalers[key](flat)[:, :half]
            labels = flat[:, half:].round().long().clamp(0, self.n_classes - 1)
            onehot = nn.functional.one_hot(labels, self.n_classes).float().transpose(1, 2)
            return torch.cat([ranges.unsqueeze(1), onehot], dim=1)
        return self.scalers[key](obs)

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        parts = [self.encoders[k](self._channels(k, observations[k], observations)) for k in self.keys]
        return self.head(torch.cat(parts, dim=1))


def preprocess_observation(
    obs: torch.Tensor | dict[str, torch.Tensor], space: gym.spaces.Space, normalize_images: bool = True
) -> torch.Tensor | dict[str, torch.Tensor]:
    """SB3's ``preprocess_obs`` (``stable_baselines3.common.preprocessing``), the same tensors, with a 1-D
    ``MultiDiscrete`` whose entries share one class count one-hot encoded in one call: ``(B, n * classes)``
    float32, entry-major, as SB3 concatenates its per-entry one-hots. Any other space goes to SB3's function
    (Dict entries one by one)."""
    if isinstance(space, gym.spaces.Dict):
        if not isinstance(obs, dict):
            raise TypeError(f"a Dict observation space needs a dict of tensors, got {type(obs).__name__}")
        return {key: preprocess_observation(value, space[key], normalize_images) for key, value in obs.items()}
    if isinstance(space, gym.spaces.MultiDiscrete) and space.nvec.ndim == 1 and space.nvec.size:
        n = int(space.nvec[0])
        if (space.nvec == n).all():
            return nn.functional.one_hot(obs.long(), n).float().view(obs.shape[0], space.nvec.size * n)
    return preprocess_obs(obs, space, normalize_images=normalize_images)


class _OneCallPreprocessing(BaseModel):
    """``extract_features`` through `preprocess_observation`. A mixin listed after SB3's policy class, so that it
    comes between ``ActorCriticPolicy`` (whose ``extract_features`` calls ``super()``) and ``BaseModel``."""

    def extract_features(self, obs, features_extractor: BaseFeaturesExtractor) -> torch.Tensor:
        return features_extractor(preprocess_observation(obs, self.observation_space, self.normalize_images))


class SemRelocPolicy(MultiInputActorCriticPolicy, _OneCallPreprocessing):
    """SB3's ``MultiInputPolicy`` with `preprocess_observation` and torch's fused Adam (the module docstring): pass it
    to ``PPO`` (or ``A2C``) in place of ``"MultiInputPolicy"``, with the same ``policy_kwargs``.

    With Adam (``optimizer_class``, SB3's default; A2C passes RMSprop unless ``use_rms_prop=False``) and no
    ``optimizer_kwargs``, these are ``{"eps": 1e-5, "fused": True}`` (`FUSED_ADAM`): SB3's ``eps`` with torch's
    fused implementation (CPU and CUDA), which updates all of a parameter's entries in one kernel instead of a
    dozen tensor operations per parameter; the same algorithm rounded in another order, so a run differs from
    ``"MultiInputPolicy"``'s in the last bits. ``optimizer_kwargs={"eps": 1e-5}`` gives SB3's own optimizer; any
    other ``optimizer_kwargs`` or ``optimizer_class`` is taken as SB3 takes it."""

    def __init__(self, *args, optimizer_class=torch.optim.Adam, optimizer_kwargs=None, **kwargs):
        if optimizer_kwargs is None and optimizer_class is torch.optim.Adam:
            optimizer_kwargs = dict(FUSED_ADAM)
        super().__init__(*args, optimizer_class=optimizer_class, optimizer_kwargs=optimizer_kwargs, **kwargs)


FUSED_ADAM = {"eps": 1e-5, "fused": True}
"""`SemRelocPolicy`'s default ``optimizer_kwargs``: SB3's Adam ``eps``, torch's fused Adam."""
