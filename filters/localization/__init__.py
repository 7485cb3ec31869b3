"""Monte Carlo localization on a grid map.

* :mod:`filters.localization.likelihood_field` -- lidar and per-class semantic likelihood fields, numba kernel.
* :mod:`filters.localization.likelihood_reference` -- the same likelihood in plain NumPy (the reference).
* :mod:`filters.localization.mcl` -- the MCL filter (resampling, KLD sampling, augmented MCL).
* :mod:`filters.localization.belief` -- the belief summary of a particle set.
"""
