"""The gaze controller of the Vizzy head (gaze_controller executable): what a real robot runs."""
