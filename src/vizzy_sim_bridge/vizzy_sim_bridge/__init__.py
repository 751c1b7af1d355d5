"""Simulated Vizzy head (sim executable) and the gaze controller (gaze_controller executable)."""
