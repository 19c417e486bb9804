"""Part I (Ch. 3-4): imitation, compliance and kinesthetic teaching, F/T identification, key-point reproduction, teleoperation, guidance with collision avoidance."""
