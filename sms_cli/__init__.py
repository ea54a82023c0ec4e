"""sms: mission analysis for space manipulator systems (URDF robot + YAML mission)."""

__version__ = "0.1.0"
