"""ROS-free algorithms of vizzy_sim_bridge go here (numpy only, fully typed, no ROS imports).

- camera: pinhole intrinsics and stereo projection matrices of the eyes and the RGB-D sensor.
- kinematics: the Vizzy head's kinematic chain (real-robot numbers), frames, signs, gaze angles.
- model: the MuJoCo model of the head (MJCF from primitives) and its real-time physics.
- scenes: the seeded scenes (tabletop, visual_search, pedestrians) with ground truth.
- render: offscreen rendering (EGL, else OSMesa) of the head's cameras.
- rgbd: the RGB-D sensor's depth noise and organized point clouds.
- pedestrians: procedural walking people for the pedestrians scene.
- gaze: the gaze controller's validation, arbitration, head/eye inverse kinematics and saccade
  and pursuit trajectories.
"""
