"""IMU recordings of a person's two arms -> human joint angles -> Baxter joint vector."""
