"""ROS-free algorithms of vizzy_sim_bridge go here (numpy only, fully typed, no ROS imports).

- camera: pinhole intrinsics and stereo projection matrices.
- kinematics: the head's approximate kinematic chain, frames and gaze angles.
- pattern: the synthetic moving stereo pattern of the placeholder simulator.
- gaze: validation and arbitration of gaze requests.
"""
