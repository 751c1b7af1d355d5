"""Resource-constrained multiple object tracking and attention planning (thesis chapter 5)."""
