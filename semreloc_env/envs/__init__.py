"""The semreloc Gymnasium environments."""

from .semreloc import SemRelocEnv

__all__ = ["SemRelocEnv"]
