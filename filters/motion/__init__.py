"""Motion models, vectorised over ``(N, 3)`` pose arrays.

* :mod:`filters.motion.odometry` -- the odometry (rot1, trans, rot2) sampling model of MCL and the simulator.
* :mod:`filters.motion.odometry_slam` -- the same model behind the SLAM :class:`~filters.motion.velocity.MotionModel`
  protocol, with Jacobians.
* :mod:`filters.motion.velocity` -- the protocol and the velocity-controlled car-like and unicycle models.
"""
