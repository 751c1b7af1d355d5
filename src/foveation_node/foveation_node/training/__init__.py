"""Training and data generation for the recognition CNN: renders of the simulated head.

Not imported by the node: a robot that runs only foveation_node needs neither MuJoCo nor
vizzy_sim_bridge; these modules import them when they render (train_foveation_classifier says in
one line what is missing).

- object_views: single-object renders of the classes of our scenes (random pose, colour, light).
- tabletop_views: cluttered tabletop renders with each object's ground-truth box and class.
- background_views: fixations on no object (the background class).
- window_views: the windows around fixations a window model is trained on (the head fixating
  each object as the gaze controller would: imports vizzy_gaze).
- train_classifier: the train_foveation_classifier program (the packaged models' recipes; its
  --window mode is window_training).
"""
