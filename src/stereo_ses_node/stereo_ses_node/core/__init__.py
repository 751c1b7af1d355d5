"""ROS-free algorithms of stereo_ses_node go here.

numpy/OpenCV/torch only, fully typed, no ROS imports. Planned modules:
- stereo: log-polar / Cartesian stereo reconstruction with Unscented Transform covariances.
- ses: the egocentric Sensory Ego-Sphere memory and bandit gaze selection.
"""
