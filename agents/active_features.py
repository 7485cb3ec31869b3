"""A CNN + MLP features extractor for `semreloc_env.observations.ActiveObservation`.

`ActiveExtractor` encodes every image entry (3-D ``Box``, channels first: ``ego``,
``global``) with its own small CNN, and every other entry (``hypotheses``, ``belief``, ``lidar``,
``semantic_range``, the one-hot ``semantic_class`` that SB3 makes of a ``MultiDiscrete``,
``odometry``, ``last_action``) through one shared MLP over their concatenation; the parts are
concatenated and mapped to ``features_dim`` features. Use it with ``"MultiInputPolicy"`` or
`agents.features.SemRelocPolicy`: ``policy_kwargs={"features_extractor_class": ActiveExtractor}``.

The images are in ``[0, 1]`` already (float32, so SB3 does not rescale them); vectors are scaled
to ``[0, 1]`` by their space bounds, as `agents.features` does. Nothing here depends on the
particle count or the layout's size: the observation's bounds do not.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.preprocessing import get_flattened_obs_dim
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn

from .features import _Scale

MIN_IMAGE_CELLS = 8
"""Smallest side (cells) of an image entry (``ego``, ``global``) `ActiveExtractor`'s convolutions take."""


class ActiveExtractor(BaseFeaturesExtractor):
    """Per-image CNNs and one MLP over the vector entries, concatenated (see the module docstring).

    Args:
        observation_space: a ``Dict`` of ``Box`` (3-D ones are images ``(C, H, W)`` with ``H, W >= 8``)
            and ``MultiDiscrete`` / ``Discrete`` entries.
        features_dim: size of the output.
        cnn_channels: channels of the three stride-2 3x3 convolutions of each image CNN.
        image_dim: output size of each image CNN.
        vector_dim: output size of the vector MLP (two layers).
    """

    def __init__(
        self,
        observation_space: gym.spaces.Dict,
        features_dim: int = 256,
        cnn_channels: tuple[int, int, int] = (16, 32, 32),
        image_dim: int = 128,
        vector_dim: int = 128,
    ):
        super().__init__(observation_space, features_dim)
        if not isinstance(observation_space, gym.spaces.Dict):
            raise TypeError(f"ActiveExtractor needs a Dict observation space, got {observation_space}")
        self.image_keys: list[str] = []
        self.vector_keys: list[str] = []
        self.cnns = nn.ModuleDict()
        self.scalers = nn.ModuleDict()
        n_vec = 0
        for key, space in observation_space.spaces.items():
            if isinstance(space, gym.spaces.Box) and len(space.shape) == 3:
                self.image_keys.append(key)
                self.cnns[key] = self._cnn(space.shape, cnn_channels, image_dim)
            elif isinstance(space, gym.spaces.Box):
                self.vector_keys.append(key)
                self.scalers[key] = _Scale(space)
                n_vec += int(np.prod(space.shape))
            elif isinstance(space, (gym.spaces.MultiDiscrete, gym.spaces.Discrete)):
                self.vector_keys.append(key)  # one-hot already (SB3's preprocess_obs)
                n_vec += int(get_flattened_obs_dim(space))
            else:
                raise TypeError(f"observation entry {key!r} is {space}: not a Box or (Multi)Discrete")
        self.mlp = (
            nn.Sequential(nn.Linear(n_vec, 2 * vector_dim), nn.ReLU(), nn.Linear(2 * vector_dim, vector_dim), nn.ReLU())
            if n_vec
            else None
        )
        total = image_dim * len(self.image_keys) + (vector_dim if n_vec else 0)
        self.head = nn.Sequential(nn.Linear(total, features_dim), nn.ReLU())

    @staticmethod
    def _cnn(shape: tuple[int, ...], channels: tuple[int, int, int], out_dim: int) -> nn.Sequential:
        c, h, w = shape
        if h < MIN_IMAGE_CELLS or w < MIN_IMAGE_CELLS:
            raise ValueError(f"image entries need H, W >= {MIN_IMAGE_CELLS}, got {shape}")
        layers: list[nn.Module] = []
        for ch in channels:
            layers += [nn.Conv2d(c, ch, kernel_size=3, stride=2, padding=1), nn.ReLU()]
            c = ch
        conv = nn.Sequential(*layers, nn.Flatten())
        with torch.no_grad():
            n_flat = conv(torch.zeros(1, *shape)).shape[1]
        return nn.Sequential(conv, nn.Linear(n_flat, out_dim), nn.ReLU())

    def forward(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        parts = [self.cnns[k](observations[k]) for k in self.image_keys]
        if self.mlp is not None:
            vec = [
                self.scalers[k](observations[k]) if k in self.scalers else observations[k].flatten(1)
                for k in self.vector_keys
            ]
            parts.append(self.mlp(torch.cat(vec, dim=1)))
        return self.head(torch.cat(parts, dim=1))
