"""From a learned policy to a robot: time-parameterised joint trajectories within Baxter's
limits, written as our CSV, Baxter SDK playback files or ROS 2 bags, and the policy as ONNX."""
