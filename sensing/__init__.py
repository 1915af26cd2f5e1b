"""What the robot perceives: observations and the sensor models that score them.

    from sensing import LandmarkObservation, Observations, LandmarkSensorModel, LineSensorModel

`LandmarkSensorModel` scores typed range-bearing detections (goalposts, line crossings, marks);
`LineSensorModel` scores points on detected field lines against a distance-transform likelihood field;
`CombinedSensorModel` adds them. Leg kinematics and the velocity EKF live in `proprioception.kinematics` and
`proprioception.velocity` (and `proprioception.velocity_odometry` turns the EKF into filter odometry); collision detection
from servo commands and readings, the percept the adaptive motion model needs, in `proprioception.collision`.
"""

from field.moved import keep_old_names

from .combined import CombinedSensorModel
from .landmarks import LandmarkSensorModel
from .lines import LineSensorModel
from .observations import LandmarkObservation, Observations

__all__ = ["LandmarkObservation", "Observations", "LandmarkSensorModel", "LineSensorModel", "CombinedSensorModel"]

# What the robot feels moved to its own package, proprioception; the old names still import, with a warning.
keep_old_names(
    {
        f"sensing.{name}": f"proprioception.{name}"
        for name in ("collision", "kinematics", "velocity", "velocity_odometry")
    }
)
