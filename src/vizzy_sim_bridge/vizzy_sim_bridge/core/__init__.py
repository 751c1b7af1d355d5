"""ROS-free algorithms of vizzy_sim_bridge (numpy and MuJoCo, fully typed, no ROS imports); the
head's kinematics and cameras are vizzy_vision's.

- model: the MuJoCo model of the head (MJCF from primitives) and its real-time physics.
- scenes: the seeded scenes (tabletop, visual_search, pedestrians) with ground truth.
- render: offscreen rendering (EGL, else OSMesa) of the head's cameras.
- rgbd: the RGB-D sensor's depth noise and organized point clouds.
- pedestrians: procedural walking people for the pedestrians scene.
"""
