"""What the robot perceives: landmark observations and the landmark sensor model.

    from sensing import LandmarkObservation, Observations, LandmarkSensorModel
"""
from .landmarks import LandmarkSensorModel
from .observations import LandmarkObservation, Observations

__all__ = ["LandmarkObservation", "Observations", "LandmarkSensorModel"]
