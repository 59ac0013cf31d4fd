"""Everything that draws: env frames, plan drawings, sector and Kinect views. Reads state only."""
