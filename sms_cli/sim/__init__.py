"""Simulation: scenario sequencing, actuators and sensors, metrics, and MCAP recording."""
