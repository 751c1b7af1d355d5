"""Training and data generation for the cylinder classifier: RGB-D frames of the simulated head.

Not imported by the node: a robot that runs only cylinder_detector_node needs neither MuJoCo nor
vizzy_sim_bridge; these modules import them when they render (train_cylinder_classifier says in
one line what is missing).

- sim_frames: rendered tabletop RGB-D frames with ground-truth cylinders, at random head poses.
- patch_data: the patches of Eq. 4.4 cut from segmented clusters, labelled by ground truth.
- train_classifier: the train_cylinder_classifier program (the packaged model's recipe).
"""
