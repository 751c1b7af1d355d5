"""Cylinder detection and parameter identification in point clouds (thesis chapter 4)."""
