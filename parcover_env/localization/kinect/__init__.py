"""Min et al.'s overhead Kinect localization: marker pipeline, multi-Kinect tracker, the system loop."""
