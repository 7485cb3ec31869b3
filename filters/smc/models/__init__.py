"""State-space models for the generic particle filters (`filters.smc.pf`, `filters.smc.firefly`)."""

from filters.smc.models.base import StateSpaceModel
from filters.smc.models.growth import GrowthModel, GrowthModelParams

__all__ = ["GrowthModel", "GrowthModelParams", "StateSpaceModel"]
