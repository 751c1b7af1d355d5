"""ROS-free algorithms of stereo_ses_node (thesis chapter 3); numpy/scipy/OpenCV, no ROS imports.

- geometry: convergent stereo poses, mid-point triangulation (Eq. 3.8).
- sensors: Cartesian and log-polar (foveation package) sensors as Gaussian RFs (Eqs. 3.6-3.7).
- ut: Unscented Transform (Eqs. 3.9-3.18), with linearization and Monte Carlo references.
- multires: disparity maps of rectified pairs at the resolution each sensor needs (full SGBM,
  the Cartesian grid, the log-polar sensor's foveated pyramid), the search window from the
  geometry, coarse-to-fine ranges, bad-pixel rates.
- stereo: SGBM on each sensor's view -> correspondences -> UT points.
- ses: the randomized Sensory Ego-Sphere (Eqs. 3.19-3.35), exact fast association.
- decision: reward statistics, UCB / PI / EI gaze selection, reachable cells (Eqs. 3.36-3.43).
- information: -log|Sigma| and the search metrics of section 3.4 (Eqs. 3.45-3.56).
- linalg3, synthetic: batched 3x3 inverse; synthetic stereo pairs (a textured plane seen by
  verged eyes; rectified pairs of slanted textured layers with ground truth and occlusions).
"""
