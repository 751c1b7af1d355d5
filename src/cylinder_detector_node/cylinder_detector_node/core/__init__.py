"""ROS-free algorithms of cylinder_detector_node go here.

numpy/OpenCV/torch only, fully typed, no ROS imports. Planned modules:
- segmentation: tabletop plane removal and Euclidean clustering.
- hough: cylinder parameters by the depth-based Hough transform.
"""
