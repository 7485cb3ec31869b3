"""Generic sequential Monte Carlo.

* :mod:`filters.smc.resampling` -- weights (normalise, effective sample size) and the resampling schemes.
* :mod:`filters.smc.pf` -- the bootstrap particle filter over a state-space model.
* :mod:`filters.smc.firefly` -- FA-PF and IFA-PF (paper 001).
* :mod:`filters.smc.models` -- benchmark state-space models.
"""
