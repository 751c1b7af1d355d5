"""ROS-free pieces every Vizzy package shares (numpy/SciPy/OpenCV only, fully typed):

- camera: pinhole intrinsics and stereo projection matrices of the eyes and the RGB-D sensor.
- frames: quaternions (x, y, z, w) and rotation matrices, one convention, on SciPy's Rotation.
- kinematics: the Vizzy head's kinematic chain (real-robot numbers), REP 103 frames, joint signs,
  gaze angles; what the simulator, the gaze controller and the URDF are built from.
- logpolar: `LogPolarRetina`, the log-polar sensor with overlapping Gaussian receptive fields
  (Eq. 1.1, section 3.3.2) of the foveation and stereo nodes.
- image_checks: input validation with clear ValueErrors.
- rays: pixel rays and back-projection.
- pointcloud: PCL's packed rgb.
"""
