"""What the robot perceives: observations and the sensor models that score them.

    from sensing import LandmarkObservation, Observations, LandmarkSensorModel, LineSensorModel

`LandmarkSensorModel` scores typed range-bearing detections (goalposts, line crossings, marks);
`LineSensorModel` scores points on detected field lines against a distance-transform likelihood field;
`CombinedSensorModel` adds them. Leg kinematics and the velocity EKF live in `sensing.kinematics` and
`sensing.velocity` (and `sensing.velocity_odometry` turns the EKF into filter odometry); collision detection
from servo commands and readings, the percept the adaptive motion model needs, in `sensing.collision`.
"""
from .combined import CombinedSensorModel
from .landmarks import LandmarkSensorModel
from .lines import LineSensorModel
from .observations import LandmarkObservation, Observations

__all__ = ["LandmarkObservation", "Observations", "LandmarkSensorModel", "LineSensorModel", "CombinedSensorModel"]
