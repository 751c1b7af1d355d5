"""Training and data generation for the recognition CNN: renders of the simulated head.

Not imported by the node: a robot that runs only foveation_node needs neither MuJoCo nor
vizzy_sim_bridge; these modules import them when they render (train_foveation_classifier says in
one line what is missing).

- object_views: single-object renders of the classes of our scenes (random pose, colour, light).
- tabletop_views: cluttered tabletop renders with each object's ground-truth box and class.
- train_classifier: the train_foveation_classifier program (the packaged model's recipe).
"""
