"""State-space models for the generic particle filters (:mod:`filters.pf`, :mod:`filters.firefly`)."""

from filters.models.base import StateSpaceModel
from filters.models.growth import GrowthModel, GrowthModelParams

__all__ = ["GrowthModel", "GrowthModelParams", "StateSpaceModel"]
