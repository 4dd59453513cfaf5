"""dualarm: human joint-angle constraints from IMU demonstrations guiding dual-agent DDPG."""

__version__ = "0.1.0"
