"""What the controller is allowed to see and do: sensors and actuators in the loop.

Sensor noise, quantisation, velocity estimation, delay and contact observers; actuator
saturation and rate limits.

Built by the closed loop only when a scene declares ``[sensors]`` or ``[actuators]``.
"""

from ucontrol.sensors.actuators import Actuators
from ucontrol.sensors.measurement import Sensors
from ucontrol.sensors.momentum_observer import MomentumObserver
from ucontrol.sensors.sensor_settings import (
    CONTACT_OBSERVERS,
    VELOCITY_SOURCES,
    ActuatorSettings,
    SensorSettings,
)

__all__ = [
    "CONTACT_OBSERVERS",
    "VELOCITY_SOURCES",
    "ActuatorSettings",
    "Actuators",
    "MomentumObserver",
    "SensorSettings",
    "Sensors",
]
