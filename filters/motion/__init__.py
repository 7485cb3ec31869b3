"""Motion models, vectorised over ``(N, 3)`` pose arrays.

* `filters.motion.odometry` -- the odometry (rot1, trans, rot2) sampling model of MCL and the simulator.
* `filters.motion.odometry_slam` -- the same model behind the SLAM `MotionModel`
  protocol, with Jacobians.
* `filters.motion.velocity` -- the protocol and the velocity-controlled car-like and unicycle models.
"""
