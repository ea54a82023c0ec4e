"""Time integration of the SystemModel's equations of motion."""
