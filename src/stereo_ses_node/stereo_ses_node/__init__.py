"""Log-polar stereo with Unscented Transform and the Sensory Ego-Sphere (thesis chapter 3)."""
