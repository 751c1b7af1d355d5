"""Simulated Vizzy head (the sim executable): MuJoCo cameras, RGB-D sensor, joints, tf, scenes."""
