"""robointel."""
