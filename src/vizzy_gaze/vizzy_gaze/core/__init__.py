"""ROS-free algorithms of vizzy_gaze (numpy only, fully typed, no ROS imports).

- gaze: the gaze controller's validation, arbitration, head/eye inverse kinematics and saccade
  and pursuit trajectories (the head's geometry from vizzy_vision.kinematics).
"""
