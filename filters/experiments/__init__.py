"""Support for experiment scripts: confidence intervals from :mod:`scipy.stats` (:mod:`.stats`)."""
