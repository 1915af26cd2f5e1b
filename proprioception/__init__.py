"""What the robot feels: its own joints, feet and IMU, as opposed to what its camera perceives (`sensing`).

    from proprioception.collision import CollisionDetector, learn_reference
    from proprioception.velocity import VelocityEKF, VelocityEKFParams, LegOdometry
    from proprioception.velocity_odometry import EKFOdometry

- `proprioception.collision`: collision detection by comparing the leg servos' readings with their commands
  (Hoffmann), producing the percept `motion_models.AdaptiveMotion` takes.
- `proprioception.kinematics`: leg kinematics in the Denavit-Hartenberg convention (Wawrzyński eq. 5-14).
- `proprioception.velocity`: the velocity EKF fusing the IMU with leg kinematics and the gyroscope.
- `proprioception.velocity_odometry`: the EKF's velocity turned into odometry for the motion models.
"""
