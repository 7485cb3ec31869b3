"""Generic sequential Monte Carlo.

* `filters.smc.resampling` -- weights (normalise, effective sample size) and the resampling schemes.
* `filters.smc.pf` -- the bootstrap particle filter over a state-space model.
* `filters.smc.firefly` -- FA-PF and IFA-PF (paper 001).
* `filters.smc.models` -- benchmark state-space models.
"""
