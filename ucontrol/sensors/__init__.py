"""What the controller is allowed to see and do: sensors and actuators in the loop.

Sensor noise, quantisation, velocity estimation and delay; actuator saturation and rate limits.

Built by the closed loop only when a scene declares ``[sensors]`` or ``[actuators]``.
"""

from ucontrol.sensors.actuators import Actuators
from ucontrol.sensors.measurement import Sensors
from ucontrol.sensors.sensor_settings import VELOCITY_SOURCES, ActuatorSettings, SensorSettings

__all__ = ["VELOCITY_SOURCES", "ActuatorSettings", "Actuators", "SensorSettings", "Sensors"]
