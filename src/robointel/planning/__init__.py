"""Part III (Ch. 7): CFS, trajectory planning, SQP baseline, temporal optimization, FRMP."""
