"""Estimators for 2D robot localization and SLAM: numpy + scipy (+ numba kernels) only.

No simulator, gymnasium, pymunk or torch here: every filter runs on data from a
real robot as well as from `semreloc_env`. One subpackage per concept:

* `filters.localization` -- Monte Carlo localization: likelihood fields (and their NumPy
  reference), the MCL filter, the belief summary.
* `filters.motion` -- the motion models: odometry (sampling), its linearised form for SLAM,
  velocity-controlled car-like / unicycle models.
* `filters.mapping` -- grids, occupancy + semantic mapping, ROS map files, map metrics.
* `filters.smc` -- generic sequential Monte Carlo: weights and resampling, the bootstrap PF,
  the firefly PFs, benchmark state-space models.
* `filters.slam` -- landmark SLAM: FastSLAM 1.0/2.0 (+ WOC), EKF-SLAM, IFA-FastSLAM.
* `filters.robot_data` -- sensor data containers (laser and semantic scans).
* `filters.simulators` -- simulators that serve only experiments and tests (car-like SLAM
  simulator, grid ray caster).
* `filters.experiments` -- what every experiment shares: the runner (sequential, process pool or
  Ray), confidence intervals (``scipy.stats``), report writers, typed command lines (tyro); and the
  paper 000 / 001 reproductions, which need nothing above this package.
* `filters.tools` -- commands over the filters alone (replaying a robot log).
* `filters.pose` -- pose algebra shared by all of the above.
* `filters.numbers` -- what counts as a number in argument checks (`is_int`, `is_real`).
* `filters.numba_cache` -- a cache folder for the compiled kernels where numba finds none to write.
"""

from .numba_cache import ensure_cache_dir

ensure_cache_dir()
