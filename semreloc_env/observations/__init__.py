"""Observations for active-relocalization policies: spatial belief images, hypotheses, scans.

* `ActiveObservation` — the wrapper (egocentric crop, whole-map view,
  hypothesis vector, belief summary, normalised scans, last action); never the true pose.
* `.rasters` — the top-down images of the filter's map and particles.
* `.hypotheses` — the belief's hypothesis list (the filter's, or clustered here).
"""

from .active import BELIEF_SUMMARY, HYPOTHESIS_FEATURES, OBSERVATION_KEYS, ActiveObservation
from .hypotheses import hypotheses_of

__all__ = [
    "BELIEF_SUMMARY",
    "HYPOTHESIS_FEATURES",
    "OBSERVATION_KEYS",
    "ActiveObservation",
    "hypotheses_of",
]
