"""Monte Carlo localization on a grid map.

* `filters.localization.likelihood_field` -- lidar and per-class semantic likelihood fields, numba kernel.
* `filters.localization.likelihood_reference` -- the same likelihood in plain NumPy (the reference).
* `filters.localization.mcl` -- the MCL filter (resampling, KLD sampling, augmented MCL).
* `filters.localization.belief` -- the belief summary of a particle set.
"""
