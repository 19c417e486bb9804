"""Grasp transfer by non-rigid registration (Ch. 6)."""
