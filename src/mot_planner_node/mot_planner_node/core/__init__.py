"""ROS-free algorithms of mot_planner_node (thesis chapter 5). numpy/scipy/OpenCV, typed.

- kalman: constant-velocity Kalman filters over stacks of targets (section 5.3.1).
- observation: sliding-window quantization noise of the detector (Eqs. 5.8-5.15, 5.22).
- regions: dynamic search regions and the K_max / S_max constraints (Eqs. 5.16-5.20).
- planner: the resource-constrained POMDP solved online by MCTS/UCT (Eqs. 5.21-5.25).
- association: Hungarian association on Mahalanobis distance with gating.
- detector: the detector plug-in interface and OpenCV's HOG people detector.
- egomotion: beliefs moved by the camera's rotation between frames (H = K R K^-1).
- ground_plane: does a person box stand on the floor at a person's height (gaze gate).
- tracker: the per-frame pipeline of Fig. 5.1 (predict, plan, detect, associate, update).
- motchallenge, metrics: MOTChallenge folders and CLEAR MOT / IDF1 scoring.
- simulated: synthetic pedestrians and a simulated detector for tests and benchmarks.
"""
