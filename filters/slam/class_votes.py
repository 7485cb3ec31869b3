"""FastSLAM whose landmarks also carry a class: per particle and landmark slot, a vote count per class.

Association stays purely geometric (the parent's ML gates or known ids); the class labels of the
observations a particle associates with a slot are counted, and a landmark's class is the most
voted one. So a detector's occasional wrong class does not split a landmark, and every landmark
can be drawn and reported with its class. Votes follow the particles through resampling.
"""

from __future__ import annotations

import numpy as np

from filters.numbers import is_int_dtype
from filters.slam.fastslam import Association, FastSLAM


class ClassVotingFastSLAM(FastSLAM):
    """`FastSLAM` plus class votes.

    Args (beyond FastSLAM's):
        n_classes: class labels are ``1..n_classes`` (``0`` means "no class" and is never voted).

    Use ``update(z, ids, classes)`` with ``classes (K,)`` int labels per observation (``None``: no votes).
    State added: ``votes (N, C, n_classes + 1)`` int64 (column 0 unused).
    """

    def __init__(self, *args, n_classes: int, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        if int(n_classes) < 1:
            raise ValueError(f"n_classes must be >= 1, got {n_classes}")
        self.n_classes = int(n_classes)
        self.votes = np.zeros(self.exists.shape + (self.n_classes + 1,), dtype=np.int64)
        self._classes: np.ndarray | None = None

    def update(self, z=None, ids=None, classes=None) -> None:
        """FastSLAM's update; ``classes (K,)`` labels in ``1..n_classes`` are voted onto the associated slots."""
        if classes is not None:
            c = np.asarray(classes)
            if c.size == 0:
                c = c.reshape(0)
            k = 0 if z is None else np.asarray(z).reshape(-1, 2).shape[0]
            if c.shape != (k,) or (c.size and not is_int_dtype(c.dtype)):
                raise ValueError(f"classes must be ({k},) integers, got {c!r}")
            if c.size and (c.min() < 1 or c.max() > self.n_classes):
                raise ValueError(f"class labels must lie in 1..{self.n_classes}, got {c.tolist()}")
            self._classes = c.astype(np.int64)
        try:
            super().update(z, ids)
        finally:
            self._classes = None

    def landmark_classes(self, slots: np.ndarray, particle: int | None = None) -> np.ndarray:
        """Most voted label ``(len(slots),)`` of ``slots`` in ``particle`` (default: the best one); 0 if no vote."""
        b = self._best if particle is None else int(particle)
        v = self.votes[b, np.asarray(slots, dtype=np.int64)]
        return np.where(v.sum(axis=-1) > 0, np.argmax(v, axis=-1), 0).astype(np.int64)

    # ------------------------------------------------------------------ hooks
    def _associate(self, z: np.ndarray, ids: np.ndarray | None) -> Association:
        assoc = super()._associate(z, ids)
        cap = self.exists.shape[1]
        if self.votes.shape[1] < cap:  # the parent grew its capacity
            extra = np.zeros((self.n_particles, cap - self.votes.shape[1], self.n_classes + 1), dtype=np.int64)
            self.votes = np.concatenate([self.votes, extra], axis=1)
        if self._classes is not None:
            rows = np.arange(self.n_particles)
            for j, label in enumerate(self._classes):
                sel = rows[assoc.matched[:, j] | assoc.new[:, j]]
                np.add.at(self.votes, (sel, assoc.slots[sel, j], label), 1)
        return assoc

    def _apply_resample(self, indices: np.ndarray, mutate: np.ndarray | None) -> None:
        idx = np.asarray(indices, dtype=np.int64)
        if idx.shape == (self.n_particles,):  # a wrong shape is the parent's ValueError
            self.votes = self.votes[idx]
        super()._apply_resample(indices, mutate)
