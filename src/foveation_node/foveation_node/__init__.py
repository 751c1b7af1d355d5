"""Foveated vision: space-variant images, foveated CNN detections, saccades (thesis chapter 2)."""
