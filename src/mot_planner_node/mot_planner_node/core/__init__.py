"""ROS-free algorithms of mot_planner_node go here.

numpy/OpenCV/torch only, fully typed, no ROS imports. Planned modules:
- tracking: one constant-velocity Kalman filter per target (Eqs. 5.1-5.6), with the
  detector noise model of Eqs. 5.7-5.15.
- planning: search regions (Eq. 5.18) chosen by MCTS under K_max / S_max.
"""
