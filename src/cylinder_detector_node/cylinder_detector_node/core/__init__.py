"""ROS-free algorithms of cylinder_detector_node (thesis chapter 4).

numpy/scipy/Open3D only, fully typed, no ROS imports:
- geometry: PCA normals and principal curvature per point (section 4.3.3).
- accumulator: orientation Hough accumulators, GMM-sampled (Eq. 4.1-4.2, Table 4.1) or uniform, and
  their voting functions (Eq. 4.3 and the normals-only baseline of Rabbani & van den Heuvel 2005).
- fitting: two-stage cylinder fit (orientation vote, then axis alignment + circle Hough), Eq. 4.4.
- segmentation: tabletop plane RANSAC, Euclidean clustering, 2D patch projection (section 4.3.1).
- pipeline: segmentation then one fit per cluster in the table frame.
- synthetic: cylinders with caps and noise (section 4.4.1) for tests, experiments and benchmarks.
- scene: a ray-cast 640x480 organized tabletop frame (cylinders and distractors).
- open3d_lib: Open3D's compiled module without the package's visualization start-up.
"""
