"""ROS-free algorithms of foveation_node go here.

numpy/OpenCV/torch only, fully typed, no ROS imports. Planned modules:
- foveation: the Gaussian-pyramid foveation of an image at a fixation point (Eqs. 2.1-2.4).
- detection: the feed-forward / feedback passes of the foveated CNN (Fig. 2.5).
"""
